# SPDX-License-Identifier: GPL-3.0-or-later
"""GGX microfacet BRDF, float64 (formulas.md section 3).

Roughness alpha in (0, 1] (the squared-perceptual-roughness convention of 004: D(1) = 1/(pi alpha^2)).
Same conventions as ``sg``: numpy broadcasting over leading dimensions, vectors in a trailing axis of
length 3, unit vectors in; ``incoming`` and ``outgoing`` both point away from the surface.

Papers: 001 = rectangle-based MRP-ASG (Eq. 16); 004 = Tokuyoshi and Harada, "Stochastic light
culling for VPLs on GGX microsurfaces" (EGSR 2017), Eqs. 6-8.
"""

from __future__ import annotations

import numpy as np

from .numerics import dot, f64, norm, safe_normalize, safe_ratio


def ggx_ndf(cos_theta_m, roughness):
    """D(c) = alpha^2 chi+(c) / (pi (alpha^2 c^2 + (1 - c)(1 + c))^2) (004 Eq. 6; 001 Eq. 16).

    The textbook denominator 1 - (1 - alpha^2) c^2 cancels catastrophically in float32 near c = 1
    for small alpha (it is alpha^2 = 1e-6 at alpha = 1e-3, below float32's epsilon); alpha^2 c^2 +
    (1 - c)(1 + c) only adds positive terms. sin^2 is clamped at 0 for |c| > 1 from rounding.
    """
    c = f64(cos_theta_m)
    a2 = f64(roughness) ** 2
    sin2 = np.maximum((1.0 - c) * (1.0 + c), 0.0)
    denominator = a2 * c * c + sin2
    value = a2 / (np.pi * denominator * denominator)
    return np.where(c > 0.0, value, 0.0)


def ggx_g1_denominator(abs_cos, a2):
    """|c| + sqrt((1 - alpha^2) c^2 + alpha^2): 2|c| / G1dist (004 Eq. 8)."""
    return abs_cos + np.sqrt((1.0 - a2) * abs_cos * abs_cos + a2)


def g1_distant(cos_theta, roughness):
    """Smith masking of GGX, G1dist(c) = 2|c| / (|c| + sqrt((1 - alpha^2) c^2 + alpha^2)) (004 Eq. 8).

    In [0, 1], = 1 at |c| = 1, = 0 at c = 0 (for alpha > 0).
    """
    abs_cos = np.abs(f64(cos_theta))
    denominator = ggx_g1_denominator(abs_cos, f64(roughness) ** 2)
    return safe_ratio(2.0 * abs_cos, denominator)


def fresnel_schlick(cos_theta, f0):
    """Schlick's Fresnel F = f0 + (1 - f0)(1 - c)^5, c clamped to [0, 1] (rounding, back faces)."""
    c = np.clip(f64(cos_theta), 0.0, 1.0)
    return f64(f0) + (1.0 - f64(f0)) * (1.0 - c) ** 5


def ggx_half_vector_ndf(incoming, outgoing, normal, roughness):
    """D(wh.n) (004 Eq. 6) of the half vector wh = (wi + wo)/|wi + wo| of directions above the
    surface; 0 when wi = -wo (no half vector). The GLSL twin keeps sin² of wh in twice the
    precision near the peak of a sharp lobe."""
    half = f64(incoming) + f64(outgoing)
    half_length = norm(half)
    half = safe_normalize(half, 0.0, half_length)
    return np.where(half_length > 0.0, ggx_ndf(dot(half, f64(normal)), f64(roughness)), 0.0)


def microfacet_brdf(incoming, outgoing, normal, roughness, f0):
    """GGX BRDF f = F(wi.wh) G1dist(wi) G1dist(wo) D(wh.n) / (4 |wi.n| |wo.n|) (004 Eq. 7-8).

    Evaluated as F D / ((c_i + s_i)(c_o + s_o)) with s = sqrt((1 - alpha^2) c^2 + alpha^2): the
    4 c_i c_o of the masking numerators cancel the denominator analytically, so the grazing limit
    (c -> 0, where f -> F D / (alpha (c + s))) stays finite. 0 when either cosine is <= 0 (chi+), and
    when wi = -wo (no half vector).
    """
    incoming = f64(incoming)
    outgoing = f64(outgoing)
    normal = f64(normal)
    alpha = f64(roughness)
    a2 = alpha * alpha
    cos_i = dot(incoming, normal)
    cos_o = dot(outgoing, normal)
    half = incoming + outgoing
    half_length = norm(half)
    valid = (cos_i > 0.0) & (cos_o > 0.0) & (half_length > 0.0)
    half = safe_normalize(half, 0.0, half_length)
    d = ggx_half_vector_ndf(incoming, outgoing, normal, alpha)
    f = fresnel_schlick(dot(incoming, half), f0)
    ci = np.maximum(cos_i, 0.0)
    co = np.maximum(cos_o, 0.0)
    value = f * d / (ggx_g1_denominator(ci, a2) * ggx_g1_denominator(co, a2))
    return np.where(valid, value, 0.0)
