# SPDX-License-Identifier: GPL-3.0-or-later
"""Shading with virtual spherical Gaussian lights (VSGLs), float64 ground truth (formulas.md §6).

000 = Tokuyoshi, "Modified filtered importance sampling for virtual spherical Gaussian lights"
(CVM 2016), app. C; 003 = the Square Enix SG talk (2015). Twin: ``glsl/lib/vsgl_shading.glsl``.

For a shading point y_p with normal n_p, view direction ω_o (towards the eye) and a material
(diffuse reflectance Rd RGB, specular F0 RGB, GGX roughness α), each VSGL lobe (the diffuse and
the specular SG of every VSGL both illuminate) gives one incoming-radiance SG (000 Eq. 12):

    ξµ = (µv − y_p)/|µv − y_p|,  λσ = |µv − y_p|²/σv²,
    Lin(ω) ≈ cv/(2πσv²) G(ω; −ξv, λv) G(ω; ξµ, λσ) = cin G(ω; ξin, λin),

the product taken with ``sg.sg_product`` (stable exponent |ξm| − λ1 − λ2), µv and σv² the lobe's
own (``diffuse_mean``/``specular_mean``; ``vsgl.POSITIONAL_DISTRIBUTIONS``: the same for both
lobes in the paper's "shared" form, 000 app. B.2). Then, per lobe:

* **Diffuse**, mode ``"separable"`` (the default of the modified and original kernels,
  ``diffuse_mode_for_kernel``): the incoming radiance of 000 Eqs. 10-11 with the radiant intensity
  taken at the direction of the lobe's mean instead of multiplied into one SG with the positional
  lobe (``vsgl_separable_lobe``),

      Lin(ω) ≈ cv G(−ξµ; ξv, λv) G(ω; ξµ, λσ)/(2πσv²),
      Ld = cv G(−ξµ; ξv, λv)/(2πσv²) · Rd/π · A(λσ) ⟨ξµ, n_p⟩

  (the cosine pulled out of the positional lobe's integral as in 000 app. C, exact A), where a
  flat cluster's diffuse lobe emits as its texels' Lambertian lobes instead of 000 Eq. 6's SG,
  cv G(−ξµ; ξv, λv) → :func:`vsgl_diffuse_emission` (``diffuse_emission="lambert"``, the default;
  "sg" keeps the SG for every cluster; why: docs/accuracy.md, "The diffuse lobe of a flat
  cluster"). Why not
  Eq. 12's product for the diffuse: it tilts the incoming lobe's axis to (λσ ξµ − λv ξv)/λin,
  towards −ξv, by as much as the positional lobe is broad. For a cluster spanning a room's corner
  (its mean between floor and wall, ξv diagonal, λv broad) the receivers across the room then see
  the lobe centred behind the cluster's own walls, and the pulled-out cosine drops most of it: one
  corner VSGL gives 0.72 of its VPLs' light (brute force with SG lobes), the separable form 0.87
  (tests/test_reference_vsgl_shading.py); in the suite's Cornell box and closed room the VSGLs
  whose |ξ̄| is under 0.9 of a flat cluster's carry 18 % and 22 % of the diffuse light with Eq. 12
  but give 39 % and 73 % of what the separable form adds (benchmarks/diffuse_mode_shares.py), and
  the closed room's VSGLs then give 0.99 of Cycles' light against their SG-lobe VPLs' 1.01
  (benchmarks/energy_budget.py). The specular keeps Eq. 12's product (below). Far from the VSGL the two forms are the same point light
  Iv(−ξµ) ⟨ξµ, n⟩/d² (000 app. C.1 derives Eq. 12 for small σv or large distances): their exponents
  differ by λv²(1 − ⟨ξµ, −ξv⟩²)/(2λσ) to first order, within 2 % at 100 σv for λv ≤ 10. Near a
  sharp lobe (λσ ≲ λv²) the separable form keeps the emission lobe's own width where Eq. 12 widens
  it by the positions' spread. A receiver on a flat VSGL's own plane has ⟨ξµ, n⟩ = 0: no light
  from its own surface, as Lambert's reflector gives it none.
  Mode ``"cosine"`` (000 app. C, Eq. 12's SG, cosine pulled out of the integral):
  ``Ld = cin Rd/π · A(λin) ⟨ξin, n_p⟩`` with the exact A(λ) (``sg.sg_integral``), not its
  large-λ form 2π/λ. Mode ``"sg-convolution"`` (003's simplified 2-VSGL mode, formulas §6):
  ``Ld = cin Rd ∫ G(ω; ξin, λin) G(ω; n_p, λd)/A(λd) dω`` (``sg.sg_product_integral``, λd = 2).
  Mode ``"clamped-cosine"``: ``Ld = cin Rd/π ∫ G(ω; ξin, λin) max(⟨ω, n_p⟩, 0) dω``
  (``sg.sg_clamped_cosine_integral``, the closed form of Tokuyoshi et al. 2024, within 1e-3 of its
  peak of the exact integral). 000's form is its limit for sharp lobes far above the horizon; for
  broad incoming lobes (λin ~ 1-10: a VSGL near the receiver, a wide cluster) it overestimates the
  light from straight above (×1.73 at λ = 2) and drops every lobe whose axis is below the horizon.
  Integrating Eq. 12's SG exactly is not the default all the same, because that SG is wrong where
  000's form hides it: a receiver on or near a flat VSGL's own surface sees Eq. 12's lobe centred
  below its horizon (the isotropic Gaussian of positions and the diffuse lobe's tail behind its
  plane, which the hemisphere normalization counts as absent), whose upper part the exact integral
  turns into light the surface gives itself; Lambert's reflector gives it none
  (tests/test_reference_vsgl_shading.py: 44 % of a wall's light on a lit floor patch; in the suite the
  occluder scene's mean goes from 0.94 to 2.04 of Cycles, while the closed room's goes from 0.84 to
  0.90 and its relative RMSE from 0.23 to 0.18).
* **Specular** (000 app. C): the receiver's GGX lobe ρs⟨ω,n⟩ ≈ C(ω) Ǵ(ω) with the ASG of 003 at
  the shading point (``asg.asg_specular_lobe``: bandwidths ηx = λh/(8 cos²θo), ηy = λh/8,
  λh = 2/α², i.e. D(ω_h) ≈ D(1) · exp(−ηx (ω·ξx)² − ηy (ω·ξy)²)), and

      Ls ≈ cin C(ξin) ∫ G(ω; ξin, λin) Ǵ(ω) dω
         ≈ cin C(ξin) · π/sqrt((ηx+ν)(ηy+ν)) · Ǵ(ξin; ηxν/(ηx+ν), ηyν/(ηy+ν)),  ν = λin/2
      (``asg.sg_asg_convolution``).

  **C exactly**: with ωi = ξin, h = (ωi + ωo)/|ωi + ωo|, ci = ⟨ωi, n⟩, co = ⟨ωo, n⟩,
  s = sqrt((1 − α²)c² + α²) (GGX Smith, separable G2 = G1(ci) G1(co) as in ``ggx.microfacet_brdf``):

      C(ωi) Ǵ(ωi) := F(ωi·h) G2 D(1) exp(−ηx(ωi·ξx)² − ηy(ωi·ξy)²) ci / (4 ci co)
                   = F(ωi·h) D(1) · ci / ((ci + si)(co + so)) · exp(...),    D(1) = 1/(πα²),

  i.e. C = Fresnel × masking × 1/(4 cos cos) × D's normalization × ⟨ωi,n⟩/⟨ωi,ξz⟩: the ASG's own
  smooth factor ⟨ω, ξz⟩ (ξz = mirror direction) is replaced by the rendering equation's cosine
  ⟨ω, n⟩, which ρs⟨ω,n⟩ really has. In code that is ``sg_asg_convolution`` with z = n_p
  (``specular_cosine="normal"``, the default). Keeping the ASG's ⟨ω, ξz⟩ instead
  (``specular_cosine="lobe-axis"``, C = F G2 D(1)/(4 ci co) literally) overestimates by up to
  1/cos θo (×2 at 60°); against brute force (tests/test_reference_vsgl_shading.py) its specular
  error is 40-59 % where the default's is 24-38 %.
  Specular mode ``"product"`` (the default, the GPU's) is that, with Eq. 12's SG, whose cin, for a
  diffuse lobe with the separable diffuse and ``diffuse_emission="lambert"``, is scaled to the flat
  cluster's Lambertian emission (:func:`vsgl_diffuse_emission_ratio`) at the direction the receiver
  gathers the lobe's light from (:func:`specular_emission_direction`): the peak of the incoming SG
  times the receiver's lobe warped to its reflection direction (000 Eq. 7). The SG's emission is
  below Lambert's by up to 20 % at 45-70° from a flat reflector's normal and above it near grazing,
  so a sharp receiver facing a lit floor got too little of it: the demo's gold 0.87 of Cycles in the
  bright band of the floor's reflection, 0.93 with Lambert's (docs/accuracy.md, "A flat cluster's
  emission seen by glossy receivers"). At the point-light limit (λσ → ∞) the direction is between
  ξµ and the mirror direction by the two lobes' sharpness. Mode
  ``"separable"`` (measured, not shipped) carries the diffuse's separable form to the receiver:
  Ls ≈ cv G(−ξµ; ξv, λv)/(2πσv²) · C(ξµ) ∫ G(ω; ξµ, λσ) Ǵ(ω) dω, the positional lobe convolved
  with the receiver's ASG and the emission taken at the mean's direction. It is the point light at
  N = M as the product is, but clustered it is worse on sharp receivers: over the positional lobe,
  which straddles a flat cluster's plane, it keeps the emission of −ξµ where the product's
  G(ω; −ξv, λv) fades towards grazing, so a sharp lobe aimed at the floor near grazing gets too much
  (tests/test_reference_vsgl_shading.py: against exact VPLs 0.56 against 0.38 at α = 0.1; on the
  demo's gold, the glossy receivers' VSGLs give 0.919 against 0.913 of the exact VPLs' light but
  per-pixel RMSE 0.640 against 0.602: benchmarks/specular_receiver_split.py, docs/accuracy.md).
  Zero when co ≤ 0 (view below the shading normal: χ+). The receiver's α is clamped to
  ``ALPHA_MIN`` (λh = 2/α² ≤ 2e6, the range the SG/ASG float32 libraries are built for).

Guards (finite everywhere): |µv − y_p| → 0 (λσ → 0, ξµ irrelevant in Eq. 12, −ξv used for it,
in the separable form too), σv² floored at
``VARIANCE_FLOOR`` (the generator's absolute floor: 1/(2πσv²) ≤ 1.6e11), λ's up to ~1e20
(products and A(λ) stay in range), grazing views (ASG floors), back-facing VSGLs (⟨ξin,n⟩ = 0),
zero-power VSGLs (amplitude 0).

Brute force (``brute_force_shading``): every RSM texel a VPL (000 §4, formulas §4):
I(ω) = Φ ρ(y, ω', ω) ⟨ω, n⟩ with ρ = Rd/π + GGX(F0 = Rs, α), summed exactly at the shading point
with the receiver's exact Lambert + GGX BRDF; ``vpl_lobes="sg"`` replaces the VPL's BRDF lobes by
000 Eqs. 6-7 (the SGs the VSGLs are built from) to separate the approximation errors.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .asg import asg_specular_lobe, sg_asg_convolution
from .ggx import fresnel_schlick, ggx_g1_denominator, microfacet_brdf
from .numerics import dot, f64, norm, safe_normalize
from .sg import (DIFFUSE_HEMISPHERE_SCALE, DIFFUSE_SHARPNESS, diffuse_lobe_hemisphere, sg_clamped_cosine_integral,
                 sg_evaluate,
                 sg_integral, sg_product, sg_product_integral, specular_lobe_warp)
from .vsgl import (MOMENT_CHANNELS, RSM, VARIANCE_FLOOR_ABSOLUTE, texel_moments,
                   vsgl_parameters)

#: Floor on σv² (same as the generator's absolute floor, 000 app. B.2).
VARIANCE_FLOOR = VARIANCE_FLOOR_ABSOLUTE
#: Smallest receiver GGX α (λh = 2/α² = 2e6).
ALPHA_MIN = 1e-3
DIFFUSE_MODES = ("separable", "cosine", "sg-convolution", "clamped-cosine")
SPECULAR_MODES = ("product", "separable")
SPECULAR_COSINES = ("normal", "lobe-axis")

#: VSGL fields read by shading (a dict from ``vsgl.generate_vsgls`` or ``read_table``): each lobe
#: with its own position (``vsgl.POSITIONAL_DISTRIBUTIONS``; equal for "shared").
VSGL_KEYS = ("diffuse_mean", "diffuse_variance", "diffuse_amplitude", "diffuse_axis",
             "diffuse_sharpness", "specular_mean", "specular_variance", "specular_amplitude",
             "specular_axis", "specular_sharpness")


def diffuse_mode_for_kernel(kernel: str) -> str:
    """003's 2-VSGL mode shades with the diffuse SG convolution, the others with the separable
    incoming radiance, cosine pulled out (000 Eqs. 10-11 and app. C; why not Eq. 12's product, nor
    the clamped-cosine integral: the module documentation)."""
    return "sg-convolution" if kernel == "two-vsgl" else "separable"


#: The diffuse mode of a call that names none: the renderer's for the settings' default kernel
#: ("modified"), so a direct caller shades as the frame does.
DEFAULT_DIFFUSE_MODE = diffuse_mode_for_kernel("modified")


def vsgl_incoming_sg(position, mean, variance, lobe_axis, lobe_sharpness):
    """Incoming radiance SG of one VSGL lobe at shading points (000 Eq. 12), without cv.

    Returns ``(axis_in, sharpness_in, scale)`` with cin = cv · scale,
    scale = e^(λin − λv − λσ) / (2π σv²). Broadcasts (vectors in a trailing axis of 3).
    """
    r = f64(mean) - f64(position)
    d2 = dot(r, r)
    dist = np.sqrt(d2)
    lobe_axis = f64(lobe_axis)
    r, lobe_axis = np.broadcast_arrays(r, lobe_axis)
    # At y_p = µv λσ = 0 and the axis is irrelevant; −ξv keeps it a unit vector.
    xi_mu = safe_normalize(r, -lobe_axis, dist)
    var = np.maximum(f64(variance), VARIANCE_FLOOR)
    lam_sigma = d2 / var
    axis_in, lam_in, scale = sg_product(-lobe_axis, f64(lobe_sharpness), xi_mu, lam_sigma)
    return axis_in, lam_in, scale / (2.0 * np.pi * var)


def vsgl_separable_lobe(position, mean, variance, lobe_axis, lobe_sharpness, emission="sg"):
    """The separable incoming radiance of one VSGL lobe (000 Eqs. 10-11 with Iv(−ω) taken at the
    direction of µv), without cv: Lin(ω) ≈ cv G(−ξµ; ξv, λv) G(ω; ξµ, λσ)/(2πσv²).

    Returns ``(xi_mu, lam_sigma, scale)`` with Lin = cv · scale · G(ω; ξµ, λσ),
    scale = G(−ξµ; ξv, λv)/(2πσv²) (``emission`` "sg"; "lambert": a diffuse lobe's
    :func:`vsgl_diffuse_emission` at −ξµ in place of the SG). Broadcasts (vectors in a trailing axis
    of 3). At y_p = µv (λσ = 0) −ξv stands in for ξµ, as in :func:`vsgl_incoming_sg`.
    """
    r = f64(mean) - f64(position)
    d2 = dot(r, r)
    lobe_axis = f64(lobe_axis)
    r, lobe_axis = np.broadcast_arrays(r, lobe_axis)
    xi_mu = safe_normalize(r, -lobe_axis, np.sqrt(d2))
    var = np.maximum(f64(variance), VARIANCE_FLOOR)
    if emission == "lambert":
        intensity = vsgl_diffuse_emission(dot(-xi_mu, lobe_axis), lobe_sharpness)
    elif emission == "sg":
        intensity = sg_evaluate(-xi_mu, lobe_axis, f64(lobe_sharpness))
    else:
        raise ValueError(f"emission must be one of {EMISSIONS}, got {emission!r}")
    return xi_mu, d2 / var, intensity / (2.0 * np.pi * var)


#: The mean normal length r̄ over which a diffuse lobe's emission goes from 000 Eq. 6's SG to its
#: texels' Lambertian lobe (smoothstep): a flat cluster (r̄ ≥ 0.97 is the flat class of
#: benchmarks/results/vsgl_aggregation_diagnosis.md) emits as Lambert's lobe, one spanning surfaces
#: that face different ways keeps the SG, which gives rooms' corner clusters more of their light
#: than a Lambert lobe of their normals' spread (a vMF of them) does: the 24 lights 0.883 → 0.843 of
#: Cycles with that for every cluster.
FLAT_CLUSTER = (0.95, 0.99)
#: The separable diffuse's emission of a VSGL's diffuse lobe (EMISSIONS): "lambert", flat clusters'
#: texels' Lambertian lobe (vsgl_diffuse_emission), or "sg", 000 Eq. 6's SG for every cluster.
EMISSIONS = ("lambert", "sg")


def mean_normal_length(lobe_sharpness):
    """r̄ of a VSGL diffuse lobe's texel normals, from its λv (000 app. B.1): every texel adds
    ξ̄ = λd/(λd + 1) n (Toksvig, λd = 2), so r̄ = |ξ̄v| (λd + 1)/λd with |ξ̄v| = λv/(λv + 1)."""
    lam = np.maximum(f64(lobe_sharpness), 0.0)
    return np.clip(lam / (lam + 1.0) * ((DIFFUSE_SHARPNESS + 1.0) / DIFFUSE_SHARPNESS), 0.0, 1.0)


def vsgl_diffuse_emission(cosine, lobe_sharpness):
    """The separable diffuse's radiant intensity of a VSGL diffuse lobe per unit cv towards a
    direction at cosine μ to its axis ξv (emission "lambert"): 000 Eq. 6's SG e^(λv (μ − 1)) blended
    by smoothstep over FLAT_CLUSTER of r̄ (mean_normal_length) into its texels' Lambertian lobe
    P max(μ, 0)/π, P = cv A(λv)/(1 + e^(−λd)) the cluster's flux (vsgl.vsgl_parameters'
    hemisphere-normalized amplitude). Why: the SG (λd = 2) keeps e^(−2) of its peak at the horizon,
    where a Lambertian texel sends nothing, so a flat reflector lights what it sees at grazing angles
    too much: on the suite's occluder, whose floor lights the occluding wall edge-on, the relative
    RMSE against Cycles falls from 0.83 with the SG to 0.20 (docs/accuracy.md, "The diffuse lobe of a
    flat cluster")."""
    mu = f64(cosine)
    lam = f64(lobe_sharpness)
    low, high = FLAT_CLUSTER
    t = np.clip((mean_normal_length(lam) - low) / (high - low), 0.0, 1.0)
    weight = t * t * (3.0 - 2.0 * t)
    sg = np.exp(lam * (np.minimum(mu, 1.0) - 1.0))
    lambert = sg_integral(lam) / DIFFUSE_HEMISPHERE_SCALE * np.maximum(mu, 0.0) / np.pi
    return (1.0 - weight) * sg + weight * lambert


#: Cap on the exponent λv (1 − μ) of :func:`vsgl_diffuse_emission_ratio`. A diffuse lobe's λv is at
#: most λd = 2 (Toksvig of its texels' λd-lobes, 000 app. B.1) and Lambert's lobe is 0 below μ = 0, so
#: the exponent stays ≤ 2 wherever the ratio is used; the cap 2 λd only bounds out-of-range sharpnesses
#: (the ratio then stays ≤ e⁴ A(λv)/π, finite times any float32 amplitude).
EMISSION_RATIO_EXPONENT_MAX = 2.0 * DIFFUSE_SHARPNESS


def vsgl_diffuse_emission_ratio(cosine, lobe_sharpness):
    """:func:`vsgl_diffuse_emission` over 000 Eq. 6's SG e^(λv (μ − 1)) at the same cosine μ,
    without the division: (1 − w) + w P max(μ, 0)/π e^(min(λv (1 − μ), EMISSION_RATIO_EXPONENT_MAX)),
    w the flat-cluster weight and P the hemisphere-normalized flux of vsgl_diffuse_emission. 1 for a
    cluster that keeps the SG; for a flat one Lambert's lobe over the SG, 0 at and below the horizon."""
    mu = np.minimum(f64(cosine), 1.0)
    lam = f64(lobe_sharpness)
    low, high = FLAT_CLUSTER
    t = np.clip((mean_normal_length(lam) - low) / (high - low), 0.0, 1.0)
    weight = t * t * (3.0 - 2.0 * t)
    exponent = np.minimum(lam * (1.0 - mu), EMISSION_RATIO_EXPONENT_MAX)
    lambert = sg_integral(lam) / DIFFUSE_HEMISPHERE_SCALE * np.maximum(mu, 0.0) / np.pi * np.exp(exponent)
    return (1.0 - weight) + weight * lambert


def specular_emission_direction(axis_in, sharpness_in, view, normal, roughness):
    """Where a receiver's specular gathers one lobe's light from: the axis of the product of Eq. 12's
    incoming SG G(ω; ξin, λin) and the receiver's specular lobe warped to the reflection direction
    G(ω; ξs, λs) (000 Eq. 7, ``sg.specular_lobe_warp``), (λin ξin + λs ξs)/|λin ξin + λs ξs|
    (ξin where the sum vanishes). A broad receiver takes ξin, the incoming lobe's peak; a sharp one its
    mirror direction, as far as the incoming lobe reaches there."""
    reflection, lam_s = specular_lobe_warp(view, normal, np.maximum(f64(roughness), ALPHA_MIN))
    summed = f64(sharpness_in)[..., None] * f64(axis_in) + lam_s[..., None] * reflection
    return safe_normalize(summed, f64(axis_in), norm(summed))


def vsgl_diffuse_factor(axis_in, sharpness_in, normal, mode="cosine"):
    """Ld / (cin Rd): A(λin)/π ⟨ξin, n⟩ ("cosine", 000 app. C; also "separable", called with the
    positional lobe ξµ, λσ of :func:`vsgl_separable_lobe` and its scale as cin),
    ∫ G(ξin, λin) G(n, λd) dω / A(λd) ("sg-convolution", 003) or
    1/π ∫ G(ω; ξin, λin) max(ω·n, 0) dω ("clamped-cosine", Tokuyoshi et al. 2024)."""
    if mode == "clamped-cosine":
        return sg_clamped_cosine_integral(dot(f64(axis_in), f64(normal)), sharpness_in)
    if mode in ("cosine", "separable"):
        return sg_integral(sharpness_in) / np.pi * np.maximum(dot(f64(axis_in), f64(normal)), 0.0)
    if mode == "sg-convolution":
        return (sg_product_integral(axis_in, sharpness_in, normal, DIFFUSE_SHARPNESS)
                / sg_integral(DIFFUSE_SHARPNESS))
    raise ValueError(f"diffuse mode must be one of {DIFFUSE_MODES}, got {mode!r}")


def vsgl_specular_factor(axis_in, sharpness_in, view, normal, roughness, f0, specular_cosine="normal"):
    """Ls / cin, RGB (..., 3): C(ξin) · SG × ASG convolution (see the module documentation)."""
    axis_in = f64(axis_in)
    view = f64(view)
    normal = f64(normal)
    alpha = np.maximum(f64(roughness), ALPHA_MIN)
    a2 = alpha * alpha
    x_axis, y_axis, z_axis, eta_x, eta_y = asg_specular_lobe(view, normal, alpha)
    cos_axis = normal if specular_cosine == "normal" else z_axis
    if specular_cosine not in SPECULAR_COSINES:
        raise ValueError(f"specular_cosine must be one of {SPECULAR_COSINES}")
    conv = sg_asg_convolution(axis_in, sharpness_in, x_axis, y_axis, cos_axis, eta_x, eta_y)
    ci = np.maximum(dot(axis_in, normal), 0.0)
    co_raw = dot(view, normal)
    co = np.maximum(co_raw, 0.0)
    half = axis_in + view
    half = safe_normalize(half, normal, norm(half))
    d1 = 1.0 / (np.pi * a2)
    masking = ggx_g1_denominator(ci, a2) * ggx_g1_denominator(co, a2)
    k = np.where(co_raw > 0.0, conv * d1 / masking, 0.0)
    return k[..., None] * fresnel_schlick(dot(axis_in, half)[..., None], f0)


def _receivers(position, normal, view, diffuse_reflectance, specular_f0, roughness):
    """The shading points as flat float64 rows: (P, 3) vectors and colours, (P,) roughness."""
    return (f64(position).reshape(-1, 3), f64(normal).reshape(-1, 3), f64(view).reshape(-1, 3),
            f64(diffuse_reflectance).reshape(-1, 3), f64(specular_f0).reshape(-1, 3),
            f64(roughness).reshape(-1))


def _chunks(count, per_chunk):
    for start in range(0, count, per_chunk):
        yield slice(start, min(count, start + per_chunk))


def shade(vsgls, position, normal, view, diffuse_reflectance, specular_f0, roughness,
          diffuse_mode=DEFAULT_DIFFUSE_MODE, specular_cosine="normal", per_term=False, visibility=None,
          specular_mode="product", diffuse_emission="lambert"):
    """Indirect radiance (diffuse, specular), each (P, 3), at P shading points from N VSGLs.

    vsgls     dict with ``VSGL_KEYS`` (rows = VSGLs), e.g. from ``vsgl.generate_vsgls``.
    position, normal, view (P, 3) (view = unit vector from the point to the eye);
    diffuse_reflectance, specular_f0 (P, 3); roughness (P,) GGX α (clamped to ``ALPHA_MIN``).
    The sum over VSGLs of both lobes (diffuse SG and specular SG of each VSGL).
    ``per_term=True`` also returns the (P, N, 2, 3) contributions (lobe 0 = VSGL diffuse SG).
    ``visibility`` (P, N, 2): each lobe's visibility from each point (:func:`vsgl_visibility`),
    weighting its light; None: every lobe is seen. ``diffuse_mode`` (``DIFFUSE_MODES``): by default
    the renderer's for the default kernel (``DEFAULT_DIFFUSE_MODE``; 003's 2-VSGL tables want
    "sg-convolution", ``diffuse_mode_for_kernel``). ``specular_mode`` (``SPECULAR_MODES``): the
    receivers' specular term from Eq. 12's SG ("product") or from the separable incoming radiance
    ("separable"; the module documentation). ``diffuse_emission`` (``EMISSIONS``): with the
    separable diffuse, the VSGLs' diffuse lobes emit as :func:`vsgl_diffuse_emission` ("lambert",
    the GPU's) or as 000 Eq. 6's SG ("sg").
    """
    if diffuse_mode not in DIFFUSE_MODES:
        raise ValueError(f"diffuse mode must be one of {DIFFUSE_MODES}, got {diffuse_mode!r}")
    if specular_mode not in SPECULAR_MODES:
        raise ValueError(f"specular mode must be one of {SPECULAR_MODES}, got {specular_mode!r}")
    if diffuse_emission not in EMISSIONS:
        raise ValueError(f"diffuse emission must be one of {EMISSIONS}, got {diffuse_emission!r}")
    position, normal, view, rd, f0, alpha = _receivers(position, normal, view, diffuse_reflectance,
                                                       specular_f0, roughness)
    count = len(f64(vsgls["diffuse_variance"]).reshape(-1))
    diffuse = np.zeros((len(position), 3))
    specular = np.zeros((len(position), 3))
    terms = []
    chunk = max(1, 400_000 // max(len(position), 1))
    lobes = ("diffuse", "specular")
    for rows in _chunks(count, chunk):
        part = []
        for lobe in lobes:
            amp_key, axis_key, sharp_key = (f"{lobe}_amplitude", f"{lobe}_axis", f"{lobe}_sharpness")
            mean = f64(vsgls[f"{lobe}_mean"]).reshape(-1, 3)[rows][None]
            variance = f64(vsgls[f"{lobe}_variance"]).reshape(-1)[rows][None]
            amplitude = f64(vsgls[amp_key]).reshape(-1, 3)[rows][None]
            axis_in, lam_in, scale = vsgl_incoming_sg(
                position[:, None], mean, variance,
                f64(vsgls[axis_key]).reshape(-1, 3)[rows][None],
                f64(vsgls[sharp_key]).reshape(-1)[rows][None])
            seen = 1.0 if visibility is None else f64(visibility)[:, rows, lobes.index(lobe), None]
            c_in = amplitude * scale[..., None] * seen
            if "separable" in (diffuse_mode, specular_mode):
                xi_mu, lam_sigma, sep_scale = vsgl_separable_lobe(
                    position[:, None], mean, variance, f64(vsgls[axis_key]).reshape(-1, 3)[rows][None],
                    f64(vsgls[sharp_key]).reshape(-1)[rows][None])
            if diffuse_mode == "separable":
                if lobe == "diffuse" and diffuse_emission != "sg":
                    _, _, emitted = vsgl_separable_lobe(
                        position[:, None], mean, variance, f64(vsgls[axis_key]).reshape(-1, 3)[rows][None],
                        f64(vsgls[sharp_key]).reshape(-1)[rows][None], diffuse_emission)
                else:
                    emitted = sep_scale
                ld = (amplitude * emitted[..., None] * seen
                      * vsgl_diffuse_factor(xi_mu, lam_sigma, normal[:, None], "separable")[..., None]
                      * rd[:, None])
            else:
                ld = c_in * vsgl_diffuse_factor(axis_in, lam_in, normal[:, None], diffuse_mode)[..., None] \
                    * rd[:, None]
            if specular_mode == "separable":
                if lobe == "diffuse" and diffuse_mode == "separable" and diffuse_emission != "sg":
                    sep_scale = emitted
                ls = (amplitude * sep_scale[..., None] * seen
                      * vsgl_specular_factor(xi_mu, lam_sigma, view[:, None], normal[:, None], alpha[:, None],
                                             f0[:, None], specular_cosine))
            else:
                c_spec = c_in
                if lobe == "diffuse" and diffuse_mode == "separable" and diffuse_emission != "sg":
                    # The receiver's specular sees the flat cluster's Lambertian emission too, taken
                    # where it gathers the lobe's light (specular_emission_direction).
                    toward = specular_emission_direction(axis_in, lam_in, view[:, None], normal[:, None],
                                                         alpha[:, None])
                    c_spec = c_in * vsgl_diffuse_emission_ratio(
                        dot(-toward, f64(vsgls[axis_key]).reshape(-1, 3)[rows][None]),
                        f64(vsgls[sharp_key]).reshape(-1)[rows][None])[..., None]
                ls = c_spec * vsgl_specular_factor(axis_in, lam_in, view[:, None], normal[:, None],
                                                   alpha[:, None], f0[:, None], specular_cosine)
            diffuse += ld.sum(axis=1)
            specular += ls.sum(axis=1)
            if per_term:
                part.append(np.stack((ld, ls), axis=-2))
        if per_term:
            terms.append(np.stack(part, axis=2))
    if per_term:
        return diffuse, specular, np.concatenate(terms, axis=1)
    return diffuse, specular


# --- Brute force: every RSM texel a VPL ----------------------------------------------------------


@dataclass(frozen=True)
class VPLs:
    """Virtual point lights (000 §4): one per RSM texel, arrays (M, ...) or (H, W, ...).

    position (y), normal (n), flux Φ (RGB), diffuse_reflectance Rd (RGB), specular_f0 Rs (RGB,
    GGX Schlick F0), roughness α (GGX), incoming ω' (unit, from y towards the light).
    """

    position: np.ndarray
    normal: np.ndarray
    flux: np.ndarray
    diffuse_reflectance: np.ndarray
    specular_f0: np.ndarray
    roughness: np.ndarray
    incoming: np.ndarray

    def flat(self) -> "VPLs":
        return VPLs(*(f64(getattr(self, name)).reshape((-1, 3) if name != "roughness" else (-1,))
                      for name in self.__dataclass_fields__))

    def rsm(self) -> RSM:
        """The RSM of these VPLs as VSGL generation takes it (000 Eqs. 6-7 lobes)."""
        axis, sharpness = specular_lobe_warp(self.incoming, self.normal, self.roughness)
        return RSM(position=f64(self.position), normal=f64(self.normal),
                   flux_diffuse=f64(self.flux) * f64(self.diffuse_reflectance),
                   flux_specular=f64(self.flux) * f64(self.specular_f0),
                   specular_axis=axis, specular_sharpness=sharpness)


def _ggx_rgb(incoming, outgoing, normal, alpha, f0):
    """GGX BRDF for RGB F0 (Schlick is linear in F0): b0 + F0 (b1 - b0)."""
    b0 = microfacet_brdf(incoming, outgoing, normal, alpha, 0.0)
    b1 = microfacet_brdf(incoming, outgoing, normal, alpha, 1.0)
    return b0[..., None] + f64(f0) * (b1 - b0)[..., None]


def vpl_intensity(vpls: VPLs, directions, lobes="ggx"):
    """(diffuse, specular) radiant intensity (..., M, 3) of the VPLs towards unit `directions`
    (..., M, 3): Φ Rd/π ⟨ω,n⟩ and Φ f_GGX(ω', ω) ⟨ω,n⟩ ("ggx"), or the SG lobes of 000 Eqs. 6-7,
    Φ Rd G(ω; n, λd)/A_hemi(λd) (normalized over the hemisphere: ``sg.DIFFUSE_HEMISPHERE_SCALE``)
    and Φ Rs G(ω; ξs, λs)/A(λs) ("sg"): the lobes VSGL generation sums."""
    v = vpls.flat()
    cos = np.maximum(dot(directions, v.normal), 0.0)
    if lobes == "ggx":
        diffuse = v.flux * v.diffuse_reflectance / np.pi * cos[..., None]
        spec = v.flux * _ggx_rgb(v.incoming, directions, v.normal, v.roughness, v.specular_f0) \
            * cos[..., None]
        return diffuse, spec
    if lobes == "sg":
        diffuse = (v.flux * v.diffuse_reflectance
                   * diffuse_lobe_hemisphere(directions, v.normal)[..., None])
        axis, sharpness = specular_lobe_warp(v.incoming, v.normal, v.roughness)
        spec = (v.flux * v.specular_f0
                * (sg_evaluate(directions, axis, sharpness) / sg_integral(sharpness))[..., None])
        return diffuse, spec
    raise ValueError(f"lobes must be 'ggx' or 'sg', got {lobes!r}")


def brute_force_shading(vpls: VPLs, position, normal, view, diffuse_reflectance, specular_f0,
                        roughness, vpl_lobes="ggx"):
    """Exact one-bounce radiance (diffuse, specular), each (P, 3), from every VPL as a point light:
    L = Σ_j I_j(ω_j→p)/|y_j − y_p|² · ρ_p(ω, ω_o) ⟨ω, n_p⟩ with the receiver's Lambert + GGX BRDF
    (α clamped to ``ALPHA_MIN`` as in shading). No visibility (VSGL shading has none either).
    VPLs at the shading point are skipped."""
    v = vpls.flat()
    position, normal, view, rd, f0, alpha = _receivers(position, normal, view, diffuse_reflectance,
                                                       specular_f0, roughness)
    alpha = np.maximum(alpha, ALPHA_MIN)
    diffuse = np.zeros((len(position), 3))
    specular = np.zeros((len(position), 3))
    for p in range(len(position)):
        r = v.position - position[p]
        d2 = dot(r, r)
        ok = d2 > 0.0
        omega = r / np.sqrt(np.where(ok, d2, 1.0))[:, None]
        i_d, i_s = vpl_intensity(v, -omega, vpl_lobes)
        irradiance = (i_d + i_s) * np.where(ok, 1.0 / np.where(ok, d2, 1.0), 0.0)[:, None] \
            * np.maximum(dot(omega, normal[p]), 0.0)[:, None]
        diffuse[p] = (irradiance * rd[p] / np.pi).sum(axis=0)
        brdf = _ggx_rgb(omega, view[p], normal[p], alpha[p], f0[p])
        specular[p] = (irradiance * brdf).sum(axis=0)
    return diffuse, specular


def per_texel_vsgls(rsm) -> dict:
    """Every RSM texel its own VSGL (the N = M limit, 000 app. B with one VPL per cluster)."""
    rsm = RSM.coerce(rsm)
    return vsgl_parameters(texel_moments(rsm).reshape(-1, MOMENT_CHANNELS))


#: |ξ̄| of a flat reflector's diffuse lobe: every texel's lobe is the λ = 2 SG (000 app. B.1), whose
#: mean direction has length λ/(1 + λ).
FLAT_DIFFUSE_AXIS_LENGTH = DIFFUSE_SHARPNESS / (1.0 + DIFFUSE_SHARPNESS)


def vsgl_reflector_side(mean, axis, sharpness, position):
    """The share of a VSGL diffuse lobe that its own reflector does not hide from ``position``
    (..., 3): clamp(1 + sin ε / sin θc, 0, 1), ε the elevation of the receiver above the lobe's mean
    plane (through µv, normal ξv) and θc the half-angle of the cap of normals whose diffuse lobes
    sum to the lobe's mean direction length |ξ̄| = λv/(1 + λv): |ξ̄|/|ξ̄|_flat = (1 + cos θc)/2.

    Why: a flat reflector lights nothing behind its plane, but a VSGL would (000 Eq. 12): its
    positions are an isotropic Gaussian, which straddles the plane by σv, and at distances under
    σv the positional lobe is so wide that the product's axis follows the emission lobe — the sunlit
    back of a thin wall then lights the wall's own shaded front. The imperfect shadow map cannot
    stop that light (its origin sits on the reflector, whose own points it leaves out). A curved
    reflector's normals tilt by up to θc, so receivers down to θc below the plane keep a share (the
    brute-force share of a spherical cap's texels facing them: tests/test_vsgl_visibility.py).

    The shader no longer applies it (vsgl_visibility's ``reflector_side``): the VSGLs' maps keep
    their own reflector's surface (pipeline.VSGL_OWN_REFLECTOR_SIGMAS), and the cap model assumes a
    bent cluster convex, where a room corner's cluster is concave and lights the receivers between
    its walls (benchmarks/visibility_diagnosis.py gives what it would take)."""
    planarity = np.clip(f64(sharpness) / (1.0 + f64(sharpness)) / FLAT_DIFFUSE_AXIS_LENGTH, 0.0, 1.0)
    cos_c = 2.0 * planarity - 1.0
    sin_c = np.sqrt(np.maximum(1.0 - cos_c * cos_c, 0.0))
    offset = f64(position) - f64(mean)
    distance = norm(offset)
    sin_elevation = np.where(distance > 0.0, dot(f64(axis), offset) / np.where(distance > 0.0, distance, 1.0), 1.0)
    return np.clip(1.0 + sin_elevation / np.maximum(sin_c, 1e-4), 0.0, 1.0)


def vsgl_visibility(depths, maps_per_vsgl, vsgls, position, normal, max_radius, reflector_side=False, surfaces=False):
    """(P, N, 2) visibility of each VSGL lobe from P shading points (glsl/vsgl_shading's
    vsgl_visibility): the filtered lookup (reference.ism.ism_pcf) from the lobe's shadow origin
    (reference.ism.shadow_origin) in its map of
    ``depths`` (maps, S, S), map maps_per_vsgl·i (+ 1 for the specular lobe with two maps per
    VSGL; with one, both lobes take the map of the VSGL's diffuse lobe position ``diffuse_mean``): one texel where σ_v / distance is under half a texel (or ``max_radius`` is 0), else the
    bilinear filter of about two texels (reference.ism.ism_pcf_bilinear). ``reflector_side``: the
    diffuse lobe's times :func:`vsgl_reflector_side`, which the shader no longer applies
    (pipeline.VSGL_OWN_REFLECTOR_SIGMAS says why; benchmarks/visibility_diagnosis.py measures it).
    ``surfaces``: maps that keep their surfaces' depth and whose lookups take the surface normal
    offset (reference.ism.lookup_offsets; passes/ism.py ISMAtlas.normal_offset)."""
    from . import ism

    position, normal = f64(position).reshape(-1, 3), f64(normal).reshape(-1, 3)
    count = len(f64(vsgls["diffuse_variance"]).reshape(-1))
    size = depths.shape[-1]
    texel_angle = np.sqrt(4.0 * np.pi) / size
    result = np.ones((len(position), count, 2))
    for i in range(count):
        for lobe, name in enumerate(("diffuse", "specular")):
            if lobe == 1 and maps_per_vsgl == 1:
                result[:, i, 1] = result[:, i, 0]
                continue
            # One map per VSGL: at its diffuse lobe's positional Gaussian (pipeline.MAPS_PER_VSGL),
            # pushed along the diffuse axis.
            at = "diffuse_" if maps_per_vsgl == 1 else f"{name}_"
            variance = float(f64(vsgls[f"{at}variance"]).reshape(-1)[i])
            mean = ism.shadow_origin(f64(vsgls[f"{at}mean"]).reshape(-1, 3)[i], variance,
                                     f64(vsgls[f"{name}_axis"]).reshape(-1, 3)[i])
            sigma = np.sqrt(max(variance, 0.0))
            distance = np.linalg.norm(position - mean, axis=-1)
            radius = np.clip(np.floor(sigma / np.maximum(distance, 1e-30) / texel_angle + 0.5), 0, max_radius)
            for r in np.unique(radius).astype(int):
                here = radius == r
                depth = depths[maps_per_vsgl * i + lobe]
                result[here, i, lobe] = (ism.ism_pcf(depth, mean, position[here], 0, normals=normal[here],
                                                     surfaces=surfaces) if r == 0
                                         else ism.ism_pcf_bilinear(depth, mean, position[here], normals=normal[here],
                                                                   surfaces=surfaces))
    if not reflector_side:
        return result
    # The diffuse lobe's own reflector (vsgl_reflector_side); with one map per VSGL the specular
    # lobe took the diffuse lobe's map lookup above, without it.
    result[:, :, 0] *= vsgl_reflector_side(f64(vsgls["diffuse_mean"]).reshape(1, -1, 3),
                                           f64(vsgls["diffuse_axis"]).reshape(1, -1, 3),
                                           f64(vsgls["diffuse_sharpness"]).reshape(1, -1), position[:, None])
    return result
