# SPDX-License-Identifier: GPL-3.0-or-later
"""Spherical Gaussians (SG) and the SG reflection lobes, float64 (formulas.md section 1).

``G(w; xi, lam) = exp(lam (w.xi - 1))`` with unit axis ``xi`` and sharpness ``lam >= 0``
(000 app. A; 003). Every function broadcasts numpy-style over leading dimensions; vectors live in a
trailing axis of length 3, scalars are accepted for every scalar parameter. Directions must be unit
vectors (nothing here renormalizes them: the GLSL twins take the same inputs).

Papers: 000 = Tokuyoshi, "Modified filtered importance sampling for virtual spherical Gaussian
lights" (CVM 2016); 003 = the Square Enix SG talk (2015).
"""

from __future__ import annotations

import numpy as np

from .numerics import dot, f64, norm, one_minus_exp_ratio, safe_normalize, safe_ratio

#: Sharpness of the diffuse SG lobe, lambda_d ~= 2 (000 Eq. 6, "obtained by the least square
#: method"; see docs/accuracy.md for the measured optimum).
DIFFUSE_SHARPNESS = 2.0

#: A Lambertian reflector emits its reflected flux Φ·Rd into its hemisphere only, but 000 Eq. 6
#: normalizes its SG lobe over the whole sphere: ∫ over the upper hemisphere of G(ω; n, λd)/A(λd)
#: is (1 − e^(−λd))/(1 − e^(−2λd)) = 1/(1 + e^(−λd)), 0.881 at λd = 2, and the 11.9 % below the
#: horizon enters the reflector and lights nothing. Normalizing over the hemisphere instead,
#: Rd · G(ω; n, λd) / A_hemi(λd) with A_hemi(λ) = 2π (1 − e^(−λ))/λ, keeps "energy conservation"
#: (000 app. A.1) where the light goes: the lobe is A(λd)/A_hemi(λd) = 1 + e^(−λd) times 000's.
#: Brute-force VPLs from the suite's RSMs (benchmarks/energy_budget.py) lose 11-13 % with the
#: sphere-normalized lobe against Lambert's, none with this one.
DIFFUSE_HEMISPHERE_SCALE = 1.0 + float(np.exp(-DIFFUSE_SHARPNESS))

#: Floor on |w'.n| in the spherical warp (000 Eq. 7) and on (w_o.n) in the ASG bandwidth (003).
#: At grazing incidence the true cosine reaches 0 and the sharpness would be infinite. With 1e-4 the
#: largest sharpness at roughness 1e-3 is 2e6 / 4e-4 = 5e9 for the SG lobe and 2e6 / (8 * 1e-8) =
#: 2.5e13 for the ASG bandwidth: finite in float32 (max 3.4e38), and so are the products
#: (eta * nu ~ 1e23) the SG x ASG convolution forms from them.
COSINE_FLOOR = 1e-4

_TWO_PI = 2.0 * np.pi
_FOUR_PI = 4.0 * np.pi


def sg_evaluate(omega, axis, sharpness):
    """G(w; xi, lam) = exp(lam (w.xi - 1)) (000 app. A), evaluated as exp(-lam/2 |w - xi|^2).

    The two are equal for unit vectors (000 app. A writes both). The difference form keeps the
    precision of small angles: w.xi - 1 rounds to 0 in float32 once the angle is below ~2.4e-4 rad,
    which is the whole lobe at lam = 1e6.
    """
    omega = f64(omega)
    axis = f64(axis)
    d = omega - axis
    return np.exp(-0.5 * f64(sharpness) * dot(d, d))


def sg_integral(sharpness):
    """A(lam) = integral of G over the sphere = 2 pi (1 - e^(-2 lam)) / lam (000 app. A).

    Written 4 pi * (-expm1(-2 lam)) / (2 lam): exact to rounding for lam = 1e-6 and equal to the
    limit 4 pi at lam = 0.
    """
    return _FOUR_PI * one_minus_exp_ratio(2.0 * f64(sharpness))


def _product_parts(axis1, sharpness1, axis2, sharpness2):
    """xi_m = lam1 xi1 + lam2 xi2, |xi_m| and the exponent d = |xi_m| - lam1 - lam2.

    d is computed as -lam1 lam2 |xi1 - xi2|^2 / (|xi_m| + lam1 + lam2): multiply
    |xi_m| - (lam1 + lam2) by (|xi_m| + lam1 + lam2) and use |xi_m|^2 = lam1^2 + lam2^2 +
    2 lam1 lam2 xi1.xi2 for unit axes. The direct difference cancels catastrophically for close,
    sharp lobes (two numbers ~2e6 whose difference is ~1).
    """
    axis1 = f64(axis1)
    axis2 = f64(axis2)
    lam1 = f64(sharpness1)
    lam2 = f64(sharpness2)
    xi_m = lam1[..., None] * axis1 + lam2[..., None] * axis2
    length = norm(xi_m)
    diff = axis1 - axis2
    denominator = length + lam1 + lam2
    exponent = safe_ratio(-lam1 * lam2 * dot(diff, diff), denominator)
    return xi_m, length, exponent


def sg_product(axis1, sharpness1, axis2, sharpness2):
    """Product of two SGs as one scaled SG (000 app. A; 003).

    G(w; xi1, lam1) G(w; xi2, lam2) = scale * G(w; axis, sharpness) with xi_m = lam1 xi1 + lam2 xi2,
    axis = xi_m / |xi_m|, sharpness = |xi_m|, scale = exp(|xi_m| - lam1 - lam2).

    Returns ``(axis, sharpness, scale)``. When |xi_m| = 0 (opposite axes, equal sharpness, or both
    sharpnesses 0) the product is the constant ``scale``; axis1 is returned so that the axis stays a
    unit vector (no NaN) and any axis is correct for sharpness 0.
    """
    xi_m, length, exponent = _product_parts(axis1, sharpness1, axis2, sharpness2)
    axis = safe_normalize(xi_m, f64(axis1), length)
    return axis, length, np.exp(exponent)


def sg_product_integral(axis1, sharpness1, axis2, sharpness2):
    """Integral of G(w; xi1, lam1) G(w; xi2, lam2) over the sphere (000 app. A; 003).

    = 4 pi sinh(|xi_m|) / (e^(lam1 + lam2) |xi_m|)
    = 2 pi e^d (1 - e^(-2 |xi_m|)) / |xi_m|,  d = |xi_m| - lam1 - lam2 in its stable form
    (see ``sg_product``); the limit |xi_m| -> 0 is 4 pi e^(-lam1 - lam2).
    """
    _, length, exponent = _product_parts(axis1, sharpness1, axis2, sharpness2)
    return _FOUR_PI * np.exp(exponent) * one_minus_exp_ratio(2.0 * length)


def sg_lobe_normalized(omega, axis, sharpness):
    """G(w; xi, lam) / A(lam): the von Mises-Fisher density (000 app. A, Eq. 6-7).

    A(lam) in its expm1 form (``sg_integral``) is exact at lam = 0 (4 pi) and only underflows
    (2 pi / lam < 2.2e-308) for lam > ~2.8e308, so the density is finite for lam from 0 to ~1e308.
    """
    lam = f64(sharpness)
    return sg_evaluate(omega, axis, lam) / (_FOUR_PI * one_minus_exp_ratio(2.0 * lam))


def diffuse_lobe_hemisphere(omega, normal):
    """Lambert lobe <w, n>/pi as the SG of 000 Eq. 6 normalized over the hemisphere:
    DIFFUSE_HEMISPHERE_SCALE · G(w; n, lam_d) / A(lam_d) (its integral over w.n > 0 is 1).
    The lobe every VPL and VSGL emits with (reference/vsgl.py vsgl_parameters)."""
    return DIFFUSE_HEMISPHERE_SCALE * sg_lobe_normalized(omega, normal, DIFFUSE_SHARPNESS)


def diffuse_lobe(omega, normal):
    """Lambert lobe <w, n>/pi as a normalized SG: G(w; n, lam_d) / A(lam_d), lam_d = 2 (000 Eq. 6).

    Multiply by the diffuse reflectance R_d outside.
    """
    return sg_lobe_normalized(omega, normal, DIFFUSE_SHARPNESS)


def ndf_sharpness(roughness):
    """lam_h = 2 / alpha^2: SG fit of a Beckmann/GGX NDF normalized to max 1 (000 app. A.1; 003).

    Roughness alpha in (0, 1]; alpha = 0 gives inf (a mirror), callers clamp.
    """
    alpha = f64(roughness)
    return 2.0 / (alpha * alpha)


def specular_lobe_warp(incoming, normal, roughness):
    """Spherical warp of the NDF's SG to an SG in the outgoing direction (000 Eq. 7; Wang et al.).

    xi_s = 2 (w'.n) n - w' (mirror direction of the incoming direction w', which points away from
    the surface), lam_s = lam_h / (4 max(|w'.n|, COSINE_FLOOR)). (000 writes |xi_s.n|, which is
    |w'.n| for unit vectors.) Returns ``(axis, sharpness)``.
    """
    incoming = f64(incoming)
    normal = f64(normal)
    cos_n = dot(incoming, normal)
    axis = 2.0 * cos_n[..., None] * normal - incoming
    # The floor keeps lam_s finite at grazing incidence (see COSINE_FLOOR).
    sharpness = ndf_sharpness(roughness) / (4.0 * np.maximum(np.abs(cos_n), COSINE_FLOOR))
    return axis, sharpness


def specular_lobe(omega, incoming, normal, roughness):
    """rho_s <w, n> ~= R_s G(w; xi_s, lam_s) / A(lam_s), the energy-preserving form (000 Eq. 7).

    Multiply by the specular reflectance R_s outside.
    """
    axis, sharpness = specular_lobe_warp(incoming, normal, roughness)
    return sg_lobe_normalized(omega, axis, sharpness)
