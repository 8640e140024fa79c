# SPDX-License-Identifier: GPL-3.0-or-later
"""Float64 twin of the imperfect shadow maps (ISMs) that give VSGLs visibility (000 §5 uses a 64²
ISM per VSGL; Ritschel et al. 2008): the octahedral projection, the point splat, the pull-push hole
fill and the filtered lookup.

**Projection: octahedral, the whole sphere in one square.** A VSGL's lobes are spherical Gaussians
with support on the whole sphere, and the diffuse lobe of a cluster of varied normals (000 Eq. 6's
Toksvig-shortened axis) reaches past any hemisphere; receivers at grazing angles from the lobe
axis are common (a floor's bounce onto the wall beside it). A paraboloid about the lobe axis covers
one hemisphere and would cut those receivers off; two paraboloids double the seams. The octahedral
map (d / |d|₁ folded onto the square) covers every direction with one tile, has no singularity,
keeps neighbouring texels neighbouring across its folds (``octahedral_wrap``), and its texels' solid
angles stay within a factor 3√3 ≈ 5.2 of each other (the density ratio of dω/(du dv) = |d|₁³ between
an octahedron face's centre and its vertices; 4.9 at 64², measured by quadrature in
tests/test_reference_ism.py; one paraboloid's is 4 over half the sphere), so one map serves both
lobes of a VSGL at one position.

**Depth** is the radial distance |p − o| from the ISM's origin o (a VSGL lobe's mean position),
stored per texel as the nearest splatted point. Positive floats keep their order as unsigned
integers, so the GPU splat is an ``imageAtomicMin`` on the float's bits (blender-gpu.md).

**Pull-push** (Ritschel et al. 2008 after Grossman and Dally): *pull* builds a pyramid whose texel
is the mean of its valid children, valid when any child is; *push* fills each hole of a level from
its parent, coarsest first. A map with one valid texel comes out full; valid texels keep their depth.

**Lookup**: a receiver at x sees the ISM's origin when |x − o| ≤ stored + bias. The bias (the
texel's footprint at the receiver's distance, slope-scaled by the receiver's incidence, plus a
floor) keeps the surface a VSGL sits on from shadowing itself; a receiver facing away from the
origin moves off its own surface, away from it, instead (``lookup_offsets``: the depth bias let the
light of VSGLs behind a thin wall through it). ``ism_pcf`` averages that test over the (2k+1)² texels around
the receiver's, wrapping across the octahedral folds: the VSGL is a Gaussian of positions (σ_v), not
a point, so its shadow is soft, and k follows σ_v / |x − o| in texels.
"""

from __future__ import annotations

import numpy as np

from .numerics import f64

#: Stored depth of a texel no point reached.
EMPTY = np.inf


def octahedral_encode(directions) -> np.ndarray:
    """(..., 2) octahedral coordinates in [−1, 1]² of directions (..., 3) (need not be unit)."""
    d = f64(directions)
    d = d / np.maximum(np.abs(d).sum(axis=-1, keepdims=True), 1e-300)
    xy = d[..., :2]
    sign = np.where(xy >= 0.0, 1.0, -1.0)
    folded = (1.0 - np.abs(xy[..., ::-1])) * sign
    return np.where((d[..., 2] < 0.0)[..., None], folded, xy)


def octahedral_decode(uv) -> np.ndarray:
    """(..., 3) unit directions of octahedral coordinates (..., 2) in [−1, 1]²."""
    uv = f64(uv)
    z = 1.0 - np.abs(uv[..., 0]) - np.abs(uv[..., 1])
    sign = np.where(uv >= 0.0, 1.0, -1.0)
    xy = np.where((z < 0.0)[..., None], (1.0 - np.abs(uv[..., ::-1])) * sign, uv)
    d = np.concatenate([xy, z[..., None]], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def ism_texel(directions, size: int) -> np.ndarray:
    """(..., 2) int64 texel (column, row) of directions in a ``size`` × ``size`` octahedral map."""
    uv = octahedral_encode(directions)
    return np.clip(np.floor((uv * 0.5 + 0.5) * size), 0, size - 1).astype(np.int64)


def texel_directions(size: int) -> np.ndarray:
    """(size, size, 3) unit directions of the texel centres, [row, column]."""
    centres = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    u, v = np.meshgrid(centres, centres, indexing="xy")
    return octahedral_decode(np.stack([u, v], axis=-1))


def octahedral_wrap(column, row, size: int):
    """The texel a neighbourhood reaches past the square's edge: across an edge of the octahedral
    map lies the mirror image about the edge's midpoint (the fold), so (−1 − c, S − 1 − r) for a
    column off the left, and likewise for the other edges."""
    column, row = np.asarray(column).copy(), np.asarray(row).copy()
    for _ in range(2):  # a corner reaches off two edges
        off = (column < 0) | (column >= size)
        column = np.where(column < 0, -1 - column, np.where(column >= size, 2 * size - 1 - column, column))
        row = np.where(off, size - 1 - row, row)
        off = (row < 0) | (row >= size)
        row = np.where(row < 0, -1 - row, np.where(row >= size, 2 * size - 1 - row, row))
        column = np.where(off, size - 1 - column, column)
    return column, row


#: Largest splat radius in texels: a point covers at most (2r + 1)² texels.
SPLAT_MAX_RADIUS = 3
#: The largest radius of the maps that keep their surfaces (vsgl_addon/pipeline.py
#: SURFACE_LIGHT_TYPES): their oriented splats keep a surface's depth across a wide splat, and the
#: VSGLs just behind a thin wall see its points sparsely (a point 0.4 m away stands for hundreds
#: of texels), so the splat of SPLAT_MAX_RADIUS leaves holes through which the ground behind shows:
#: the sun courtyard's maps give 1.132 of Cycles' light with 3, 1.110 with 6, 1.102 with 8 and 1.101
#: with 12, exact depth maps 1.085 (float64 lookups; texels written per point 1.39 with 3, 1.42 with 8).
#: With every light's maps keeping their surfaces, the VSGLs on the occluder scene's floor by its low
#: wall see the wall as sparsely: whole frames (seeds 0-1) give its relative RMSE 0.836 with point
#: maps, 0.850 with 8 and 0.834 with 12, the courtyard's 0.260 with 8 and 0.251 with 12, the rest of
#: the suite within 0.001 (benchmarks/results/ism_surfaces_cap12.md).
SURFACE_SPLAT_MAX_RADIUS = 12
#: The splat's width over the mean spacing of the points seen from the map's origin (splat_radius).
SPLAT_SHARE = 0.7071067811865476


def texel_solid_angle(offsets, size):
    """Solid angle of the octahedral texel around each direction: (2/size)² / |p|³ with
    p = d/|d|₁ the point on the octahedron (dω = dA_uv / |p|³ on a face), so from 4/size² on the
    axes to 3√3 times that at the face centres."""
    d = f64(offsets)
    ratio = np.abs(d).sum(axis=-1) / np.maximum(np.linalg.norm(d, axis=-1), 1e-300)  # 1/|p| = |d|₁/|d|
    return 4.0 / (size * size) * ratio ** 3


def splat_radius(offsets, cos_theta, point_area, size, max_radius=None):
    """The half-width in texels of a point's splat: the point stands for ``point_area`` of the
    surface, which subtends point_area · |cos θ| / d² seen from the origin, n texels of the local
    :func:`texel_solid_angle`; neighbouring points then lie about √n texels apart, and a square
    splat of 2r + 1 ≥ s texels, r = ⌈(s − 1)/2⌉ (at most SPLAT_MAX_RADIUS), covers a gap of s;
    s = SPLAT_SHARE·√n, less than the mean spacing √n, since the jittered points' gaps are mostly
    shorter (a Poisson set's nearest neighbour lies at half the mean spacing) and pull-push fills
    the rest. A larger splat grows every silhouette by the excess: with s = √n + 1/2 the occluder
    scene's receiver lost 15 % of the unshadowed light that exact visibility keeps, with
    s = √n 9 %, with s = √n/√2 4 % (benchmarks/visibility_diagnosis.py). A point splatted into one texel
    leaves holes in a near occluder, which the points behind it then fill: the leak of point-based
    ISMs (Ritschel et al. 2008); sized splats close those holes with the occluder's own depth.
    ``max_radius``: the cap instead of SPLAT_MAX_RADIUS."""
    d = f64(offsets)
    distance2 = np.maximum((d * d).sum(axis=-1), 1e-300)
    texels = f64(point_area) * np.abs(f64(cos_theta)) / distance2 / texel_solid_angle(d, size)
    cap = SPLAT_MAX_RADIUS if max_radius is None else max_radius
    return np.clip(np.ceil(0.5 * (SPLAT_SHARE * np.sqrt(texels) - 1.0)), 0, cap).astype(np.int64)


def splat(points, origin, size: int, min_distance: float = 0.0, normals=None, point_area: float = 0.0,
          plane=None, plane_depth: float = 0.0, max_radius=None) -> np.ndarray:
    """(size, size) float64 map [row, column] of the nearest radial distance of ``points`` (N, 3)
    seen from ``origin`` (3,) per texel; EMPTY where none lands. Points closer than
    ``min_distance`` (the origin's own point) are not splatted, nor, with ``plane`` = (n_x, n_y,
    n_z, c), the points whose offset p − origin has n · (p − origin) < c (:func:`keeps_point`).
    With ``normals`` and the surface area each point stands for (``point_area``), a point covers
    the texels of :func:`splat_radius` around its own (wrapping across the octahedral folds), each
    at the point's distance (``plane_depth`` 0) or at its tangent plane's depth within
    ``plane_depth`` point spacings of it (:func:`tangent_plane_depth`; the maps that keep their surfaces,
    SURFACE_LIGHT_TYPES in vsgl_addon/pipeline.py, take SPLAT_PLANE_DEPTH), the radius capped at
    ``max_radius`` (None: SPLAT_MAX_RADIUS; those maps take SURFACE_SPLAT_MAX_RADIUS)."""
    offsets = f64(points).reshape(-1, 3) - f64(origin)
    distance = np.linalg.norm(offsets, axis=-1)
    keep = np.isfinite(distance) & (distance > max(min_distance, 1e-300))
    if plane is not None:
        keep &= keeps_point(offsets, plane)
    offsets, distance = offsets[keep], distance[keep]
    texel = ism_texel(offsets, size)
    depth = np.full((size, size), EMPTY)
    if normals is None or not point_area > 0.0:
        np.minimum.at(depth, (texel[:, 1], texel[:, 0]), distance)
        return depth
    normals = f64(normals).reshape(-1, 3)[keep]
    cos_theta = (normals * offsets).sum(axis=-1) / distance
    radius = splat_radius(offsets, cos_theta, point_area, size, max_radius)
    directions = texel_directions(size) if plane_depth > 0.0 else None
    for r in np.unique(radius):
        here = radius == r
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                column, row = octahedral_wrap(texel[here, 0] + dx, texel[here, 1] + dy, size)
                written = distance[here]
                if directions is not None:
                    written = tangent_plane_depth(offsets[here], normals[here], directions[row, column],
                                                  point_area, plane_depth)
                np.minimum.at(depth, (row, column), written)
    return depth


#: The splat of the maps that keep their surfaces (vsgl_addon/pipeline.py SURFACE_LIGHT_TYPES):
#: each texel where its direction meets the point's tangent plane, within SPLAT_PLANE_DEPTH point
#: spacings (√point_area) of the point's distance (tangent_plane_depth; 0: the distance).
SPLAT_PLANE_DEPTH = 1.0


def tangent_plane_depth(offsets, normals, directions, point_area, reach_spacings=None):
    """(N,) the depth a point (offset p − o from the map's origin, unit normal n) writes into the
    splat texel of unit centre direction u: the disk the point stands for lies in its tangent plane,
    which the texel's ray meets at t = n · (p − o) / n · u (an oriented splat, a surfel: Pfister et
    al. 2000). Its own distance |p − o| written over the whole splat is nearer than its surface by up
    to the splat's half-width times the surface's depth slope, so a receiver on that surface at grazing
    incidence shadows itself unless the lookup's bias spans the splat; the slope-scaled depth bias
    that does so reaches through a thin wall in front of the receiver. t is kept within
    ``reach_spacings`` (None: SPLAT_PLANE_DEPTH) · √point_area of |p − o| (the depth the disk and its neighbours' gap can span;
    the plane's depth grows without bound towards its horizon), and a ray that leaves the plane
    behind (t ≤ 0, or n · u = 0) takes the far end of that range: the surface recedes there."""
    offsets, normals, directions = f64(offsets), f64(normals), f64(directions)
    distance = np.linalg.norm(offsets, axis=-1)
    reach = (SPLAT_PLANE_DEPTH if reach_spacings is None else reach_spacings) * np.sqrt(max(f64(point_area), 0.0))
    across = (normals * directions).sum(axis=-1)
    height = (normals * offsets).sum(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = height / across
    t = np.where(np.isfinite(t) & (t > 0.0), t, distance + reach)
    return np.clip(t, distance - reach, distance + reach)


def keeps_point(offsets, plane) -> np.ndarray:
    """(N,) bool: a map's half-space ``plane`` = (n, c) keeps the points at ``offsets`` (N, 3) from its
    origin with n · offset ≥ c (glsl/ism/ism_splat.comp.glsl). n = 0, c = 0 (the default) keeps
    every point; a map that stands for a flat reflector passes its plane (passes/vpl_culling.py
    vpl_clusters), so the reflector's own surface, and anything behind it, is not splatted."""
    plane = f64(plane).reshape(4)
    return ~(f64(offsets).reshape(-1, 3) @ plane[:3] < plane[3])


#: Gaps of up to 2·GAP_REACH − 1 texels between nearer texels on both sides are closed (close_gaps).
GAP_REACH = 3
#: A texel is a gap when both sides are nearer than (1 − GAP_MARGIN) times its depth.
GAP_MARGIN = 0.1
#: The four lines a gap is looked for along: rows, columns, both diagonals.
GAP_DIRECTIONS = ((1, 0), (0, 1), (1, 1), (1, -1))
#: The gap closing of the maps that keep their surfaces (vsgl_addon/pipeline.py
#: SURFACE_LIGHT_TYPES): each side's surface continued to the texel as a plane (close_gaps
#: ``continued``); False: the side's nearest depth as it is.
GAP_EXTRAPOLATE = True


def close_gaps(depth, continued: bool = False) -> np.ndarray:
    """The splatted map with its gaps closed before pull-push: a texel (empty or not) whose nearest
    depths within GAP_REACH texels on *both* sides along a row, column or diagonal are nearer than
    (1 − GAP_MARGIN) × its own takes the farther of those two (the least over the four lines),
    wrapping across the octahedral folds. Through a hole in a near occluder the points behind it
    show (the leak of point-based maps); pull-push fills only texels no point reached, and sized
    splats close holes only by growing every silhouette as much. A hole has the occluder on both
    sides, a silhouette's background only on one, so this closes holes up to 2·GAP_REACH − 1
    texels wide and leaves outlines where they are (concave corners of an outline and slits
    narrower than the reach close too). On a continuous surface the depth changes by much less
    than GAP_MARGIN per texel, so the surfaces' own texels stay. ``continued``: each side's
    surface is continued to the texel as a plane (:func:`_plane_continued`) and the texel is a gap
    only when both continued sides pass in front of it: a room's concave corner, farther than the
    walls on both sides, is no gap (with oriented splats, whose depths follow the walls' planes)."""
    depth = f64(depth)
    size = depth.shape[0]
    rows, columns = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    best = np.full(depth.shape, EMPTY)
    scale = 1.0 / np.abs(texel_directions(size)).sum(axis=-1)  # |q|, q = d/|d|₁ on the octahedron
    reach = min(GAP_REACH, size)  # the fold's mirror reaches at most a side
    for dx, dy in GAP_DIRECTIONS:
        sides, surfaces = [], []
        for sign in (-1, 1):
            nearest = np.full(depth.shape, EMPTY)
            at = np.zeros(depth.shape, np.int64)
            for k in range(1, reach + 1):
                column, row = octahedral_wrap(columns + sign * k * dx, rows + sign * k * dy, size)
                here = depth[row, column]
                at = np.where(here < nearest, k, at)
                nearest = np.minimum(nearest, here)
            sides.append(nearest)
            if continued:
                surfaces.append(np.maximum(nearest, _plane_continued(depth, scale, columns, rows, sign * dx,
                                                                     sign * dy, at, size)))
            else:
                surfaces.append(nearest)
        farther = np.maximum(sides[0], sides[1])
        gap = np.maximum(surfaces[0], surfaces[1]) < (1.0 - GAP_MARGIN) * depth
        best = np.minimum(best, np.where(gap, farther, EMPTY))
    return np.minimum(depth, best)


def _plane_continued(depth, scale, columns, rows, dx, dy, at, size):
    """The depth at each texel of the surface seen ``at`` and at + 1 texels away along (dx, dy),
    continued as a plane: a plane n · x = h seen from the origin has depth t = h |q| / (n · q) along
    the octahedron's point q of a direction, and q is linear in the texel coordinates on each face,
    so |q| / t is too. EMPTY where the continued plane turns away (|q| / t ≤ 0) or the texel beyond
    is empty: a side whose surface is not known makes the texel no gap."""
    column, row = octahedral_wrap(columns + at * dx, rows + at * dy, size)
    near_w = scale[row, column] / depth[row, column]
    column, row = octahedral_wrap(columns + (at + 1) * dx, rows + (at + 1) * dy, size)
    beyond_w = scale[row, column] / depth[row, column]
    w = near_w + at * (near_w - beyond_w)
    with np.errstate(divide="ignore", invalid="ignore"):
        continued = np.where((w > 0.0) & (beyond_w > 0.0) & (near_w > 0.0), scale / w, EMPTY)
    return continued


def pull_push(depth) -> np.ndarray:
    """The map with its holes (EMPTY) filled (see the module documentation); ``size`` a power of
    two. A map with no valid texel stays EMPTY."""
    depth = f64(depth)
    size = depth.shape[0]
    if size & (size - 1) or depth.shape != (size, size):
        raise ValueError(f"pull-push needs a square power-of-two map, got {depth.shape}")
    levels, valid = [np.where(np.isfinite(depth), depth, 0.0)], [np.isfinite(depth)]
    while levels[-1].shape[0] > 1:
        d, w = levels[-1], valid[-1].astype(np.float64)
        half = d.shape[0] // 2
        total = (d * w).reshape(half, 2, half, 2).sum(axis=(1, 3))
        count = w.reshape(half, 2, half, 2).sum(axis=(1, 3))
        levels.append(np.where(count > 0, total / np.maximum(count, 1.0), 0.0))
        valid.append(count > 0)
    filled, known = levels[-1], valid[-1]
    for d, w in zip(reversed(levels[:-1]), reversed(valid[:-1])):
        parent = np.repeat(np.repeat(filled, 2, axis=0), 2, axis=1)
        parent_known = np.repeat(np.repeat(known, 2, axis=0), 2, axis=1)
        filled = np.where(w, d, parent)
        known = w | parent_known
    return np.where(known, filled, EMPTY)


#: A lobe's shadow origin lies this many σ_v from its mean along its axis (shadow_origin). The
#: GPU's twin is ISM_SHADOW_ORIGIN_SIGMAS of glsl/lib/ism.glsl, compiled from this value (its define
#: ISM_ORIGIN_SIGMAS, vsgl_addon/shaders.py LIBRARY_DEFINES; passes/ism.py set_shadow_origin_sigmas).
SHADOW_ORIGIN_SIGMAS = 0.5


def shadow_origin(mean, variance, axis, sigmas=None):
    """Where a VSGL lobe's map is centred: its mean position μ_v moved ``sigmas``·σ_v (None:
    SHADOW_ORIGIN_SIGMAS, read at the call) along
    its unit lobe axis ξ_v (the direction its light leaves in). μ_v is the mean of its cluster's
    surface points, so on a curved or folded cluster it lies behind the surface (inside a ball,
    behind a block's edge) and a segment from μ_v to a receiver first crosses the cluster's own
    surface; moved off the surface by a fraction of the cluster's spread it sees what the cluster
    sees. Exact visibility (ray-cast, benchmarks/visibility_diagnosis.py) of the occluder scene
    rises from 0.894 to 0.921 of Cycles' light with 0.5 σ_v, the Cornell box's from 0.747 to 0.763."""
    sigmas = SHADOW_ORIGIN_SIGMAS if sigmas is None else sigmas
    sigma = np.sqrt(np.maximum(f64(variance), 0.0))
    return f64(mean) + f64(sigmas) * sigma[..., None] * f64(axis)



def vsgl_map_origins(vsgls, maps_per_vsgl: int, first_map: int, point_sets: int, own_reflector_sigmas: float):
    """The splat's table of a VSGL table's maps (GPU twin: glsl/ism/ism_origins.comp.glsl): map i
    (``maps_per_vsgl`` 1) or maps 2i, 2i + 1 (2: the diffuse and the specular lobe) of VSGL i, each
    centred on its lobe's shadow_origin, splatting point set (first_map + map) mod ``point_sets``
    (Ritschel et al. 2008 give neighbouring maps different subsets) and leaving out the points within
    ``own_reflector_sigmas`` σ_v of the origin (the lobe's own reflector, 000 §5). Returns
    (origins (M, 3), set index (M,), minimum distance (M,)), float64."""
    if maps_per_vsgl not in (1, 2):
        raise ValueError(f"maps per VSGL must be 1 or 2, got {maps_per_vsgl}")
    lobes = ("diffuse",) if maps_per_vsgl == 1 else ("diffuse", "specular")
    means = np.stack([f64(vsgls[f"{lobe}_mean"]).reshape(-1, 3) for lobe in lobes], axis=1)
    variances = np.stack([f64(vsgls[f"{lobe}_variance"]).reshape(-1) for lobe in lobes], axis=1)
    axes = np.stack([f64(vsgls[f"{lobe}_axis"]).reshape(-1, 3) for lobe in lobes], axis=1)
    origins = shadow_origin(means, variances, axes).reshape(-1, 3)
    sigma = np.sqrt(np.maximum(variances, 0.0)).reshape(-1)
    maps = np.arange(first_map, first_map + len(origins))
    return origins, maps % point_sets, f64(own_reflector_sigmas) * sigma


#: Largest tan of the receiver's incidence the slope-scaled bias follows (as lib/shadow.glsl).
ISM_MAX_SLOPE = 8.0


def ism_bias(distance, size: int, tan_incidence=0.0, slope: float = 1.0, floor: float = 1e-3):
    """Depth bias at radial ``distance``: ``slope`` texel footprints (a texel spans about
    sqrt(4π)/size rad) × (1 + tan θ), θ the receiver's incidence from the ISM's origin (capped at
    ISM_MAX_SLOPE: a surface seen at grazing angles spans more depth per texel), plus ``floor``
    metres."""
    tan_incidence = np.minimum(f64(tan_incidence), ISM_MAX_SLOPE)
    return slope * f64(distance) * np.sqrt(4.0 * np.pi) / size * (1.0 + tan_incidence) + floor


def tan_incidence(normals, offsets, distance):
    """tan of the angle between receiver normals and the direction towards the ISM's origin."""
    cos_theta = np.clip(np.abs((f64(normals) * -f64(offsets)).sum(axis=-1)) / np.maximum(distance, 1e-300), 0, 1)
    return np.sqrt(np.maximum(1.0 - cos_theta * cos_theta, 0.0)) / np.maximum(cos_theta, 1e-3)


#: The lookup's receiver offset along its normal, in filter footprints (:func:`lookup_offsets`); 0:
#: none, the slope-scaled depth bias of :func:`ism_bias`. The GPU's twins are ISM_NORMAL_OFFSET,
#: ISM_NORMAL_OFFSET_DEPTH and ISM_BACK_OFFSET of glsl/lib/ism.glsl, compiled from these values
#: (vsgl_addon/shaders.py LIBRARY_DEFINES; passes/ism.py set_lookup_bias).
NORMAL_OFFSET = 0.0
#: With NORMAL_OFFSET > 0, the depth bias left, in texel footprints at the receiver's distance.
NORMAL_OFFSET_DEPTH = 0.5
#: A receiver facing away from the map's origin moves this many filter footprints away from it
#: along its normal, with no depth bias but 1 mm; 0: it is biased as one facing the origin. 1 gives
#: the sun courtyard 1.405 of Cycles' light instead of 1.432 (its shaded wall's glossy tiles 1.57
#: instead of 1.64) and leaves the rest of the suite within 0.003 (benchmarks/ism_lookup_bias.py).
BACK_OFFSET = 1.0
#: The bilinear lookup's bias at most SPREAD_BIAS times the depth spread of its four texels plus
#: NORMAL_OFFSET_DEPTH texel footprints (:func:`ism_pcf_bilinear`); 0: no such cap.
SPREAD_BIAS = 0.0


#: The lookup of the maps that keep their surfaces and take the normal offset (the sun's:
#: vsgl_addon/pipeline.py NORMAL_OFFSET_LIGHT_TYPES; the others' keep the slope-scaled depth bias):
#: NORMAL_OFFSET and NORMAL_OFFSET_DEPTH for them (lookup_offsets ``surfaces``). The GPU's twins are
#: the defines ISM_SURFACE_OFFSET and ISM_SURFACE_OFFSET_DEPTH of glsl/lib/ism.glsl.
SURFACE_NORMAL_OFFSET = 1.0
SURFACE_NORMAL_OFFSET_DEPTH = 1.0


def lookup_offsets(offsets, normals, size: int, footprint: float, surfaces: bool = False):
    """The receivers' offsets from the map's origin (..., 3) and their depth bias (...,) as the
    lookup tests them, for a filter of ``footprint`` texels (α = √(4π)/size a texel's span, θ the
    receiver's incidence from the origin, n its unit normal, which faces the camera).

    NORMAL_OFFSET 0 (or no normals): the offsets unchanged and :func:`ism_bias`, footprint · |x − o|
    · α · (1 + tan θ), tan θ capped at ISM_MAX_SLOPE. Else the receiver x moves off its own surface
    along n, turned towards the origin, by δ = NORMAL_OFFSET · footprint · |x − o| · α · sin θ,
    with a depth bias of NORMAL_OFFSET_DEPTH texel footprints plus 1 mm (Holbert's normal-offset
    shadows). Against the receiver's own plane that is a depth margin of δ / cos θ (with
    NORMAL_OFFSET 1 a footprint's depth slope, without a cap); against an occluder in front only
    δ · cos θ ≤ δ / 2 nearer (and δ · sin θ sideways), where the slope-scaled depth bias moves the
    receiver through it by up to nine footprints at grazing incidence, more than a thin wall.

    BACK_OFFSET > 0: a receiver facing away from the origin (n · (o − x) < 0: its own surface
    stands between them; the G-buffer's normal faces the camera) moves BACK_OFFSET · footprint ·
    |x − o| · α along n, away from the origin, with 1 mm of depth bias, whatever NORMAL_OFFSET is:
    it sees the origin only if nothing is splatted across its own surface's texels, where either
    bias above lets the light of a VSGL behind a wall that is thinner than the bias through it.

    ``surfaces``: a map that keeps its surfaces' depth (oriented splats, continued gap sides) takes
    SURFACE_NORMAL_OFFSET and SURFACE_NORMAL_OFFSET_DEPTH instead: its receivers' own surfaces are
    stored at their depth, so the small depth bias the normal offset leaves does not shadow them,
    and the offset stops the light of a VSGL behind a thin wall that the slope-scaled depth bias of
    a grazed receiver lets through (benchmarks/ism_holes.py)."""
    normal_offset = SURFACE_NORMAL_OFFSET if surfaces else NORMAL_OFFSET
    offset_depth = SURFACE_NORMAL_OFFSET_DEPTH if surfaces else NORMAL_OFFSET_DEPTH
    offsets = f64(offsets)
    distance = np.linalg.norm(offsets, axis=-1)
    if normals is None:
        return offsets, ism_bias(distance, size, 0.0, slope=footprint)
    normals = f64(normals)
    towards = (normals * -offsets).sum(axis=-1)
    cos_theta = np.clip(np.abs(towards) / np.maximum(distance, 1e-300), 0.0, 1.0)
    sin_theta = np.sqrt(np.maximum(1.0 - cos_theta * cos_theta, 0.0))
    bias = ism_bias(distance, size, sin_theta / np.maximum(cos_theta, 1e-3), slope=footprint)
    texel = footprint * distance * np.sqrt(4.0 * np.pi) / size
    shift = np.zeros_like(distance)
    if normal_offset > 0.0:
        shift = normal_offset * texel * sin_theta * np.where(towards >= 0.0, 1.0, -1.0)
    back = (towards < 0.0) & (BACK_OFFSET > 0.0)
    shift = np.where(back, BACK_OFFSET * texel, shift)
    moved = offsets + shift[..., None] * normals
    if normal_offset > 0.0:
        bias = offset_depth * np.linalg.norm(moved, axis=-1) * np.sqrt(4.0 * np.pi) / size + 1e-3
    return moved, np.where(back, 1e-3, bias)


def _receiver(depth, origin, receivers, normals, bias, footprint=1.0, surfaces=False):
    size = depth.shape[0]
    offsets = f64(receivers) - f64(origin)
    if bias is None:
        offsets, bias = lookup_offsets(offsets, normals, size, footprint, surfaces)
    return ism_texel(offsets, size), np.linalg.norm(offsets, axis=-1), f64(bias)


def ism_visibility(depth, origin, receivers, normals=None, bias=None, surfaces=False) -> np.ndarray:
    """1 where receivers (..., 3) see the ISM's origin (nothing stored nearer than them, less the
    bias; default :func:`ism_bias`, slope-scaled by the receivers' ``normals`` when given), 0 where
    the map holds something in front."""
    texel, distance, bias = _receiver(depth, origin, receivers, normals, bias, surfaces=surfaces)
    stored = f64(depth)[texel[..., 1], texel[..., 0]]
    return (distance <= stored + bias).astype(np.float64)


def ism_pcf(depth, origin, receivers, radius: int, normals=None, bias=None, surfaces=False) -> np.ndarray:
    """The visibility test averaged over the (2·radius + 1)² texels around each receiver's texel,
    wrapping across the octahedral folds (percentage-closer filtering). The default bias spans the
    filter's footprint (1 + radius texels): a neighbour texel of a sloped surface lies nearer."""
    size = depth.shape[0]
    depth = f64(depth)
    texel, distance, bias = _receiver(depth, origin, receivers, normals, bias, 1.0 + radius, surfaces)
    total = np.zeros(distance.shape)
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            column, row = octahedral_wrap(texel[..., 0] + dx, texel[..., 1] + dy, size)
            total += distance <= depth[row, column] + bias
    return total / (2 * radius + 1) ** 2


def ism_pcf_bilinear(depth, origin, receivers, normals=None, bias=None, surfaces=False) -> np.ndarray:
    """The visibility test on the four texels around each receiver's continuous position in the
    map (texel centres at (i + ½)/size of the octahedral square), weighted bilinearly: a filter of
    about two texels from one textureGather on the GPU. The block is kept inside the square
    (clamped at its edges, where the weights then fall on the edge texels: the texel holding the
    direction among them) instead of wrapping across the folds: the wrap's four separate fetches
    and mirrors cost the shading pass more than the rest of its lookup on llvmpipe, which runs
    both sides of a branch (benchmarks/visibility_cost.py). A 1² map: its one texel. The default
    bias (:func:`lookup_offsets`, ``surfaces`` as there) spans the filter's footprint (two texels)."""
    size = depth.shape[0]
    depth = f64(depth)
    offsets = f64(receivers) - f64(origin)
    if bias is None:
        offsets, bias = lookup_offsets(offsets, normals, size, 2.0, surfaces)
    distance = np.linalg.norm(offsets, axis=-1)
    cell = (octahedral_encode(offsets) * 0.5 + 0.5) * size - 0.5
    corner = np.clip(np.floor(cell), 0.0, max(size - 2, 0))
    f = np.clip(cell - corner, 0.0, 1.0) * (size > 1)
    corner = corner.astype(np.int64)
    block = []
    for dy in (0, 1):
        for dx in (0, 1):
            column = np.minimum(corner[..., 0] + dx, size - 1)
            row = np.minimum(corner[..., 1] + dy, size - 1)
            block.append(((f[..., 0] if dx else 1.0 - f[..., 0]) * (f[..., 1] if dy else 1.0 - f[..., 1]),
                          depth[row, column]))
    bias = f64(bias)
    if SPREAD_BIAS > 0.0 and size > 1 and normals is not None:
        # The map's own depth spread over the block bounds what its surface's slope needs: a wall
        # seen face-on spreads little, so a receiver behind it gets little bias; an empty texel
        # (EMPTY) spreads without bound and leaves the bias as it was.
        nearest = np.minimum.reduce([d for _, d in block])
        farthest = np.maximum.reduce([d for _, d in block])
        spread = np.where(np.isinf(farthest), np.inf, farthest - nearest)
        floor = NORMAL_OFFSET_DEPTH * distance * np.sqrt(4.0 * np.pi) / size + 1e-3
        bias = np.minimum(bias, SPREAD_BIAS * spread + floor)
    total = np.zeros(distance.shape)
    for weight, stored in block:
        total += weight * (distance <= stored + bias)
    return total
