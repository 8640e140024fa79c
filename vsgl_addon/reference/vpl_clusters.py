# SPDX-License-Identifier: GPL-3.0-or-later
"""Float64 twin of the glossy VPLs' shadow-map clusters (GLSL: ``glsl/lib/vpl_clusters.glsl``,
``glsl/vpl_culling/vpl_clusters.comp.glsl`` and ``vpl_cluster_sets.comp.glsl``; the pass:
``vsgl_addon/passes/vpl_culling.py``).

VPL visibility (light-paths.md: every technique's light is shadowed) is one imperfect shadow map
(000 §5's ISMs, Ritschel et al. 2008) per cluster of VPLs, the texels of one CLUSTER_TEXELS² block of
one RSM view. 004 §7 omits visibility; why these maps is said at passes/vpl_culling.py
CLUSTER_TEXELS. A cluster's map is centred on the Φ-weighted mean position of its VPLs moved off the
surface along their mean normal (reference.ism.shadow_origin, as a VSGL lobe's: the Φ-weighted
variance per axis is its σ_v²), leaves out the points within OWN_REFLECTOR_SIGMAS σ of that origin
(its own reflector, as a VSGL's) and those outside :func:`cluster_planes`' half-space.

Map m of a frame's VPLs is block m mod blocks² of view m div blocks² (:func:`vpl_cluster_map`), so a
VPL's map follows from its texel on the GPU without a search; a block without a VPL keeps an empty
map (EMPTY_CLUSTER_DISTANCE: no point is splatted). The occupied maps take the point sets in order,
(first map + occupied maps before it) mod point sets: the sets the maps of a compacted list of
clusters get, so the maps are the same whichever way they are counted.
"""

from __future__ import annotations

import math

import numpy as np

from .ism import shadow_origin
from .numerics import f64

#: The side of a cluster's block of RSM texels (a GPU work group of CLUSTER_TEXELS² invocations).
CLUSTER_TEXELS = 16
#: Metres above its VPLs' plane a cluster's map starts (the floor of reference.ism.ism_bias): the
#: reflector's own points, sampled from float32 triangles, lie within rounding of that plane.
CLUSTER_PLANE_SLACK = 1e-3
#: An empty block's minimum distance: beyond every point, so its map keeps none (all unknown).
EMPTY_CLUSTER_DISTANCE = 1e30
#: Added to each VPL's weight max(Φ Rs): a cluster of VPLs whose flux rounds to nothing still has a
#: mean (of its positions).
CLUSTER_WEIGHT_FLOOR = 1e-30


def cluster_blocks(view_size: int) -> int:
    """Blocks per side of a ``view_size``² RSM view (a partial block at the edge counts)."""
    return max(1, math.ceil(int(view_size) / CLUSTER_TEXELS))


def vpl_cluster_map(texel, view, view_size: int) -> np.ndarray:
    """The map of the VPL of RSM texel ``texel`` (row-major, x + side y) of view ``view``: view ·
    blocks² + the texel's block, row-major (GLSL vpl_cluster_map)."""
    texel = np.asarray(texel, np.int64)
    blocks = cluster_blocks(view_size)
    block = (texel // view_size) // CLUSTER_TEXELS * blocks + (texel % view_size) // CLUSTER_TEXELS
    return np.asarray(view, np.int64) * blocks * blocks + block


def cluster_planes(positions, cluster, origins, axis, slack: float = CLUSTER_PLANE_SLACK) -> np.ndarray:
    """(C, 4) half-space of each cluster's map (reference.ism.keeps_point: n · (p − origin) ≥ c): the
    points above the plane through its highest VPL along its mean normal n, plus ``slack``. A glossy
    VPL's light leaves into the hemisphere of its normal, so on a flat cluster (every normal n) a
    segment from a VPL to a receiver it lights stays above the plane of its start, and a point below
    the highest VPL's plane can only block it where it leaves the surface, inside the slack: leaving
    such points out is exact there. Kept, the reflector's own surface, seen edge-on from an origin
    just above it, splats a band of near depths at the map's horizon, which pull-push then spreads
    into the sparse texels above it: a mirror floor shadowed the wall behind it and the objects on it
    (validation suite, polished_metal_floor). On a curved cluster this is an approximation: a VPL
    whose normal leans off n lights receivers a little below that plane, and what stands there is not
    in its map. A cluster without a VPL gets c = −inf (callers keep such rows out)."""
    origins, axis = f64(origins).reshape(-1, 3), f64(axis).reshape(-1, 3)
    cluster = np.asarray(cluster, np.int64)
    heights = np.einsum("ij,ij->i", f64(positions).reshape(-1, 3) - origins[cluster], axis[cluster])
    top = np.full(len(origins), -np.inf)
    np.maximum.at(top, cluster, heights)
    return np.concatenate([axis, (top + slack)[:, None]], axis=-1)


def cluster_statistics(vpls, cluster, count: int):
    """(Φ-weighted mean (C, 3), variance per axis (C,), unit mean normal (C, 3), weight sum (C,)) of
    the VPLs of each of ``count`` clusters (``cluster``: each VPL's). Weight max(Φ Rs) +
    CLUSTER_WEIGHT_FLOOR; a cluster without a VPL has zeros."""
    cluster = np.asarray(cluster, np.int64)
    positions, normals = f64(vpls["position"]).reshape(-1, 3), f64(vpls["normal"]).reshape(-1, 3)
    weight = np.max(f64(vpls["flux"]) * f64(vpls["rs"]), axis=-1).reshape(-1) + CLUSTER_WEIGHT_FLOOR

    def sums(values):
        return f64(np.bincount(cluster, values, count))[:count]

    total = sums(weight)
    safe = np.where(total > 0.0, total, 1.0)
    mean = np.stack([sums(weight * positions[:, k]) for k in range(3)], -1) / safe[:, None]
    variance = sums(weight * np.sum((positions - mean[cluster]) ** 2, axis=-1)) / safe / 3.0  # per axis, as σ_v²
    axis = np.stack([sums(weight * normals[:, k]) for k in range(3)], -1)
    axis /= np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), 1e-30)
    return mean, variance, axis, total


def vpl_cluster_origins(vpls, view_size: int, views: int, first_map: int, point_sets: int,
                        own_reflector_sigmas: float, slack: float = CLUSTER_PLANE_SLACK):
    """The splat's table of the VPL clusters' maps (GPU twin: vpl_clusters.comp.glsl, then
    vpl_cluster_sets.comp.glsl), one map per block of each of ``views`` views of ``view_size``²
    (``vpls``: the dict of passes.vpl_culling.scene_vpls, with each VPL's ``texel`` and ``view``).
    Returns (origins (M, 3), point set (M,), minimum distance (M,), half-spaces (M, 4), occupied (M,)
    bool), float64; an empty block has origin 0, EMPTY_CLUSTER_DISTANCE and half-space 0."""
    blocks = cluster_blocks(view_size)
    count = int(views) * blocks * blocks
    cluster = vpl_cluster_map(vpls["texel"], vpls["view"], view_size)
    mean, variance, axis, _ = cluster_statistics(vpls, cluster, count)
    occupied = np.bincount(cluster, minlength=count)[:count] > 0
    origins = np.where(occupied[:, None], shadow_origin(mean, variance, axis), 0.0)
    sigma = np.sqrt(np.maximum(variance, 0.0))
    distance = np.where(occupied, f64(own_reflector_sigmas) * sigma, EMPTY_CLUSTER_DISTANCE)
    planes = np.where(occupied[:, None], cluster_planes(vpls["position"], cluster, origins, axis, slack), 0.0)
    rank = np.cumsum(occupied) - occupied
    return origins, (int(first_map) + rank) % int(point_sets), distance, planes, occupied
