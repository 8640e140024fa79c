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


# --- SG times the clamped cosine (diffuse receivers) ---------------------------------------------
#
# S(μ, λ) = 1/π ∫ G(ω; ξ, λ) max(ω·n, 0) dω, μ = ξ·n: the diffuse light of an incoming-radiance SG
# on a Lambert receiver, per unit amplitude and reflectance. No elementary closed form exists.
# Tokuyoshi ("Accurate diffuse lighting from spherical Gaussian lights", HPG 2022 posters)
# interpolates between its exact values with the lobe straight above (μ = 1) and straight below
# (μ = −1) by a sigmoid in μ; Tokuyoshi, Ikeda, Kulkarni and Harada ("Hierarchical light sampling
# with accurate spherical Gaussian lighting", SIGGRAPH Asia 2024, supplementary document,
# Listings 6-7) replace the sigmoid by the clamped cosine smoothed with a Gaussian of width 1/t(λ)
# (a fitted rational t), which is exact at μ = ±1, tends to max(μ, 0) as λ → ∞ and is what is built
# here:
#
#     S(μ, λ) = 2 [Sl(λ) + s(μ, t) (Su(λ) − Sl(λ))],
#     Su(λ) = (λ − 1 + e^−λ)/λ²,  Sl(λ) = e^−λ (1 − e^−λ (1 + λ))/λ²      (S(±1, λ) / 2),
#     s(μ, t) = ½ (μ erfc(−tμ) + erfc(t)) − e^(−t²μ²) expm1(t² (μ² − 1)) / (2√π t),
#     t(λ) = λ sqrt(½ (λ² + Aλ + B)/(λ³ + Cλ² + Dλ + E)),
#
# s(1) = 1, s(−1) = 0, s(μ) = ½(μ + 1) at t = 0. Measured against quadrature over λ = 1e−6 … 1e6
# and μ = −1 … 1 (tests/test_reference_sg.py): absolute error ≤ 9.6e-4 of S(1, λ) (the peak), exact
# at μ = ±1; 000 app. C's cosine pulled out, A(λ)/π max(μ, 0), is 73 % too bright at λ = 2, μ = 1.
CLAMPED_COSINE_T_FIT = (2.7360831611272558028247203765204, 17.02129778174187535455530451145,
                        4.0100826728510421403939290030394, 15.219156263147210594866010069381,
                        76.087896272360737270901154261082)
#: Below this λ the hemisphere integrals Su, Sl use their Taylor series (their closed forms cancel).
CLAMPED_COSINE_SERIES_LIMIT = 0.5
_INV_SQRT_PI = 1.0 / np.sqrt(np.pi)
_erfc = np.vectorize(__import__("math").erfc, otypes=[np.float64])


def _series(lam, sign):
    """Σ_k (sign·λ)^k / (k + 2)! for k = 0 … 11 (Horner; the next term is < 3e-12 of the sum at λ = 0.5)."""
    total = np.zeros_like(lam)
    for k in range(11, -1, -1):
        total = total * (sign * lam) + 1.0 / float(np.prod(np.arange(1, k + 3)))
    return total


def sg_upper_clamped_cosine(sharpness):
    """Su(λ) = 1/(2π) ∫ G(ω; n, λ) max(ω·n, 0) dω = (λ − 1 + e^−λ)/λ² (lobe axis on the normal)."""
    lam = f64(sharpness)
    safe = np.where(lam > CLAMPED_COSINE_SERIES_LIMIT, lam, 1.0)
    return np.where(lam > CLAMPED_COSINE_SERIES_LIMIT, (1.0 - one_minus_exp_ratio(safe)) / safe,
                    _series(lam, -1.0))


def sg_lower_clamped_cosine(sharpness):
    """Sl(λ) = 1/(2π) ∫ G(ω; −n, λ) max(ω·n, 0) dω = e^−λ (1 − e^−λ(1 + λ))/λ² (axis below)."""
    lam = f64(sharpness)
    safe = np.where(lam > CLAMPED_COSINE_SERIES_LIMIT, lam, 1.0)
    e = np.exp(-lam)
    return np.where(lam > CLAMPED_COSINE_SERIES_LIMIT, e * (one_minus_exp_ratio(safe) - np.exp(-safe)) / safe,
                    e * e * _series(lam, 1.0))


def sg_clamped_cosine_steepness(sharpness):
    """t(λ) of the smoothed clamped cosine (Tokuyoshi et al. 2024, Listing 7's fit). Written with
    1/λ above λ = 1 so that λ³ never forms (float32 twin: λ up to 1e20)."""
    a, b, c, d, e = CLAMPED_COSINE_T_FIT
    lam = f64(sharpness)
    small = np.minimum(lam, 1.0)
    ratio_small = ((small + a) * small + b) / (((small + c) * small + d) * small + e)
    inv = 1.0 / np.maximum(lam, 1.0)
    ratio_large = inv * ((b * inv + a) * inv + 1.0) / (((e * inv + d) * inv + c) * inv + 1.0)
    return lam * np.sqrt(0.5 * np.where(lam < 1.0, ratio_small, ratio_large))


def sg_clamped_cosine_lerp(cosine, steepness):
    """s(μ, t) ∈ [0, 1]: max(μ, 0) smoothed by a Gaussian of width 1/t (Tokuyoshi et al. 2024)."""
    mu = np.clip(f64(cosine), -1.0, 1.0)
    t = f64(steepness)
    mu, t = np.broadcast_arrays(mu, t)
    tz = t * mu
    safe_t = np.where(t > 0.0, t, 1.0)
    tail = np.exp(-tz * tz) * np.expm1(t * t * (mu * mu - 1.0)) * (0.5 * _INV_SQRT_PI) / safe_t
    s = 0.5 * (mu * _erfc(-tz) + _erfc(t)) - np.where(t > 0.0, tail, 0.0)
    return np.clip(s, 0.0, 1.0)


def sg_clamped_cosine_integral(cosine, sharpness):
    """S(μ, λ) = 1/π ∫ G(ω; ξ, λ) max(ω·n, 0) dω for μ = ξ·n (see the section comment): the diffuse
    light of a unit SG on a unit-albedo Lambert receiver. 1 at λ = 0, → 2π/λ · max(μ, 0)/π for λ → ∞."""
    lam = f64(sharpness)
    upper = sg_upper_clamped_cosine(lam)
    lower = sg_lower_clamped_cosine(lam)
    s = sg_clamped_cosine_lerp(cosine, sg_clamped_cosine_steepness(lam))
    return 2.0 * (lower + s * (upper - lower))
