# SPDX-License-Identifier: GPL-3.0-or-later
"""Glossy interreflection from a rectangle proxy with MRP-ASG, float64 (formulas.md §8).

001 = "rectangle-based MRP-ASG" (the paper in ../shared/papers/001_*). Twin: ``glsl/lib/mrp_asg.glsl``
(same function names). One rectangle R (centre c_r, unit normal n_r, orthonormal in-plane axes
u_r, v_r with half extents a_u, a_v, GGX roughness α_r, Schlick F0) reflects one light towards a
receiver x (position p_x, normal n_x, view o towards the eye, GGX α_x, F0); the result is the
radiance x sends to the eye through R's specular lobe (001 Eq. 3), in Blender's units.

Steps (001 §3):

1. Specular peak p_y, the point of R's plane whose half vector is n_r (Eq. 12). For a sun (the
   paper's distant light) ``mrp_peak_distant`` is Eq. 12. For a point, spot or area light the
   light direction varies over the plane; the exact peak is where the segment from p_x to the
   light's mirror image crosses the plane (``mrp_peak_local``: the reflected ray through it
   satisfies h = n_r by construction). No peak when the light or the receiver is not strictly in
   front of the plane (i·n_r ≤ 0, or the reflection r leaves R's front hemisphere).
2. Reflected radiance at the peak, L_y (Eqs. 15–17). 001 Eq. 17, L_y ≈ π m_r² f_r (i·n_y), is the
   one-sample estimate of Eq. 4 with the pdf D(0) cos θ for *unit incident radiance from every
   direction*; it has no light intensity in it, so it cannot carry a point light's W/sr or a sun's
   W/m². For Blender's lights (formulas §4) Eq. 4 is exact with the light's irradiance:
   L_y = f_r(i, r) (i·n_r) E⊥, E⊥ = I(−i)/d_l² for point/spot/area (I in W/sr) and E⊥ = S for a
   sun (``mrp_peak_radiance``). tests/test_reference_mrp_asg.py shows by quadrature of Eq. 3 that
   this form matches and Eq. 17 does not (docs/accuracy.md).
3. Disk integral (Eqs. 19–27), the solid-angle integral at x of the reflected radiance from a disk
   of radius r_d at p_y in R's plane: E = (π/k)(1 − e^(−k t)) L_y, k = 0.288 cos σ / m_r² − 0.673,
   t = 1 − 1/(1 + ρ² cos² σ), ρ = r_d / |p_y − p_x| (001 works at unit distance, §3.4),
   written π t · (1 − e^(−kt))/(kt), finite for k → 0 and k < 0 (kt ≥ −0.673).
   Eq. 24 derives ψ(θ) for a distant light: only the direction to x turns across the disk. For a
   local light the direction to the light turns too, by d_x/d_l times as much, so the half vector
   turns (1 + d_x/d_l) times as fast and the highlight seen from x is that much narrower; to first
   order in θ the fit's k is multiplied by s² = (1 + d_x/d_l)² (``spread``; 1 for a sun). Only a
   positive k is scaled (k < 0 is the fit's rough-reflector regime where it is only a floor).
4. Area ratio A (Eq. 36) from J, the bounding rectangle in R's frame of disk ∩ R (exact).
   001 divides by the disk's area, π r_d², which gives 4/π for a disk wholly inside R; dividing by
   the area of the disk's own bounding square, 4 r_d², gives 1 there and the exact 1/2 for a
   half disk; ``mrp_area_ratio`` uses 4 r_d² (``normalization="paper"`` keeps Eq. 36).
5. ASG light (Eqs. 18, 28–35): ŷx = (p_x − p_y)/|p_x − p_y|, v = ŷx × n_r, axis z = −ŷx,
   tangent m = v, bitangent n = ŷx × v; extents l_m = ρ, l_n = ρ (n_r·ŷx); bandwidths (Eq. 32,
   ε = 0.05) λ = (1 + 1/l_m²)(2.996 − ½ ln(1 + l_m²)), µ likewise; amplitude t = sqrt(λµ)/π · C,
   C = A E (Eq. 35), so that Eq. 34's integral of the ASG is C.
6. Receiver (Eqs. 6, 8, 10, 11): D(h) ≈ 1/(π α_x²) G(−r; r_x, λ_h / (4|o·n_x|)), λ_h = 2/α_x²,
   r_x = 2 (o·n_x) n_x − o; L_x ≈ M(−r_y, o) (−r_y·n_x) ∫ Ga Gi with the SG × ASG convolution of
   ``asg.sg_asg_convolution`` (ν = λ/2, docs/accuracy.md), M = F G2 / (4 cos cos) of GGX
   (separable Smith as ``ggx.microfacet_brdf``): M cos = F (−r_y·n_x)/((c_i + s_i)(c_o + s_o)).
   Mode ``"sg"`` (Eq. 37): the ASG becomes the SG G(v; z, 2 max(λ, µ)) with amplitude t and the
   SG × SG product integral replaces Eq. 11.
   ``mrp_receiver_quadrature`` integrates the ASG light against the receiver's exact GGX BRDF
   instead (a Gauss–Hermite rule on the light and a GGX rule on the receiver's lobe, combined by
   the balance heuristic): within 0.09 of that integral on the demo's gold sphere where Eq. 8's
   isotropic warp is 0.40 off, yet not the pass's, since against Cycles the frames do not improve
   (docs/accuracy.md, benchmarks/results/mrp_asg_receiver_quadrature.md).

Guards (finite everywhere): receiver in R's plane or at the peak (|p_y − p_x| → 0: no
contribution), ρ floored at ``EXTENT_FLOOR`` (λ ≤ ~3e8) and the bandwidths at ``BANDWIDTH_FLOOR``
(Eq. 32 turns negative for l > ~20, a cap wider than a hemisphere), ρ capped at ``EXTENT_MAX``, α's at ``ALPHA_MIN``, grazing
views (``sg.COSINE_FLOOR``), the normal-incidence frame (v = 0: any tangent, the ASG is isotropic
there since l_n = l_m).

``brute_force_rectangle`` is the truth for the tests: Eq. 3 over R by tensor-product
Gauss–Legendre on panels refined geometrically towards the peak and towards the receiver lobe's
mirror point, exact GGX at both ends, the light's exact irradiance at every point.
"""

from __future__ import annotations

import itertools

import numpy as np

from .asg import asg_any_tangent, asg_evaluate, asg_specular_lobe, sg_asg_convolution
from .ggx import fresnel_schlick, ggx_g1_denominator, ggx_ndf, microfacet_brdf
from .lights import light_intensity
from .numerics import dot, f64, norm, safe_normalize, safe_ratio
from .quadrature import composite_gauss_legendre
from .sg import COSINE_FLOOR, ndf_sharpness, sg_product_integral

#: Smallest GGX α at either end (λ_h = 2/α² = 2e6, as the VSGL shading's ALPHA_MIN).
ALPHA_MIN = 1e-3
#: Smallest unit-distance disk extent ρ = r_d/|p_y − p_x| (Eq. 32 gives λ ≈ 3e8 there).
EXTENT_FLOOR = 1e-4
#: Largest unit-distance extent (t of Eq. 27 is 1 to float precision long before; keeps ρ² finite
#: in float32).
EXTENT_MAX = 1e6
#: Smallest ASG bandwidth (Eq. 32 is negative for extents above ~20: wider than a hemisphere).
BANDWIDTH_FLOOR = 1e-3
#: Fit constants of 001 Eq. 25.
K_SLOPE = 0.288
K_OFFSET = 0.673
#: The sampling disk's radius in units of the reflector lobe's footprint (``mrp_lobe_extent``): at
#: least this much of the footprint, so the disk holds the highlight wherever the receiver is (a
#: fixed r_d loses most of it for far receivers, grazing light and rougher reflectors). 1.5 has the
#: lowest error of 1, 1.5 and 2 in the accuracy table (benchmarks/mrp_asg_accuracy.py, docs/accuracy.md).
DISK_LOBE_SCALE = 1.5
#: Disk-radius rules of ``mrp_shade``: 001's user-controlled r_d alone, or at least DISK_LOBE_SCALE
#: lobe footprints.
DISK_RULES = ("fixed", "lobe")
#: The receiver's GGX NDF as two SGs (weight, sharpness scale over Eq. 8's λ_h = 2/α²): GGX is
#: D(θ) = (1/πα²) (1 + θ²/α²)⁻² for small α, a narrower core than Eq. 8's single SG
#: e^(−θ²/α²) of the same peak and integral, with longer tails, so the single SG gives 1.25× the
#: light of a sharp receiver (α 0.05) whose light is about as wide as its lobe
#: (benchmarks/results/mrp_asg_receiver_split.md). 0.83 e^(−1.96 θ²/α²) + 0.17 e^(−0.295 θ²/α²)
#: keeps the peak (weights sum to 1) and the integral (Σ w/c = 1) and fits (1 + u²)⁻² with 1/30 of
#: the single SG's squared error (∫ (f − g)² u du, u = θ/α, least squares over w₁ and c₁).
RECEIVER_NDF_LOBES = ((0.83, 1.96), (0.17, 0.17 / (1.0 - 0.83 / 1.96)))
#: ε = 0.05 of 001 Eq. 31 gives ln(1/ε) = 2.996 in Eq. 32.
LOG_INV_EPSILON = 2.996
MODES = ("asg", "sg")
#: Receivers of ``mrp_shade``: Eq. 8's NDF as two SGs convolved by Eq. 11 (001's, ``mrp_convolve``,
#: the pass's), the ASG light against the receiver's exact GGX BRDF by quadrature
#: (``mrp_receiver_quadrature``), or Eq. 8's NDF warped as 003's ASG (``mrp_convolve_asg_receiver``).
RECEIVERS = ("sg", "quadrature", "asg")
#: Gauss–Hermite rule of the ASG light (nodes and weights for e^(−x²), weights over √π so they sum to
#: 1), QUADRATURE_LIGHT_NODES per axis of its tangent plane.
QUADRATURE_LIGHT_NODES = 4
#: The receiver's rule: Gauss–Legendre rings in the GGX half-vector CDF u (tan²θ_h = α² u/(1 − u))
#: times QUADRATURE_SECTORS equal sectors in azimuth, every other ring turned by half a sector.
QUADRATURE_RINGS = 3
QUADRATURE_SECTORS = 4
#: Below this ω·z the light rule's density is 0 (its 1/(ω·z)³ would overflow; the ASG is nil there).
QUADRATURE_MIN_COSINE = 1e-6
AREA_NORMALIZATIONS = ("square", "paper")
K_FITS = ("energy", "paper")


def mrp_peak_distant(position, center, normal, incoming):
    """Eq. 12 for a distant light towards ``incoming`` (unit, from the surface to the light).

    r = 2 (i·n_r) n_r − i, p_y = p_x − r ((p_x − c_r)·n_r)/(i·n_r). Returns ``(p_y, valid)``;
    valid when i·n_r > 0 and (p_x − c_r)·n_r > 0 (else p_y = p_x)."""
    position, center, normal, incoming = map(f64, (position, center, normal, incoming))
    cos_i = dot(incoming, normal)
    height = dot(position - center, normal)
    valid = (cos_i > 0.0) & (height > 0.0)
    r = 2.0 * cos_i[..., None] * normal - incoming
    step = safe_ratio(np.where(valid, height, 0.0), np.where(valid, cos_i, 0.0))
    return position - r * step[..., None], valid


def mrp_peak_local(position, center, normal, light_position):
    """Exact specular peak of a point-like light at ``light_position``: the segment from p_x to
    the light's mirror image p_l' = p_l − 2 h_l n_r crosses the plane at
    p_y = p_x + (p_l' − p_x) h_x / (h_x + h_l), h = heights above the plane (Eq. 12's condition
    h = n_r holds there exactly). Returns ``(p_y, valid)``; valid when h_x > 0 and h_l > 0."""
    position, center, normal, light_position = map(f64, (position, center, normal, light_position))
    h_x = dot(position - center, normal)
    h_l = dot(light_position - center, normal)
    valid = (h_x > 0.0) & (h_l > 0.0)
    mirror = light_position - 2.0 * h_l[..., None] * normal
    fraction = safe_ratio(np.where(valid, h_x, 0.0), np.where(valid, h_x + h_l, 0.0))
    return position + (mirror - position) * fraction[..., None], valid


def mrp_peak_brdf(cos_sigma, roughness, f0):
    """R's GGX BRDF at its own specular peak (h = n_r, c_i = c_o = cos σ):
    f_r = F(cos σ) D(1) / (c + s)², D(1) = 1/(π α²), s = sqrt((1 − α²)c² + α²)."""
    c = np.maximum(f64(cos_sigma), 0.0)
    alpha = np.maximum(f64(roughness), ALPHA_MIN)
    a2 = alpha * alpha
    g = ggx_g1_denominator(c, a2)
    return fresnel_schlick(c, f0) / (np.pi * a2 * g * g)


def mrp_peak_radiance(cos_sigma, roughness, f0, irradiance_normal):
    """L_y = f_r(i, r) (i·n_r) E⊥ in Blender's units (module documentation, step 2):
    E⊥ = I/d_l² (point, spot, area; I in W/sr towards p_y) or S (sun)."""
    c = np.maximum(f64(cos_sigma), 0.0)
    return mrp_peak_brdf(c, roughness, f0) * c * f64(irradiance_normal)


def mrp_peak_radiance_paper(cos_sigma, roughness, f0):
    """001 Eq. 17 as printed, L_y ≈ π m_r² f_r(i, r)(i·n_y) (distant light of unit radiance):
    kept only to show by quadrature that it does not match Blender's lights."""
    c = np.maximum(f64(cos_sigma), 0.0)
    alpha = np.maximum(f64(roughness), ALPHA_MIN)
    return np.pi * alpha * alpha * mrp_peak_brdf(c, alpha, f0) * c


def mrp_exp_ratio(x):
    """(1 − e^(−x))/x for any real x, = 1 at x = 0 (expm1 keeps it exact for tiny |x|)."""
    x = f64(x)
    tiny = np.abs(x) < 1e-300
    safe = np.where(tiny, 1.0, x)
    return np.where(tiny, 1.0, -np.expm1(-safe) / safe)


def mrp_disk_integral(cos_sigma, roughness, extent, spread=1.0, fit="energy"):
    """E / L_y = (π/k)(1 − e^(−k t)) = π t (1 − e^(−kt))/(kt) (001 Eqs. 25–27).

    ``extent`` = ρ = r_d / |p_y − p_x| (unit-distance radius), ``spread`` = 1 + d_x/d_l (1 for a
    sun; module documentation, step 3). t = ρ² cos²σ / (1 + ρ² cos²σ) (Eq. 27's
    1 − 1/(1 + ρ² cos² σ) without the cancellation).

    ``fit="paper"``: k = 0.288 cos σ / m_r² − 0.673 (Eq. 25). Its large-disk limit π L_y / k is
    1/(1.152 cos² σ) times the true total for a sharp reflector (≈ 1.15 at normal incidence, 4.6 at
    60°): Eq. 24 takes the attenuation along the plane of incidence, where the reflected direction
    turns twice as fast as the half vector, for every azimuth, but across that plane it turns only
    2 cos σ times as fast (dω_o = 4 (h·o) dω_h). ``fit="energy"`` (default): k = 1/(4 m_r² cos σ)
    − 0.673, the k whose π L_y / k equals ∫ L dω = F E⊥ of a sharp GGX reflector (geometric mean of
    the two directions' rates); the offset is the paper's. Evidence: docs/accuracy.md."""
    c = np.clip(f64(cos_sigma), 0.0, 1.0)
    alpha = np.maximum(f64(roughness), ALPHA_MIN)
    a2 = alpha * alpha
    if fit == "paper":
        k = K_SLOPE * c / a2 - K_OFFSET
    elif fit == "energy":
        k = 1.0 / (4.0 * a2 * np.maximum(c, COSINE_FLOOR)) - K_OFFSET
    else:
        raise ValueError(f"fit must be one of {K_FITS}, got {fit!r}")
    s = f64(spread)
    k = np.where(k > 0.0, k * s * s, k)
    q = np.minimum(f64(extent), EXTENT_MAX) ** 2 * c * c
    t = q / (1.0 + q)
    return np.pi * t * mrp_exp_ratio(k * t)


def mrp_lobe_extent(cos_sigma, roughness, spread=1.0):
    """ρ_lobe, the unit-distance radius of the reflector lobe's footprint around the peak: where the
    disk integral's integrand e^(−k t) (``mrp_disk_integral``'s energy-matched k, times spread²) has
    fallen to 1/e, k t = 1 with t = q/(1 + q), q = ρ² cos² σ: ρ = 1/(cos σ √(k − 1)); EXTENT_MAX when
    k ≤ 1 (a reflector so rough its lobe has no footprint smaller than the hemisphere)."""
    c = np.clip(f64(cos_sigma), COSINE_FLOOR, 1.0)
    alpha = np.maximum(f64(roughness), ALPHA_MIN)
    k = 1.0 / (4.0 * alpha * alpha * c) - K_OFFSET
    s = f64(spread)
    k = np.where(k > 0.0, k * s * s, k)
    excess = k - 1.0
    extent = 1.0 / (c * np.sqrt(np.where(excess > 0.0, excess, 1.0)))
    return np.where(excess > 0.0, np.minimum(extent, EXTENT_MAX), EXTENT_MAX)


def mrp_area_ratio(peak, center, axis_u, axis_v, half_u, half_v, disk_radius,
                   normalization="square"):
    """A of Eq. 36 from J, the bounding rectangle (in R's frame) of disk ∩ R.

    With the disk centre (x0, y0) in R's frame, the disk's half width at the row of R nearest its
    centre, w = sqrt(r² − (clamp(y0, ±a_v) − y0)²), bounds its x extent inside R:
    J_x = [max(x0 − w, −a_u), min(x0 + w, a_u)] (exact); J_y likewise. A = S_J / (4 r²)
    ("square") or S_J / (π r²) ("paper", Eq. 36 as printed); 0 when disk and R do not meet."""
    d = f64(peak) - f64(center)
    x0 = dot(d, f64(axis_u))
    y0 = dot(d, f64(axis_v))
    a = f64(half_u)
    b = f64(half_v)
    r = f64(disk_radius)
    wx = np.sqrt(np.maximum(r * r - (np.clip(y0, -b, b) - y0) ** 2, 0.0))
    wy = np.sqrt(np.maximum(r * r - (np.clip(x0, -a, a) - x0) ** 2, 0.0))
    # min(x0 + w, a) − max(x0 − w, −a) without subtracting the two ends (the GLSL twin's float32).
    lx = np.maximum(np.minimum(wx, a - x0) + np.minimum(wx, a + x0), 0.0)
    ly = np.maximum(np.minimum(wy, b - y0) + np.minimum(wy, b + y0), 0.0)
    if normalization == "square":
        denominator = 4.0 * r * r
    elif normalization == "paper":
        denominator = np.pi * r * r
    else:
        raise ValueError(f"normalization must be one of {AREA_NORMALIZATIONS}")
    return safe_ratio(lx * ly, denominator)


def mrp_bandwidth(extent):
    """ASG bandwidth for a unit-distance extent l (001 Eq. 32, ε = 0.05):
    (1 + 1/l²)(2.996 − ½ ln(1 + l²)), l ≥ EXTENT_FLOOR, result ≥ BANDWIDTH_FLOOR."""
    l = np.clip(f64(extent), EXTENT_FLOOR, EXTENT_MAX)
    l2 = l * l
    value = (1.0 + 1.0 / l2) * (LOG_INV_EPSILON - 0.5 * np.log1p(l2))
    return np.maximum(value, BANDWIDTH_FLOOR)


def mrp_asg_frame(position, peak, normal):
    """ASG frame of 001 Eqs. 18, 28: ``(m, n, z, distance, cos_n)`` with ŷx = (p_x − p_y)/d,
    m = v = normalize(ŷx × n_r), n = ŷx × m, z = −ŷx, cos_n = n_r·ŷx. At d = 0 (receiver at the
    peak) z = −n_r; at normal incidence (ŷx ∥ n_r) any tangent."""
    position, peak, normal = np.broadcast_arrays(f64(position), f64(peak), f64(normal))
    d_vec = position - peak
    distance = norm(d_vec)
    yx = safe_normalize(d_vec, normal, distance)
    v = np.cross(yx, normal)
    v_length = norm(v)
    m = np.where((v_length > 1e-12)[..., None], v / np.maximum(v_length, 1e-300)[..., None],
                 asg_any_tangent(yx))
    m = m - dot(m, yx)[..., None] * yx
    m = m / norm(m)[..., None]
    n = np.cross(yx, m)
    return m, n, -yx, distance, dot(normal, yx)


def mrp_receiver_sg(view, normal, roughness):
    """The receiver's NDF as an SG in the light domain (001 Eqs. 6, 8):
    ``(axis r_x, sharpness λ_h / (4 max(|o·n|, COSINE_FLOOR)), amplitude 1/(π α²))``."""
    view = f64(view)
    normal = f64(normal)
    alpha = np.maximum(f64(roughness), ALPHA_MIN)
    cos_o = dot(view, normal)
    axis = 2.0 * cos_o[..., None] * normal - view
    sharpness = ndf_sharpness(alpha) / (4.0 * np.maximum(np.abs(cos_o), COSINE_FLOOR))
    return axis, sharpness, 1.0 / (np.pi * alpha * alpha)


def mrp_receiver_factor(incoming, view, normal, roughness, f0):
    """M(−r_y, o)(−r_y·n_x) of Eq. 10: F(ω_i·h) c_i / ((c_i + s_i)(c_o + s_o)) (GGX's
    F G2/(4 c_i c_o) times c_i, Smith separable as ``ggx.microfacet_brdf``); 0 below either
    horizon."""
    incoming = f64(incoming)
    view = f64(view)
    normal = f64(normal)
    alpha = np.maximum(f64(roughness), ALPHA_MIN)
    a2 = alpha * alpha
    ci_raw = dot(incoming, normal)
    co_raw = dot(view, normal)
    ci = np.maximum(ci_raw, 0.0)
    co = np.maximum(co_raw, 0.0)
    half = incoming + view
    half = safe_normalize(half, normal, norm(half))
    value = (fresnel_schlick(dot(incoming, half), f0) * ci
             / (ggx_g1_denominator(ci, a2) * ggx_g1_denominator(co, a2)))
    return np.where((ci_raw > 0.0) & (co_raw > 0.0), value, 0.0)


def mrp_convolve(view, normal, roughness, m, n, z, bandwidth_m, bandwidth_n, amplitude, mode="asg"):
    """∫ Ga(ω) Gi(ω) dω of Eq. 10 with the ASG light (m, n, z; λ along m, µ along n; amplitude t)
    and the receiver SG (``mrp_receiver_sg``): Eq. 11 (``"asg"``) or Eq. 37 + SG product
    integral (``"sg"``)."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    axis, sharpness, sg_amplitude = mrp_receiver_sg(view, normal, roughness)
    value = 0.0
    for weight, scale in RECEIVER_NDF_LOBES:  # the NDF's two SGs (RECEIVER_NDF_LOBES)
        if mode == "asg":
            value = value + weight * sg_asg_convolution(axis, scale * sharpness, m, n, z, bandwidth_m, bandwidth_n)
        else:
            value = value + weight * sg_product_integral(z, 2.0 * np.maximum(bandwidth_m, bandwidth_n), axis,
                                                         scale * sharpness)
    return f64(amplitude) * sg_amplitude * value


#: Largest tangent-plane offset of gaussian_lobes_integral's peak (a nearly singular P).
TANGENT_MAX = 1e4


def gaussian_lobes_integral(axis, lobes):
    """∫ Π_j exp(−η_j1 (ω·e_j1)² − η_j2 (ω·e_j2)²) dω in the tangent plane at the unit ``axis``,
    ``lobes`` a list of (e1, e2, η1, η2) (arrays broadcasting together): with ω ≈ axis + u, u in the
    plane, the exponent is −uᵀPu + 2bᵀu − c, so the integral is π/√det P · exp(bᵀP⁻¹b − c).
    Returns ``(value, peak)``, peak the unit direction of the product's maximum. For an SG and an
    ASG this is Eq. 11's small-angle form (000 app. C, after Xu et al. 2013)."""
    axis = f64(axis)
    t1 = asg_any_tangent(axis)
    t2 = np.cross(axis, t1)
    terms = [(f64(e), f64(h)) for e1, e2, h1, h2 in lobes for e, h in ((e1, h1), (e2, h2))]
    g = [(dot(e, t1), dot(e, t2), dot(e, axis), h) for e, h in terms]
    # P = Σ h g gᵀ, b = −Σ h c g (c = e·axis). Cauchy–Binet: det P = Σ_{k<l} h_k h_l (g_k × g_l)², and
    # adj(P) b = −Σ_{k≠l} h_k h_l c_l (g_k⊥·g_l) g_k⊥ (the k = l terms vanish): sums without the
    # cancellation of p11 p22 − p12² when one bandwidth is ~1e8 times another (float32 twin).
    det = 0.0
    a1 = a2 = 0.0
    for k, (gk1, gk2, ck, hk) in enumerate(g):
        for l, (gl1, gl2, cl, hl) in enumerate(g):
            if l == k:
                continue
            cross = gk1 * gl2 - gk2 * gl1  # g_k⊥·g_l with g⊥ = (−g2, g1)
            if l > k:
                det = det + hk * hl * cross * cross
            a1 = a1 + hk * hl * cl * cross * gk2
            a2 = a2 - hk * hl * cl * cross * gk1
    det = np.maximum(det, 1e-300)
    # Tangent offsets beyond TANGENT_MAX are far outside either lobe: clamped to stay finite.
    u1 = np.clip(a1 / det, -TANGENT_MAX, TANGENT_MAX)
    u2 = np.clip(a2 / det, -TANGENT_MAX, TANGENT_MAX)
    # c − bᵀP⁻¹b is the quadratic's minimum: summed as the lobes' own squares at it.
    exponent = 0.0
    for gk1, gk2, ck, hk in g:
        residual = ck + gk1 * u1 + gk2 * u2
        exponent = exponent + hk * residual * residual
    value = np.pi / np.sqrt(det) * np.exp(-exponent)
    peak = axis + u1[..., None] * t1 + u2[..., None] * t2
    return value, peak / norm(peak)[..., None]


def mrp_convolve_asg_receiver(view, normal, roughness, m, n, z, bandwidth_m, bandwidth_n, amplitude):
    """``mrp_convolve`` with the receiver's NDF warped anisotropically, as 003's ASG lobe
    (``asg.asg_specular_lobe``: η = λ_h/(8 cos²θ_o) across the plane of incidence, λ_h/8 in it)
    per SG of RECEIVER_NDF_LOBES, instead of Eq. 8's isotropic λ_h/(4 cos θ_o) (their geometric
    mean): ASG light × ASG receiver in the tangent plane of the narrower lobe
    (``gaussian_lobes_integral``), the light's cosine max(ω·z, 0) at the product's peak.
    The tangent-plane product is accurate for two narrow lobes (sharp receivers); for a wide light
    (grazing σ, a rough receiver's tangent plane) it is not: benchmarks/results/mrp_asg_stages.md
    (path_partition --stages) and tests/test_reference_mrp_asg.py measure it against quadrature."""
    x, y, z_r, eta_x, eta_y = asg_specular_lobe(view, normal, roughness)
    alpha = np.maximum(f64(roughness), ALPHA_MIN)
    bandwidth_m, bandwidth_n = f64(bandwidth_m), f64(bandwidth_n)
    light_narrower = np.minimum(bandwidth_m, bandwidth_n) > np.minimum(eta_x, eta_y)
    axis = np.where(light_narrower[..., None], f64(z), z_r)
    value = 0.0
    for weight, scale in RECEIVER_NDF_LOBES:
        integral, peak = gaussian_lobes_integral(axis, [(x, y, scale * eta_x, scale * eta_y),
                                                        (m, n, bandwidth_m, bandwidth_n)])
        value = value + weight * integral * np.maximum(dot(peak, f64(z)), 0.0)
    return f64(amplitude) * value / (np.pi * alpha * alpha)


def mrp_quadrature_rules(light_nodes=QUADRATURE_LIGHT_NODES, rings=QUADRATURE_RINGS):
    """(Gauss–Hermite nodes, weights / √π) for e^(−x²) and (Gauss–Legendre nodes, weights) on [0, 1]:
    the two rules of ``mrp_receiver_quadrature`` (the GLSL twin of commit db4140c held them as
    constants; the pass does not use it, docs/accuracy.md)."""
    x, w = np.polynomial.hermite.hermgauss(light_nodes)
    u, uw = np.polynomial.legendre.leggauss(rings)
    return x, w / np.sqrt(np.pi), 0.5 * (u + 1.0), 0.5 * uw


def mrp_receiver_quadrature(view, normal, roughness, f0, m, n, z, bandwidth_m, bandwidth_n, amplitude,
                            light_nodes=QUADRATURE_LIGHT_NODES, rings=QUADRATURE_RINGS,
                            sectors=QUADRATURE_SECTORS):
    """∫ Ga(ω) f_x(ω, o) ⟨ω, n_x⟩ dω: 001 Eq. 10's integral of the ASG light (m, n, z; λ along m,
    µ along n; amplitude t) against the receiver's exact GGX BRDF (``ggx.microfacet_brdf``, Fresnel
    and masking inside), in place of Eq. 8's NDF as SGs, Eq. 11 and M pulled out.

    Those three are exact only where the receiver's lobe is isotropic and smooth across the light.
    On a sphere's flank (the demo's gold sphere: grazing views, α 0.09) the warped GGX lobe is
    stretched and about as wide as the ASG, and Eq. 11 with Eq. 8's isotropic warp is 0.40 relative
    RMSE off this integral (benchmarks/results/mrp_asg_receiver_quadrature.md). The integral is
    taken by two deterministic rules, one per lobe, combined by the balance heuristic (Veach's
    multiple importance sampling with quadrature rules in place of random samples):

    - the light's: ω = normalize(z + a m + b n) with (a, b) = (x_i/√λ, x_j/√µ), Gauss–Hermite nodes;
      its density p_L(ω) = √(λµ)/π e^(−λa² − µb²) / (ω·z)³ (the ASG's tangent-plane Gaussian
      carried to the sphere, dω = (ω·z)³ da db);
    - the receiver's: ω = 2(o·h)h − o with h at tan²θ_h = α² u_k/(1 − u_k), Gauss–Legendre u_k in
      GGX's D(h)(h·n) CDF, and ``sectors`` azimuths; its density p_R(ω) = D(h)(h·n)/(4|o·h|).

    Each rule integrates f / (p_L + p_R) against its own density, so the sum is the integral exactly
    where that ratio is as smooth as each rule assumes: a sharp light (the ratio is the receiver's
    BRDF across it), a sharp receiver (the light across its lobe), and both between.
    Returns the integral per unit amplitude times ``amplitude``; 0 where no node carries light."""
    view, normal, m, n, z = (f64(v) for v in (view, normal, m, n, z))
    alpha = np.maximum(f64(roughness), ALPHA_MIN)
    lam = np.maximum(f64(bandwidth_m), BANDWIDTH_FLOOR)
    mu = np.maximum(f64(bandwidth_n), BANDWIDTH_FLOOR)
    x, wx, u, uw = mrp_quadrature_rules(light_nodes, rings)
    directions, weights = [], []
    for i, j in itertools.product(range(len(x)), repeat=2):
        w = z + (x[i] / np.sqrt(lam))[..., None] * m + (x[j] / np.sqrt(mu))[..., None] * n
        directions.append(w / norm(w)[..., None])
        weights.append(wx[i] * wx[j])
    t1 = asg_any_tangent(normal)
    t2 = np.cross(normal, t1)
    for k in range(len(u)):
        tan2 = alpha * alpha * (u[k] / (1.0 - u[k]))
        cos_h = 1.0 / np.sqrt(1.0 + tan2)
        sin_h = np.sqrt(tan2) * cos_h
        for s in range(sectors):
            phi = 2.0 * np.pi * (s + 0.5 * (k % 2)) / sectors
            h = (cos_h[..., None] * normal
                 + sin_h[..., None] * (np.cos(phi) * t1 + np.sin(phi) * t2))
            directions.append(2.0 * dot(view, h)[..., None] * h - view)
            weights.append(uw[k] / sectors)
    total = 0.0
    for w, weight in zip(directions, weights):
        value = (asg_evaluate(w, m, n, z, lam, mu) * microfacet_brdf(w, view, normal, alpha, f0)
                 * np.maximum(dot(w, normal), 0.0))
        c = dot(w, z)
        c_safe = np.maximum(c, QUADRATURE_MIN_COSINE)
        a, b = dot(w, m) / c_safe, dot(w, n) / c_safe
        p_light = np.where(c > QUADRATURE_MIN_COSINE, np.sqrt(lam * mu) / np.pi * np.exp(-lam * a * a - mu * b * b)
                           / (c_safe * c_safe * c_safe), 0.0)
        half = w + view
        half = safe_normalize(half, normal, norm(half))
        cos_h = dot(half, normal)
        p_receiver = ggx_ndf(cos_h, alpha) * np.maximum(cos_h, 0.0) / (4.0 * np.maximum(np.abs(dot(view, half)), 1e-30))
        density = p_light + p_receiver
        ratio = np.divide(value, density, out=np.zeros_like(density * value), where=density > 0.0)
        total = total + weight * np.where(np.isfinite(ratio), ratio, 0.0)
    return f64(amplitude) * total


def light_irradiance_at(light, point):
    """(E⊥ at ``point`` for a surface facing the light, unit direction from ``point`` to the
    light, distance d_l or inf): I/d² for point/spot/area (``lights.light_intensity``), S for a
    sun; per unit light colour."""
    point = f64(point)
    if light.type == "SUN":
        direction = -f64(light.direction) / np.linalg.norm(light.direction)
        direction = np.broadcast_to(direction, point.shape)
        return (np.full(point.shape[:-1], float(light.power)), direction,
                np.full(point.shape[:-1], np.inf))
    to_light = f64(light.position) - point
    d = norm(to_light)
    direction = safe_normalize(to_light, f64(light.direction), d)
    intensity = light_intensity(light, -direction)
    return safe_ratio(intensity, d * d), direction, d


def mrp_asg_light(position, rect, light, disk_radius, spread_correction=True, peak_form="blender",
                  area_normalization="square", fit="energy", disk="lobe"):
    """001's ASG light at receivers (steps 1-5 of the module documentation), as a dict: ``valid``,
    ``peak``, ``cos_sigma``, ``radiance`` L_y, ``extent`` ρ, ``disk_integral`` E / L_y, ``area`` A,
    ``total`` C = A E (Eq. 35), the frame ``m``, ``n``, ``z``, ``bandwidth_m``, ``bandwidth_n`` and
    ``amplitude``; ``mrp_shade``'s arguments."""
    position = f64(position)
    n_r = f64(rect["normal"])
    if light.type == "SUN":
        incoming = -f64(light.direction) / np.linalg.norm(light.direction)
        peak, valid = mrp_peak_distant(position, rect["center"], n_r, incoming)
    else:
        peak, valid = mrp_peak_local(position, rect["center"], n_r, light.position)
    irradiance, incoming, light_distance = light_irradiance_at(light, peak)
    cos_sigma = np.clip(dot(incoming, n_r), 0.0, 1.0)
    if peak_form == "blender":
        radiance = mrp_peak_radiance(cos_sigma, rect["roughness"], rect["f0"], irradiance)
    else:
        radiance = mrp_peak_radiance_paper(cos_sigma, rect["roughness"], rect["f0"])
    m, n, z, distance, cos_n = mrp_asg_frame(position, peak, n_r)
    valid = valid & (distance > 0.0)
    d_safe = np.where(valid, distance, 1.0)
    extent = np.where(valid, f64(disk_radius) / d_safe, 1.0)
    spread = 1.0 + safe_ratio(d_safe, light_distance) if spread_correction else 1.0
    if disk == "lobe":
        extent = np.maximum(extent, DISK_LOBE_SCALE * mrp_lobe_extent(cos_sigma, rect["roughness"], spread))
    elif disk != "fixed":
        raise ValueError(f"disk must be one of {DISK_RULES}, got {disk!r}")
    disk_integral = mrp_disk_integral(cos_sigma, rect["roughness"], extent, spread, fit)
    area = mrp_area_ratio(peak, rect["center"], rect["axis_u"], rect["axis_v"], rect["half_u"],
                          rect["half_v"], np.minimum(extent, EXTENT_MAX) * d_safe, area_normalization)
    total = area * disk_integral * radiance
    bandwidth_m = mrp_bandwidth(extent)
    bandwidth_n = mrp_bandwidth(extent * np.abs(cos_n))
    amplitude = np.sqrt(bandwidth_m) * np.sqrt(bandwidth_n) / np.pi * total
    return dict(valid=valid, peak=peak, cos_sigma=cos_sigma, radiance=radiance, extent=extent,
                disk_integral=disk_integral, area=area, total=total, m=m, n=n, z=z,
                bandwidth_m=bandwidth_m, bandwidth_n=bandwidth_n, amplitude=amplitude)


def mrp_shade(position, normal, view, roughness, f0, rect, light, disk_radius, mode="asg",
              visibility=1.0, spread_correction=True, peak_form="blender",
              area_normalization="square", fit="energy", disk="lobe", receiver="sg"):
    """L_x(o) of one rectangle and one light at receivers (001 Eqs. 3–37; module documentation).

    ``rect``: mapping with ``center``, ``normal``, ``axis_u``, ``axis_v``, ``half_u``, ``half_v``,
    ``roughness``, ``f0``. ``light``: a ``scene_description.Light``-like object. ``visibility``:
    the light's shadow at p_y (1 = lit). Per unit light colour and per colour channel of the F0s.
    ``peak_form="paper"`` uses 001 Eq. 17 for L_y (for the comparison only). ``disk``: "lobe" (the
    default) samples a disk of radius max(r_d, DISK_LOBE_SCALE ρ_lobe |p_y − p_x|), "fixed" 001's
    r_d alone (``DISK_RULES``). ``receiver`` (``RECEIVERS``): ``"sg"`` (the default, the GPU pass's)
    001's Eq. 8 NDF as two SGs with Eq. 11 (or Eq. 37's SG product) and M pulled out;
    ``"quadrature"`` the ASG light against the exact GGX receiver (``mrp_receiver_quadrature``, ASG
    mode only; measured in benchmarks/results/mrp_asg_receiver_quadrature.md: the exact receiver
    does not bring the frames closer to Cycles); ``"asg"`` the receiver lobe of
    ``mrp_convolve_asg_receiver`` (ASG mode only, measured in benchmarks/results/mrp_asg_stages.md:
    closer than "sg" on the demo's sharp gold sphere, further on the occluded reflector's α 0.2 wall
    and at grazing light)."""
    a = mrp_asg_light(position, rect, light, disk_radius, spread_correction, peak_form, area_normalization,
                      fit, disk)
    if receiver not in RECEIVERS or (mode == "sg" and receiver != "sg"):
        raise ValueError(f"receiver must be one of {RECEIVERS} ('sg' in SG mode), got {receiver!r}")
    if receiver == "quadrature":
        value = mrp_receiver_quadrature(view, normal, roughness, f0, a["m"], a["n"], a["z"], a["bandwidth_m"],
                                        a["bandwidth_n"], a["amplitude"])
        return np.where(a["valid"], f64(visibility) * value, 0.0)
    if receiver == "asg":
        conv = mrp_convolve_asg_receiver(view, normal, roughness, a["m"], a["n"], a["z"], a["bandwidth_m"],
                                         a["bandwidth_n"], a["amplitude"])
    else:
        conv = mrp_convolve(view, normal, roughness, a["m"], a["n"], a["z"], a["bandwidth_m"], a["bandwidth_n"],
                            a["amplitude"], mode)
    factor = mrp_receiver_factor(a["z"], view, normal, roughness, f0)
    return np.where(a["valid"], f64(visibility) * factor * conv, 0.0)


def _refined_rule(half, points, order=12, smallest=1e-5, ratio=2.0):
    """Gauss–Legendre nodes/weights on [−half, half], panels shrinking geometrically towards each
    of ``points`` (clamped into the interval)."""
    edges = {-half, half}
    for p in points:
        p = float(np.clip(p, -half, half))
        edges.add(p)
        step = smallest * 2.0 * half
        while step < 2.0 * half:
            for e in (p - step, p + step):
                if -half < e < half:
                    edges.add(e)
            step *= ratio
    return composite_gauss_legendre(np.array(sorted(edges)), order)


def brute_force_rectangle(position, normal, view, roughness, f0, rect, light, order=12,
                          smallest=1e-5, receiver_brdf=True):
    """Eq. 3 over R by quadrature (one receiver): Σ f_x(−r, o) c_x · f_r(i, r) (i·n_r) E⊥(y) ·
    (r·n_r)/|y − x|² dA, exact GGX at both ends; the light unshadowed. ``receiver_brdf=False``:
    C of Eq. 13 instead, the solid-angle integral at x of R's reflected radiance."""
    position = f64(position)
    n_r = f64(rect["normal"])
    u = f64(rect["axis_u"])
    v = f64(rect["axis_v"])
    c = f64(rect["center"])
    a = float(rect["half_u"])
    b = float(rect["half_v"])
    # Refine towards the reflector's peak and towards where the receiver's mirror ray meets R.
    points = []
    if light.type == "SUN":
        incoming = -f64(light.direction) / np.linalg.norm(light.direction)
        peak, ok = mrp_peak_distant(position, c, n_r, incoming)
    else:
        peak, ok = mrp_peak_local(position, c, n_r, light.position)
    if ok:
        points.append(peak)
    mirror = 2.0 * dot(view, normal) * f64(normal) - f64(view)
    denominator = -dot(mirror, n_r)
    if denominator > 1e-9:
        points.append(position + mirror * dot(position - c, n_r) / denominator)
    xu, wu = _refined_rule(a, [dot(p - c, u) for p in points] or [0.0], order, smallest)
    xv, wv = _refined_rule(b, [dot(p - c, v) for p in points] or [0.0], order, smallest)
    y = c + xu[:, None, None] * u + xv[None, :, None] * v
    weight = wu[:, None] * wv[None, :]
    to_x = position - y
    dist = norm(to_x)
    r = to_x / dist[..., None]
    irradiance, incoming, _ = light_irradiance_at(light, y)
    cos_i = dot(incoming, n_r)
    cos_r = dot(r, n_r)
    f_reflector = microfacet_brdf(incoming, r, n_r, rect["roughness"], rect["f0"])
    radiance = f_reflector * np.maximum(cos_i, 0.0) * irradiance
    f_receiver = microfacet_brdf(-r, f64(view), f64(normal), roughness, f0)
    cos_x = np.maximum(dot(-r, f64(normal)), 0.0)
    if not receiver_brdf:
        f_receiver, cos_x = 1.0, 1.0
    integrand = radiance * f_receiver * cos_x * np.maximum(cos_r, 0.0) / (dist * dist)
    return float(np.sum(integrand * weight))
