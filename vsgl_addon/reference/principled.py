# SPDX-License-Identifier: GPL-3.0-or-later
"""Float64 twin of ``glsl/lib/principled.glsl``: Blender's Principled BSDF base layer as Cycles
renders it (measured against Cycles 5.0's Diffuse/Glossy Color and Direct passes in
``tests/test_direct_light.py``), for direct light and shading.

The model (Cycles ``kernel/svm/closure.h`` Principled branch, ``closure/bsdf_microfacet.h``):

* **Metallic layer**, weight ``metallic``: GGX reflection, α = roughness², Fresnel F82-tint with
  the default white Specular Tint, which is exactly Schlick with F0 = base colour.
* **Dielectric specular layer**, weight ``1 − metallic``: GGX reflection with the real dielectric
  Fresnel of the IOR adjusted to Specular IOR Level: F0 = ((ior − 1)/(ior + 1))² · 2 · level
  (clamped to [0, 1)), η = (1 + √F0)/(1 − √F0) (Cycles ``ior_from_F0``), F = Fresnel(η, h·ωi).
* **Diffuse** (Lambert) under the dielectric layer: Cycles' ``closure_layering_weight`` scales it by
  1 − E_spec(μo), the dielectric layer's directional albedo towards the viewer (Cycles' Glossy
  Color pass for a non-metal is that albedo: measured 0.082 for F0 = 0.04, roughness 0.3). So
  Rd = base colour · (1 − metallic) · (1 − E_spec(μo)).
* **Multiple scattering** (Cycles' default "Multiscatter GGX"): each GGX lobe is scaled by
  1 + F_ms (1 − E)/E (Turquin 2019 as Cycles' ``microfacet_ggx_preserve_energy``), E the white
  single-scattering albedo at μo, F_ms = F_ss E_avg / (1 − F_ss (1 − E_avg)), F_ss the lobe's mean
  Fresnel (F0 + (1 − F0)/21 for Schlick).
* **Masking-shadowing**: Smith height-correlated G2 = 1/(1 + Λi + Λo) (Cycles ``bsdf_G``), so
  f = F D G2 / (4 μi μo) = F D / (2 (μo s_i + μi s_o)), s = √(μ² + α² (1 − μ²)): finite at grazing.

Directional albedos are not tabulated (Cycles reads precomputed tables): :func:`principled_directional_albedos`
integrates them per point by a deterministic 8×8 NDF-importance quadrature of half vectors (smooth
integrand, within ~1e-3 of a converged integral), once per pixel, not per light; E_avg = 2∫E μ dμ by
4-point Gauss-Legendre in μ with 4×4 half vectors each. E_spec is 0.04–0.25 for dielectrics and
1 − E ≤ 3 % at roughness ≤ 0.4, so these only move the result by small corrections.

Directions point away from the surface, unit; ``incoming`` = towards the light, ``outgoing`` =
towards the viewer. Returned BRDFs exclude the cosine.
"""

from __future__ import annotations

import numpy as np

from .ggx import fresnel_schlick, ggx_ndf
from .numerics import dot, f64, norm, safe_normalize, safe_ratio

#: Smallest GGX α (roughness 1e-3), also the RSM's (``reference/rsm.py``).
ALPHA_MIN = 1e-6
#: Largest dielectric F0 (η = 1e4·…): keeps η = (1 + √F0)/(1 − √F0) finite.
F0_MAX = 0.9999
#: Smallest μo used for the view-dependent albedos (a grazing or back-facing view).
MU_MIN = 1e-4

#: Half-vector grid of the directional albedo quadrature (ALBEDO_GRID² points) and of each of the
#: four μ nodes of the average albedo.
ALBEDO_GRID = 8
AVERAGE_GRID = 4

_GAUSS_NODES = np.array([0.0694318442029737, 0.3300094782075719, 0.6699905217924281, 0.9305681557970263])
_GAUSS_WEIGHTS = np.array([0.1739274225687269, 0.3260725774312731, 0.3260725774312731, 0.1739274225687269])


def principled_alpha(roughness):
    """GGX α = roughness² (roughness clamped to [0, 1]), at least ALPHA_MIN."""
    r = np.clip(f64(roughness), 0.0, 1.0)
    return np.maximum(r * r, ALPHA_MIN)


def principled_dielectric_f0(ior, specular_ior_level):
    """F0 = ((ior − 1)/(ior + 1))² · 2 · level, clamped to [0, F0_MAX]."""
    ior = f64(ior)
    ratio = (ior - 1.0) / (ior + 1.0)
    return np.clip(ratio * ratio * 2.0 * np.maximum(f64(specular_ior_level), 0.0), 0.0, F0_MAX)


def fresnel_dielectric_f0(cos_theta, f0):
    """Unpolarised Fresnel reflectance of a dielectric whose normal-incidence reflectance is f0
    (η = (1 + √f0)/(1 − √f0) ≥ 1, seen from outside); 1 at grazing, f0 at normal incidence."""
    c = np.clip(np.abs(f64(cos_theta)), 0.0, 1.0)
    f0 = np.clip(f64(f0), 0.0, F0_MAX)
    root = np.sqrt(f0)
    eta = (1.0 + root) / (1.0 - root)
    g2 = eta * eta - 1.0 + c * c
    g = np.sqrt(np.maximum(g2, 0.0))
    a = (g - c) / np.maximum(g + c, 1e-30)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return np.clip(0.5 * a * a * (1.0 + b * b), 0.0, 1.0)


def _correlated_denominator(ci, co, a2):
    """μo s_i + μi s_o, s = √(μ² + α² (1 − μ²)): 2 μi μo (1 + Λi + Λo) of the height-correlated
    Smith G2 (Cycles ``bsdf_G``)."""
    si = np.sqrt(ci * ci + a2 * (1.0 - ci * ci))
    so = np.sqrt(co * co + a2 * (1.0 - co * co))
    return co * si + ci * so


def principled_g2_ratio(ci, co, a2):
    """2 μi / (μo s_i + μi s_o): the height-correlated Smith G2 divided by μo."""
    return 2.0 * ci / _correlated_denominator(ci, co, a2)


def albedo_quadrature(mu, roughness, samples: int = ALBEDO_GRID):
    """Directional albedos of GGX reflection at μo by deterministic NDF-importance quadrature:
    ``samples``² stratified midpoints (u1, u2) → half vectors h (cos²θh = (1 − u1)/(1 + (α² − 1) u1),
    φ = 2π u2), ωi = reflect(ωo, h); the estimator F(ωo·h) G2 (ωo·h)/(μo μh) is smooth in h.

    Returns per point the weights of the three Fresnel laws, as (E_white, cos_oh, weight) arrays of
    shape (..., samples²): E = Σ weight · F(cos_oh). Shared by the white, dielectric and metal
    albedos (:func:`principled_directional_albedos`).
    """
    mu = np.clip(f64(mu), MU_MIN, 1.0)[..., None]
    alpha = principled_alpha(roughness)
    a2 = (f64(alpha) ** 2)[..., None]
    u = (np.arange(samples) + 0.5) / samples
    u1, u2 = (g.ravel() for g in np.meshgrid(u, u, indexing="ij"))
    cos2 = (1.0 - u1) / (1.0 + (a2 - 1.0) * u1)
    ch = np.sqrt(cos2)
    sh = np.sqrt(np.maximum(1.0 - cos2, 0.0))
    phi = 2.0 * np.pi * u2
    so = np.sqrt(np.maximum(1.0 - mu * mu, 0.0))
    # o = (so, 0, mu), h = (sh cos phi, sh sin phi, ch)
    oh = so * sh * np.cos(phi) + mu * ch
    ci = 2.0 * oh * ch - mu
    valid = (ci > 0.0) & (oh > 0.0)
    ci_ = np.where(valid, ci, 1.0)
    weight = np.where(valid, principled_g2_ratio(ci_, mu, a2) * oh / ch / (samples * samples), 0.0)
    return weight, np.where(valid, oh, 1.0)


def principled_directional_albedos(mu, roughness, f0_dielectric, f0_metal, samples: int = ALBEDO_GRID):
    """(E_white, E_dielectric, E_metal RGB): single-scattering directional albedos of GGX at μo with
    Fresnel 1, the dielectric Fresnel of f0_dielectric, and Schlick of f0_metal (RGB)."""
    weight, oh = albedo_quadrature(mu, roughness, samples)
    f_d = fresnel_dielectric_f0(oh, f64(f0_dielectric)[..., None])
    m = (1.0 - np.clip(oh, 0.0, 1.0)) ** 5
    e_white = weight.sum(axis=-1)
    e_schlick = (weight * m).sum(axis=-1)  # E_metal = f0 (E_white - e_schlick) + e_schlick
    f0m = f64(f0_metal)
    e_metal = f0m * (e_white - e_schlick)[..., None] + e_schlick[..., None]
    return e_white, (weight * f_d).sum(axis=-1), e_metal


def principled_average_albedo(roughness, samples: int = AVERAGE_GRID):
    """E_avg = 2 ∫ E_white(μ) μ dμ: 4-point Gauss-Legendre in μ, ``samples``² half vectors each."""
    r = f64(roughness)
    total = np.zeros(np.shape(r))
    for node, weight in zip(_GAUSS_NODES, _GAUSS_WEIGHTS):
        w, _ = albedo_quadrature(np.full(np.shape(r), node), r, samples)
        total = total + weight * 2.0 * node * w.sum(axis=-1)
    return total


def principled_mean_schlick(f0):
    """Hemispherical cosine-weighted mean of Schlick's Fresnel: f0 + (1 − f0)/21."""
    return f64(f0) + (1.0 - f64(f0)) / 21.0


def principled_multiscatter(e_white, e_avg, fss):
    """1 + F_ms (1 − E)/E, F_ms = F_ss E_avg / (1 − F_ss (1 − E_avg)) (Cycles' energy preservation);
    numpy broadcasting (``fss`` RGB with e's [..., None])."""
    e = np.clip(f64(e_white), 1e-3, 1.0)
    e_avg = np.clip(f64(e_avg), 0.0, 1.0)
    fss = f64(fss)
    fms = fss * e_avg / (1.0 - fss * (1.0 - e_avg))
    return 1.0 + fms * (1.0 - e) / e


def principled_terms(base_color, metallic, specular_ior_level, ior, roughness, mu_o):
    """The per-pixel terms the shading needs (view-dependent through μo = n·ωo):

    ``diffuse`` Rd = base (1 − m)(1 − E_spec(μo)) (RGB), ``f0_dielectric`` (scalar),
    ``f0_metal`` = base (RGB), ``ms_dielectric`` (scalar) and ``ms_metal`` (RGB) multiple-scattering
    factors, ``specular_albedo`` (RGB) the specular lobes' albedo (what Cycles' Glossy Color holds),
    ``alpha``.
    """
    base = np.maximum(f64(base_color), 0.0)
    m = np.clip(f64(metallic), 0.0, 1.0)
    f0 = principled_dielectric_f0(ior, specular_ior_level)
    e_white, e_d, e_m = principled_directional_albedos(mu_o, roughness, f0, base)
    e_avg = principled_average_albedo(roughness)
    ms_d = principled_multiscatter(e_white, e_avg, principled_mean_schlick(f0))
    ms_m = principled_multiscatter(f64(e_white)[..., None], f64(e_avg)[..., None], principled_mean_schlick(base))
    e_dielectric = np.clip(e_d * ms_d, 0.0, 1.0)
    e_metal = np.clip(e_m * ms_m, 0.0, 1.0)
    m3 = m[..., None]
    return {
        "diffuse": base * (1.0 - m3) * (1.0 - e_dielectric)[..., None],
        "f0_dielectric": f0,
        "f0_metal": base,
        "ms_dielectric": ms_d,
        "ms_metal": ms_m,
        "specular_albedo": (1.0 - m3) * e_dielectric[..., None] + m3 * e_metal,
        "alpha": principled_alpha(roughness),
    }


def principled_ggx_correlated(ci, co, d, a2):
    """D G2 / (4 μi μo) with Smith height-correlated G2: D / (2 (μo s_i + μi s_o)) for the NDF
    value ``d``; 0 unless both cosines are > 0."""
    ci, co = f64(ci), f64(co)
    valid = (ci > 0.0) & (co > 0.0)
    denominator = 2.0 * _correlated_denominator(np.maximum(ci, 0.0), np.maximum(co, 0.0), f64(a2))
    return np.where(valid, safe_ratio(f64(d), denominator), 0.0)


def principled_brdf(incoming, outgoing, normal, base_color, roughness, metallic,
                    specular_ior_level, ior):
    """(diffuse, specular) BRDF values (RGB, 1/sr, no cosine) of the Principled base layer for light
    arriving from ``incoming``, seen from ``outgoing``. 0 when either is below the surface."""
    wi, wo, n = f64(incoming), f64(outgoing), f64(normal)
    ci, co = dot(wi, n), dot(wo, n)
    terms = principled_terms(base_color, metallic, specular_ior_level, ior, roughness, co)
    above = (ci > 0.0) & (co > 0.0)
    diffuse = np.where(above[..., None], terms["diffuse"] / np.pi, 0.0)
    h = wi + wo
    length = norm(h)
    ok = above & (length > 0.0)
    h = safe_normalize(h, 0.0, length)
    ch = dot(h, n)
    ih = dot(wi, h)
    lobe = principled_ggx_correlated(ci, co, ggx_ndf(ch, terms["alpha"]), f64(terms["alpha"]) ** 2)
    m = np.clip(f64(metallic), 0.0, 1.0)[..., None]
    f_dielectric = fresnel_dielectric_f0(ih, terms["f0_dielectric"])[..., None] * terms["ms_dielectric"][..., None]
    f_metal = fresnel_schlick(ih[..., None], terms["f0_metal"]) * terms["ms_metal"]
    specular = ((1.0 - m) * f_dielectric + m * f_metal) * lobe[..., None]
    return diffuse, np.where(ok[..., None], specular, 0.0)
