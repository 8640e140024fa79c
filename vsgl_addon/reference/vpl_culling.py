# SPDX-License-Identifier: GPL-3.0-or-later
"""Stochastic light culling of VPLs on GGX microsurfaces, float64 (formulas.md section 7).

Paper 004 = Tokuyoshi and Harada, "Stochastic light culling for VPLs on GGX microsurfaces"
(EGSR 2017). Conventions of :mod:`.ggx`: numpy broadcasting over leading axes, vectors in a
trailing axis of length 3, directions pointing away from the surface.

A glossy VPL is an RSM texel of a sharp specular reflector (alpha < alpha_c, light-paths.md): its
position q, normal n, direction towards the light w_i, flux Phi (RGB), specular albedo Rs (RGB) and
GGX roughness alpha. It emits the intensity I(w_o) = Phi Rs f1(w_i, w_o) <w_o, n>, f1 the GGX BRDF
with F = 1: Rs is the texel's directional albedo with Fresnel already in it (``reference.rsm``), and
Rs <= 1 is what makes Fmax = 1 a safe bound of Eq. 9. The acceptance test uses the scalar
intensity of the brightest channel, so one xi and one range serve the three channels.

Every quantity a GPU twin needs (hash, xi, ranges, spheroid, plane test) is a function here with the
GLSL name of ``glsl/lib/vpl_culling.glsl``.
"""

from __future__ import annotations

import numpy as np

from .ggx import ggx_g1_denominator, ggx_ndf, microfacet_brdf
from .numerics import dot, f64, norm, safe_normalize

# delta xi is clamped here: xi = 0 (accept at every distance) would give an infinite range; with
# this floor the radius of a unit-flux VPL stays below 1e15, whose square is finite in float32.
DELTA_XI_MIN = 1e-30
# (1/3)^(3/4) and (4/27)^(1/4): centre offset and radius of the sphere that bounds the diffuse
# VPL's range surface rho(theta) = R0 sqrt(cos theta) (formulas.md section 7).
DIFFUSE_CENTRE = (1.0 / 3.0) ** 0.75
DIFFUSE_RADIUS = (4.0 / 27.0) ** 0.25


def pcg_hash(value):
    """PCG-RXS-M-XS 32-bit hash (Jarzynski and Olano 2020) on uint32, wrapping like GLSL uint."""
    v = np.asarray(value, dtype=np.uint64) & np.uint64(0xFFFFFFFF)
    mask = np.uint64(0xFFFFFFFF)
    state = (v * np.uint64(747796405) + np.uint64(2891336453)) & mask
    shift = (state >> np.uint64(28)) + np.uint64(4)
    word = (((state >> shift) ^ state) * np.uint64(277803737)) & mask
    return ((word >> np.uint64(22)) ^ word).astype(np.uint32)


def vpl_xi(index, seed, frame):
    """The one uniform xi in (0, 1) of VPL ``index`` for a seed and a frame (004 Eqs. 2-3: one
    random number per light, not per pixel, so a light is either in or out for the whole image).

    23 bits, (h + 1/2) / 2^23: h + 1/2 < 2^23 is exact in float32, never 0 or 1.
    """
    frame_hash = pcg_hash(np.asarray(frame, dtype=np.uint64))
    seed_hash = pcg_hash((np.asarray(seed, dtype=np.uint64) ^ frame_hash.astype(np.uint64)))
    h = pcg_hash((np.asarray(index, dtype=np.uint64) + seed_hash.astype(np.uint64)) & np.uint64(0xFFFFFFFF))
    return ((h >> np.uint32(9)).astype(np.float64) + 0.5) / 8388608.0


def acceptance_probability(intensity, distance_squared, delta):
    """p = min(I(w_o) / (delta l^2), 1) (004 Eq. 2); 1 at l = 0 with I > 0, 0 where I = 0."""
    intensity = f64(intensity)
    den = f64(delta) * f64(distance_squared)
    p = np.where(den > 0.0, intensity / np.where(den > 0.0, den, 1.0), np.where(intensity > 0.0, 1.0, 0.0))
    return np.clip(p, 0.0, 1.0)


def light_range(intensity, delta, xi):
    """l_max(w_o) = sqrt(I(w_o) / (delta xi)) (004 Eq. 5): the VPL is accepted at x iff
    |x - q| < l_max, i.e. p > xi."""
    return np.sqrt(np.maximum(f64(intensity), 0.0) / np.maximum(f64(delta) * f64(xi), DELTA_XI_MIN))


def glossy_intensity(incoming, outgoing, normal, roughness, flux):
    """Scalar I(w_o) = Phi f1(w_i, w_o) <w_o, n> of a glossy VPL (F = 1), ``flux`` the scalar flux
    (the brightest channel of Phi Rs)."""
    cos_o = np.maximum(dot(f64(outgoing), f64(normal)), 0.0)
    return f64(flux) * microfacet_brdf(incoming, outgoing, normal, roughness, 1.0) * cos_o


def mirror_direction(incoming, normal):
    """w_u = 2 (w_i . n) n - w_i, the axis of the GGX range surface (004 Eq. 10)."""
    incoming = f64(incoming)
    normal = f64(normal)
    return 2.0 * dot(incoming, normal)[..., None] * normal - incoming


def ggx_range_radius(cos_incidence, roughness, flux, delta, xi, fmax=1.0):
    """r = sqrt(Phi Fmax G1dist(w_i) / (4 pi delta xi |w_i . n|)) (004 Eq. 12).

    G1dist(c)/|c| = 2 / (|c| + sqrt((1 - alpha^2) c^2 + alpha^2)) -> 2/alpha at grazing incidence,
    so the ratio is formed without dividing by |c| (finite for c -> 0).
    """
    c = np.abs(f64(cos_incidence))
    a2 = f64(roughness) ** 2
    g1_over_cos = 2.0 / ggx_g1_denominator(c, a2)
    num = np.maximum(f64(flux), 0.0) * f64(fmax) * g1_over_cos
    return np.sqrt(num / (4.0 * np.pi * np.maximum(f64(delta) * f64(xi), DELTA_XI_MIN)))


def ggx_bounding_surface(theta, radius, roughness):
    """s(w_o) = r sqrt(pi D(cos(theta/2))) (004 Eq. 12), theta the angle from w_u."""
    return f64(radius) * np.sqrt(np.pi * ggx_ndf(np.cos(0.5 * f64(theta)), roughness))


def ggx_spheroid(position, normal, incoming, roughness, flux, delta, xi, fmax=1.0):
    """Bounding spheroid of a glossy VPL's range (004 Eqs. 13-15).

    Returns (centre, semi_axes, rotation): semi-axes (r_u, r_v, r_w) = ((1 + a^2)/(2a) r, r, r),
    rotation rows (w_u, w_w x w_u, w_w) with w_w = w_u x n / |w_u x n| (Eq. 14), centre
    q + (1 - a^2)/(2a) r w_u (Eq. 15). At normal incidence w_u = n and the cross product vanishes;
    the spheroid is symmetric about w_u, so any unit w_w perpendicular to it serves.
    """
    position = f64(position)
    normal = f64(normal)
    incoming = f64(incoming)
    alpha = f64(roughness)
    w_u = safe_normalize(mirror_direction(incoming, normal), normal)
    r = ggx_range_radius(dot(incoming, normal), alpha, flux, delta, xi, fmax)
    cross = np.cross(w_u, normal)
    # Fallback axis: w_u x (e_x or e_y, whichever is less parallel to w_u).
    helper = np.where((np.abs(w_u[..., 0]) < 0.9)[..., None], np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    fallback = np.cross(w_u, helper)
    fallback = fallback / norm(fallback)[..., None]
    length = norm(cross)
    w_w = np.where((length > 1e-9)[..., None], cross / np.maximum(length, 1e-300)[..., None], fallback)
    w_v = np.cross(w_w, w_u)
    rotation = np.stack([w_u, w_v, w_w], axis=-2)
    stretch = (1.0 + alpha * alpha) / (2.0 * alpha)
    offset = (1.0 - alpha * alpha) / (2.0 * alpha)
    semi_axes = np.stack([stretch * r, r, r], axis=-1)
    centre = position + (offset * r)[..., None] * w_u
    return centre, semi_axes, rotation


def diffuse_sphere(position, normal, flux_reflectance, delta, xi):
    """Bounding sphere of a diffuse VPL's range (formulas.md section 7): with
    R0 = sqrt(Phi k / (pi delta xi)), centre q + (1/3)^(3/4) R0 n and radius (4/27)^(1/4) R0."""
    r0 = np.sqrt(np.maximum(f64(flux_reflectance), 0.0) / (np.pi * np.maximum(f64(delta) * f64(xi), DELTA_XI_MIN)))
    centre = f64(position) + (DIFFUSE_CENTRE * r0)[..., None] * f64(normal)
    return centre, DIFFUSE_RADIUS * r0


def spheroid_contains(points, centre, semi_axes, rotation, slack=0.0):
    """|diag(1/axes) R (x - c)| <= 1 + slack: x inside the spheroid."""
    local = np.einsum("...ij,...j->...i", f64(rotation), f64(points) - f64(centre))
    return norm(local / f64(semi_axes)) <= 1.0 + slack


def ellipsoid_plane_distance(plane_normal, plane_offset, centre, semi_axes, rotation):
    """Signed distance of the ellipsoid's stretched centre from the stretched plane (004 Eq. 16).

    Stretching space by S = R^T diag(1/a) R makes the ellipsoid the unit sphere; the plane
    n.x + d = 0 becomes (S^-1 n).x' + n.c + d = 0, so the sphere test reads
    (n.c + d) / |diag(a) R n| >= -1 for the ellipsoid to reach the plane's positive side.
    """
    plane_normal = f64(plane_normal)
    rn = np.einsum("...ij,...j->...i", f64(rotation), plane_normal)
    support = norm(f64(semi_axes) * rn)
    return (dot(plane_normal, f64(centre)) + f64(plane_offset)) / np.maximum(support, 1e-300)


def ellipsoid_frustum_overlap(planes, centre, semi_axes, rotation):
    """Conservative ellipsoid-frustum test (004 Eqs. 16-17): False only when the ellipsoid lies
    wholly outside one of the frustum's planes. ``planes`` (..., P, 4) = (n, d), inside n.x + d >= 0.
    Plane by plane it never rejects an ellipsoid that meets the frustum (no false negatives)."""
    planes = f64(planes)
    distance = ellipsoid_plane_distance(planes[..., :3], planes[..., 3], centre[..., None, :],
                                        semi_axes[..., None, :], rotation[..., None, :, :])
    return np.all(distance >= -1.0, axis=-1)


#: Edges of the tile frustum as corner pairs (:func:`tile_frustum_corners`' order): the depth_min
#: ring, the depth_max ring, and the four corner rays.
FRUSTUM_EDGES = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4],
                          [0, 4], [1, 5], [2, 6], [3, 7]])


def ellipsoid_frustum_distance(planes, corners, centre, semi_axes, rotation):
    """Distance from the ellipsoid's centre to the frustum, measured where the ellipsoid is the unit
    sphere (x' = diag(1/a) R (x - c), the stretch of 004 Eq. 16); 0 when the centre is inside.

    The stretch is affine, so the frustum stays a convex polyhedron with the same faces, edges and
    corners. Outside it the closest point lies inside a face (the foot of that face's stretched
    plane, which then satisfies every other plane) or on an edge (corners included), so the
    distance is the smallest of those. ``planes`` (..., 6, 4) of :func:`tile_frustum_planes`,
    ``corners`` (..., 8, 3) of :func:`tile_frustum_corners`."""
    planes = f64(planes)
    corners = f64(corners)
    centre = f64(centre)
    semi_axes = f64(semi_axes)
    rotation = f64(rotation)
    h = ellipsoid_plane_distance(planes[..., :3], planes[..., 3], centre[..., None, :],
                                 semi_axes[..., None, :], rotation[..., None, :, :])
    stretched = semi_axes[..., None, :] * np.einsum("...ij,...kj->...ki", rotation, planes[..., :3])
    m = stretched / np.maximum(norm(stretched), 1e-300)[..., None]
    # Foot of face k, -h_k m_k, against plane j: h_j - h_k (m_j . m_k); the tolerance keeps the
    # interior of a flat face (depth_min = depth_max: planes 4 and 5 opposite) against rounding.
    foot = h[..., None, :] - h[..., :, None] * np.einsum("...ki,...ji->...kj", m, m)
    tolerance = 1e-9 * (1.0 + np.max(np.abs(h), axis=-1))[..., None, None]
    face = (h < 0.0) & np.all(foot >= -tolerance, axis=-1)
    face_distance = np.min(np.where(face, -h, np.inf), axis=-1)
    local = np.einsum("...ij,...kj->...ki", rotation, corners - centre[..., None, :]) / semi_axes[..., None, :]
    a = local[..., FRUSTUM_EDGES[:, 0], :]
    edge = local[..., FRUSTUM_EDGES[:, 1], :] - a
    length2 = dot(edge, edge)
    t = np.clip(-dot(a, edge) / np.where(length2 > 0.0, length2, 1.0), 0.0, 1.0)
    edge_distance = np.min(norm(a + t[..., None] * edge), axis=-1)
    return np.where(np.all(h >= 0.0, axis=-1), 0.0, np.minimum(face_distance, edge_distance))


#: Relative slack of the exact test in float64: rounding never drops an ellipsoid that touches.
EXACT_SLACK = 1e-9
#: Rounding of a position in units of its magnitude (a few float64 ulps), which the stretch divides
#: by the smallest semi-axis.
POSITION_ROUNDING = 16.0 * np.finfo(np.float64).eps


def ellipsoid_frustum_overlap_exact(planes, corners, centre, semi_axes, rotation):
    """Exact ellipsoid-frustum test: True iff the ellipsoid meets the frustum (stretched distance
    <= 1, :func:`ellipsoid_frustum_distance`). Unlike :func:`ellipsoid_frustum_overlap` it rejects
    ellipsoids beyond an edge or corner that no single plane separates.

    Besides EXACT_SLACK, the slack holds the rounding of the corners and the centre stretched by the
    smallest semi-axis: a spheroid of 1e-13 m radii a metre from the origin (delta xi -> 0 at
    004 Eq. 16) is off by ~1e-3 of its size, and which way depends on the CPU's summation order."""
    corners, centre, semi_axes = f64(corners), f64(centre), f64(semi_axes)
    distance = ellipsoid_frustum_distance(planes, corners, centre, semi_axes, rotation)
    magnitude = np.maximum(np.max(np.abs(corners), axis=(-2, -1)), np.max(np.abs(centre), axis=-1))
    rounding = POSITION_ROUNDING * magnitude / np.maximum(np.min(semi_axes, axis=-1), 1e-300)
    return distance <= 1.0 + EXACT_SLACK + rounding


def glossy_vpl_radiance(receiver, receiver_normal, receiver_albedo, position, normal, incoming,
                        roughness, flux_rgb, rs_rgb):
    """Unshadowed radiance a glossy VPL puts on a diffuse receiver at x:
    L = (albedo/pi) Phi Rs f1(w_i, w_o) <w_o, n_q> <-w_o, n_x> / l^2, w_o = (x - q)/l (RGB).

    Also returns the scalar acceptance intensity I(w_o) and l^2."""
    d = f64(receiver) - f64(position)
    l2 = dot(d, d)
    w_o = safe_normalize(d, f64(normal), np.sqrt(l2))
    f1 = microfacet_brdf(incoming, w_o, normal, roughness, 1.0)
    cos_q = np.maximum(dot(w_o, f64(normal)), 0.0)
    cos_x = np.maximum(-dot(w_o, f64(receiver_normal)), 0.0)
    flux_spec = f64(flux_rgb) * f64(rs_rgb)
    intensity = np.max(flux_spec, axis=-1) * f1 * cos_q
    geometry = np.where(l2 > 0.0, f1 * cos_q * cos_x / np.where(l2 > 0.0, l2, 1.0), 0.0)
    radiance = f64(receiver_albedo) / np.pi * flux_spec * geometry[..., None]
    return radiance, intensity, l2


def stochastic_weight(intensity, distance_squared, delta, xi):
    """1/p where the VPL is accepted (p > xi), else 0 (004 Eq. 3): the estimator's weight."""
    p = acceptance_probability(intensity, distance_squared, delta)
    return np.where(p > xi, 1.0 / np.where(p > 0.0, p, 1.0), 0.0)


def shade_glossy_vpls(receivers, receiver_normals, receiver_albedo, vpls, delta, xi, accepted=None):
    """Sum over VPLs of radiance weighted by 1/p for accepted VPLs (Eq. 3); ``xi`` per VPL.

    ``receivers`` (P, 3), ``vpls`` a dict of (K, ...) arrays; ``accepted`` an optional (P, K)
    mask (the tile lists) applied on top. delta = 0 gives brute force (every VPL, weight 1)."""
    radiance, intensity, l2 = glossy_vpl_radiance(
        receivers[:, None, :], receiver_normals[:, None, :], receiver_albedo[:, None, :],
        vpls["position"][None], vpls["normal"][None], vpls["incoming"][None],
        vpls["roughness"][None], vpls["flux"][None], vpls["rs"][None])
    if delta > 0.0:
        weight = stochastic_weight(intensity, l2, delta, xi[None, :])
    else:
        weight = np.ones_like(intensity)
    if accepted is not None:
        weight = weight * accepted
    return np.sum(radiance * weight[..., None], axis=1)


#: VPLs a strided preview keeps of one RSM view's texels (the viewport's coarse image).
PREVIEW_VPLS = 1024


def preview_stride(rsm_texels: int) -> int:
    """S of the strided preview: the VPLs of an RSM of `rsm_texels` texels thinned to PREVIEW_VPLS,
    at least 1 (16 for a 128 x 128 RSM)."""
    return max(int(rsm_texels) // PREVIEW_VPLS, 1)


def strided_vpl_jitter(k, seed, stride):
    """The member of block k (VPLs k S ... k S + S - 1) a strided preview shades, in [0, S)."""
    k = np.asarray(k, np.uint64)
    return (pcg_hash((k + pcg_hash(np.uint64(seed))) & 0xFFFFFFFF) % np.uint64(stride)).astype(np.int64)


def strided_vpls(count: int, stride: int, seed: int) -> np.ndarray:
    """Indices of the VPLs a strided preview shades, each weighted S (glsl/vpl_culling/
    vpl_cull_shade.comp.glsl): one of each block of S consecutive VPLs, i = k S + jitter(k) < count,
    a jittered stratified subsample whose expectation over the jitter is the full sum."""
    stride = max(int(stride), 1)
    k = np.arange((int(count) + stride - 1) // stride)
    if stride == 1:
        return k
    i = k * stride + strided_vpl_jitter(k, seed, stride)
    return i[i < int(count)]


def glossy_vpls_from_rsm(position, normal, incoming, flux, rs, roughness, caustic_roughness):
    """The RSM texels of sharp reflectors (alpha < alpha_c, lit: flux > 0) as glossy VPLs; the
    texel arrays flattened, nothing resampled (the VPL set is as stable as the RSM)."""
    roughness = f64(roughness).reshape(-1)
    flux = f64(flux).reshape(-1, 3)
    rs = f64(rs).reshape(-1, 3)
    keep = (roughness < caustic_roughness) & (np.max(flux * rs, axis=-1) > 0.0)
    return {
        "position": f64(position).reshape(-1, 3)[keep],
        "normal": f64(normal).reshape(-1, 3)[keep],
        "incoming": f64(incoming).reshape(-1, 3)[keep],
        "flux": flux[keep],
        "rs": rs[keep],
        "roughness": roughness[keep],
        "texel": np.flatnonzero(keep),
    }


#: Smallest GGX alpha a VPL's lobe takes: the range the spheroid bounds and the shading are tested on
#: (tests/test_reference_vpl_culling.py); a mirror texel (alpha 1e-6) shines as an alpha 1e-3 lobe.
VPL_ALPHA_MIN = 1e-3


def light_vector(light):
    """(x, y, z, w) of a light for :func:`incoming_from_light`: w = 1 and its position, or for a
    sun w = 0 and the direction towards it (-its direction)."""
    if light.type == "SUN":
        return np.append(-f64(light.direction), 0.0)
    return np.append(f64(light.position), 1.0)


def incoming_from_light(light, position):
    """w_i per texel, unit, from the surface towards the light (reference.rsm.incoming_directions):
    ``light`` (..., 4) of :func:`light_vector`."""
    light = f64(light)
    position = f64(position)
    towards = np.where(light[..., 3:4] > 0.5, light[..., :3] - position, light[..., :3] + 0.0 * position)
    return safe_normalize(towards, np.array([0.0, 0.0, 1.0]))


def glossy_vpl_from_texel(position, normal, flux_specular, light, caustic_roughness):
    """One RSM texel as a glossy VPL record (004 section 3, light-paths.md's sharp-reflector row):
    ``position``, ``normal`` and ``flux_specular`` are the texel's RSM slots (xyz = q, n facing the
    light and Phi Rs; normal's w = Principled roughness), ``light`` of :func:`light_vector`.

    Returns (keep, records (..., 4, 4)): keep where GGX alpha = principled_alpha(roughness) < alpha_c
    and the texel reflects some specular flux (max channel of Phi Rs > 0); the records are the
    culling table's (passes/vpl_culling.py vpl_table): (q, max(alpha, VPL_ALPHA_MIN)),
    (n, max channel of Phi Rs), (w_i, 0), (Phi Rs, 0)."""
    from .principled import principled_alpha

    position = f64(position)
    normal = f64(normal)
    flux_specular = f64(flux_specular)
    alpha = principled_alpha(normal[..., 3])
    scalar_flux = np.max(flux_specular[..., :3], axis=-1)
    keep = (alpha < caustic_roughness) & (scalar_flux > 0.0)
    records = np.zeros(position.shape[:-1] + (4, 4))
    records[..., 0, :3] = position[..., :3]
    records[..., 0, 3] = np.maximum(alpha, VPL_ALPHA_MIN)
    records[..., 1, :3] = normal[..., :3]
    records[..., 1, 3] = scalar_flux
    records[..., 2, :3] = incoming_from_light(light, position[..., :3])
    records[..., 3, :3] = flux_specular[..., :3]
    return keep, records


def extract_glossy_vpls(position, normal, flux_specular, light, caustic_roughness):
    """The glossy VPLs of one RSM view (H, W, 4 slots as :func:`glossy_vpl_from_texel` takes them):
    the kept texels' records (K, 4, 4) in row-major texel order (row 0 first), and their texel
    indices (K,). Nothing is resampled, so the set is as stable as the RSM; this order is the GPU
    extraction's (glsl/vpl_culling/vpl_extract_write.comp.glsl), so a VPL keeps its xi."""
    keep, records = glossy_vpl_from_texel(position, normal, flux_specular, light, caustic_roughness)
    keep = keep.reshape(-1)
    return records.reshape(-1, 4, 4)[keep], np.flatnonzero(keep)


def glossy_bounding_volumes(vpls, delta, xi, fmax=1.0):
    """Spheroids (Eqs. 13-15) of a VPL dict for per-VPL xi."""
    scalar_flux = np.max(vpls["flux"] * vpls["rs"], axis=-1)
    return ggx_spheroid(vpls["position"], vpls["normal"], vpls["incoming"], vpls["roughness"],
                        scalar_flux, delta, xi, fmax)


#: How far a tile frustum reaches beyond its outermost receivers' pixel centres, in pixels. The
#: receivers lie on their pixels' centre rays (the G-buffer is rasterised there: within 4e-5 px in
#: float32 on caustic_panel), so the frustum need not reach the tile's pixel edges; the margin keeps
#: them inside the side planes against the float32 rounding of the GPU's planes (about 1e-6 of the
#: view distance, the plane coefficients' relative rounding), and keeps a one-pixel-wide frustum
#: from having coincident side planes.
PIXEL_MARGIN = 1.0 / 64.0


def tile_receiver_ndc(pixel_min, pixel_max, size):
    """NDC rectangle (ndc_min, ndc_max) of a tile frustum over the receivers of the pixels (x, y)
    from ``pixel_min`` to ``pixel_max`` inclusive (the bounding box of the tile's covered pixels) of
    a ``size`` = (W, H) image: through their outermost pixel centres, widened by PIXEL_MARGIN.
    Pixel (x, y) has its centre at NDC (2 (x + 1/2) / W - 1, 2 (y + 1/2) / H - 1). The frustum
    culls only for these receivers, so it need not cover the tile's pixels' full area nor its
    uncovered (sky) pixels or the pixels beyond the image of a partial tile."""
    size = f64(size)
    ndc_min = (f64(pixel_min) + 0.5 - PIXEL_MARGIN) / size * 2.0 - 1.0
    ndc_max = (f64(pixel_max) + 0.5 + PIXEL_MARGIN) / size * 2.0 - 1.0
    return ndc_min, ndc_max


def tile_frustum_planes(inverse_projection, view_to_world, tile_ndc_min, tile_ndc_max, depth_min, depth_max):
    """World-space planes (n, d) of a tile frustum, inside n.x + d >= 0 (the GPU stage's planes).

    The tile spans NDC [min, max] in x and y and view-space depth [depth_min, depth_max] (positive
    distances along -z). The side plane x_ndc = X is the clip-space plane P_0 - X P_3 (P the
    projection's rows, clip w = P_3 . v > 0 in front of the camera; likewise y with P_1), which
    holds the tile edge's corner rays for a perspective or orthographic camera and, unlike a cross
    product of nearby corner points, keeps its float32 precision however narrow the tile. Plane k
    holds corners k and k + 1 (mod 4) of :func:`tile_frustum_corners`. The two depth planes are
    perpendicular to the view axis (004 Eq. 17 rotates the spheroid so this stays true per tile).
    Planes are made in view space and taken to world space as covectors, p_w = W2V^T p_v (the
    stretched-plane test does not depend on their scale)."""
    projection = np.linalg.inv(f64(inverse_projection))
    w2v = np.linalg.inv(f64(view_to_world))
    (x0, y0), (x1, y1) = tile_ndc_min, tile_ndc_max
    row_x, row_y, row_w = projection[0], projection[1], projection[3]
    planes = [row_y - y0 * row_w,  # y_ndc >= y0: corners 0, 1
              x1 * row_w - row_x,  # x_ndc <= x1: corners 1, 2
              y1 * row_w - row_y,  # y_ndc <= y1: corners 2, 3
              row_x - x0 * row_w,  # x_ndc >= x0: corners 3, 0
              np.array([0.0, 0.0, -1.0, -depth_min]),  # -z >= depth_min
              np.array([0.0, 0.0, 1.0, depth_max])]    # -z <= depth_max
    return np.array(planes) @ w2v


def tile_frustum_corners(inverse_projection, view_to_world, tile_ndc_min, tile_ndc_max, depth_min, depth_max):
    """World-space corners (8, 3) of :func:`tile_frustum_planes`' frustum: k = 0..3 the tile's NDC
    corners (x0, y0), (x1, y0), (x1, y1), (x0, y1) on their view rays at depth_min, 4 + k the same
    at depth_max; side plane k holds corners k, k + 1 (mod 4) and their depth_max twins."""
    inv = f64(inverse_projection)
    v2w = f64(view_to_world)

    def unproject(x, y, z):
        p = inv @ np.array([x, y, z, 1.0])
        return p[:3] / p[3]

    (x0, y0), (x1, y1) = tile_ndc_min, tile_ndc_max
    corners = []
    for depth in (depth_min, depth_max):
        for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)):
            near, far = unproject(x, y, -1.0), unproject(x, y, 1.0)
            t = (depth + near[2]) / (near[2] - far[2])
            corners.append(near + t * (far - near))
    view = np.array(corners)
    return view @ v2w[:3, :3].T + v2w[:3, 3]
