# SPDX-License-Identifier: GPL-3.0-or-later
"""The scene's surfaces as points, for imperfect shadow maps (Ritschel et al. 2008, cited by 000 §5
for VSGL visibility): each VSGL's shadow map is splatted from a small set of surface points instead
of rasterizing the scene once per VSGL.

``scene_point_sets(geometry, points_per_set, set_count, seed)`` draws ``set_count`` independent
sets of ``points_per_set`` points each. Every set is area-weighted and stratified on its own: the
k-th point of a set takes the triangle where the cumulative area crosses (k + ξ_k)/P of the
total, so each set covers the whole scene evenly (a triangle holding a fraction a of the area gets
a·P ± 2 points of every set), and a VSGL's ISM, which splats one set, sees every surface. Different
ISMs take different sets (``set_index``), so their holes fall in different places, as in Ritschel
et al., and the average over many VSGLs is smoother than any one map.

Deterministic: the same geometry and seed give the same points, so a static scene does not flicker;
a point's jitter comes from the seed alone, not from the frame. Pure numpy, no bpy and no GPU.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Fewest points per set and most sets: an ISM needs at least one point, and the sets are indexed by
#: a VSGL's index in a table of at most 16384.
POINTS_PER_SET_RANGE = (1, 1 << 20)
SET_COUNT_RANGE = (1, 16384)


@dataclass(frozen=True)
class ScenePoints:
    """(S, P, 3) float32 positions and unit normals of S sets of P points, and the triangle of each."""

    positions: np.ndarray
    normals: np.ndarray
    triangle: np.ndarray  # (S, P) int64, index into Geometry.positions

    @property
    def set_count(self) -> int:
        return int(self.positions.shape[0])

    @property
    def points_per_set(self) -> int:
        return int(self.positions.shape[1])


def triangle_areas(positions: np.ndarray) -> np.ndarray:
    """(T,) float64 areas of (T, 3, 3) triangles (0 for degenerate or non-finite ones)."""
    p = np.asarray(positions, np.float64)
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=-1)
    return np.where(np.isfinite(area), area, 0.0)


def set_index(ism_index, set_count: int):
    """The point set an ISM splats: ISM i takes set i mod S."""
    return np.asarray(ism_index) % set_count


def scene_point_sets(geometry, points_per_set: int, set_count: int, seed: int = 0) -> ScenePoints:
    """``set_count`` area-weighted, stratified sets of ``points_per_set`` surface points each (see
    the module documentation). A scene without area gives points at the origin with normal +Z, so
    the ISMs it feeds hold nothing nearer than the points."""
    if not POINTS_PER_SET_RANGE[0] <= points_per_set <= POINTS_PER_SET_RANGE[1]:
        raise ValueError(f"points per set must be in {POINTS_PER_SET_RANGE}, got {points_per_set}")
    if not SET_COUNT_RANGE[0] <= set_count <= SET_COUNT_RANGE[1]:
        raise ValueError(f"set count must be in {SET_COUNT_RANGE}, got {set_count}")
    shape = (set_count, points_per_set)
    corners = np.asarray(geometry.positions, np.float64)
    areas = triangle_areas(corners) if len(corners) else np.zeros(0)
    total = areas.sum()
    if not total > 0.0:
        zeros = np.zeros((*shape, 3), np.float32)
        normals = np.broadcast_to(np.array([0.0, 0.0, 1.0], np.float32), (*shape, 3)).copy()
        return ScenePoints(zeros, normals, np.full(shape, -1, np.int64))
    rng = np.random.default_rng([int(seed), points_per_set, set_count])
    # Stratified over the cumulative area: one uniform sample in each 1/P stratum of every set.
    strata = (np.arange(points_per_set)[None, :] + rng.random(shape)) / points_per_set
    cumulative = np.cumsum(areas) / total
    # Exactly 1 from the last triangle with area on, so rounding never picks a zero-area one.
    cumulative[np.flatnonzero(areas > 0.0)[-1]:] = 1.0
    triangle = np.searchsorted(cumulative, strata, side="right")
    # Uniform on the triangle: the square-root warp of two uniforms to barycentrics.
    u, v = rng.random(shape), rng.random(shape)
    root = np.sqrt(u)
    b0, b1, b2 = 1.0 - root, root * (1.0 - v), root * v
    # Per triangle first (thousands), then gathered per point (hundreds of thousands): the same floats.
    positions = (b0[..., None] * corners[:, 0, :][triangle] + b1[..., None] * corners[:, 1, :][triangle]
                 + b2[..., None] * corners[:, 2, :][triangle])
    face = np.cross(corners[:, 1, :] - corners[:, 0, :], corners[:, 2, :] - corners[:, 0, :])
    normals = (face / np.maximum(np.linalg.norm(face, axis=-1, keepdims=True), 1e-300)).astype(np.float32)
    return ScenePoints(positions.astype(np.float32), normals[triangle], triangle.astype(np.int64))


#: Point sets kept between scene uploads (most recent last): a frame re-uploads the scene, but
#: drawing the sets again (0.4 s for 64 × 4096 points here) would cost more than the maps.
_CACHE: dict = {}
CACHE_ENTRIES = 4


def point_sets_key(geometry, points_per_set: int, set_count: int, seed: int = 0) -> tuple:
    """What identifies a :func:`scene_point_sets` draw: the triangles (their bytes' hash), the
    counts and the seed."""
    import hashlib

    corners = np.ascontiguousarray(np.asarray(geometry.positions, np.float64))
    return (hashlib.blake2b(corners.tobytes(), digest_size=16).digest(), corners.shape,
            int(points_per_set), int(set_count), int(seed))


def cached_scene_point_sets(geometry, points_per_set: int, set_count: int, seed: int = 0) -> ScenePoints:
    """:func:`scene_point_sets`, kept for the same triangles (their bytes' hash), counts and seed."""
    key = point_sets_key(geometry, points_per_set, set_count, seed)
    points = _CACHE.pop(key, None)
    if points is None:
        points = scene_point_sets(geometry, points_per_set, set_count, seed)
    _CACHE[key] = points
    while len(_CACHE) > CACHE_ENTRIES:
        _CACHE.pop(next(iter(_CACHE)))
    return points
