# SPDX-License-Identifier: GPL-3.0-or-later
"""Where and why the imperfect shadow maps hide more light than exact visibility from the same
shadow origin (not a test), per receiver and per VSGL.

    .venv/bin/python benchmarks/ism_over_occlusion.py [--only NAME ...] [--stride S] [--traced-sizes S ...]
        [--variants POINTS:SIZE ...] [--rebuilds MODE ...] [--tag TAG] [--results-dir DIR]

On every S-th pixel (both ways) of the suite's 240x180 camera G-buffer, each VSGL's light is the
float64 reference shading (reference/vsgl_shading.shade, per term, luminance, both lobes), weighted by:

* maps: the GPU's imperfect shadow maps with the scene's settings, looked up by the shader's
  float64 twin (reference/vsgl_shading.vsgl_visibility);
* exact: the segment from the receiver to the map's shadow origin ray-cast (hits within
  pipeline.VSGL_OWN_REFLECTOR_SIGMAS σ_v of the origin left out, as the maps leave those points out;
  visibility_diagnosis.exact_visibility);
* traced S: a map of side S whose every texel holds the exact first hit of the ray from the origin
  through its centre (past the own-reflector radius), looked up by the same twin (same bias, same
  filter): a perfect point set, so traced − exact is the octahedral projection's resolution, the
  lookup's bias and its filter footprint, and maps − traced (at the maps' side) the point set, its
  splat, the gap closing and pull-push;
* POINTS:SIZE variants: the GPU's maps rebuilt with that many points per map and that side;
* float64 MODE: the maps rebuilt by reference/ism.py's stages from the GPU's point sets with one
  stage changed (rebuilt_maps): "twin" as the GPU; "radius 0" single-texel splats; "disc S" each
  point an oriented disc of area S² times its share of the surface (disc_splat); "plane" the
  twin's squares at the point's tangent plane's depth (plane_splat); suffix " no gaps" without
  gap closing, " step gaps" / " texel gaps" with a stricter gap rule (close_gaps_rule), " plane
  gaps" with a gap also behind both sides' tangent planes (close_gaps_planes, the winning points'
  normals kept per texel: splat_normals).

The light each hides (Σ w·(v_exact − v), as a share of the light exact visibility keeps) is then
split by the receiver's material, its distance from the origin in σ_v, its incidence from the
origin, the VSGL's σ_v, and the origin's clearance (its nearest surface, in σ_v: the traced map's
least depth); and, for the point-set part, by what the maps hold at the receiver's texel against the
traced map (nearer by more than the bias: a surface in front that is not there; an empty texel
filled by pull-push), and by object: the receiver's, and the one holding the nearest depth in front
of the receiver among its 3 × 3 texels (blocking_objects). Writes
``benchmarks/results/ism_over_occlusion[_TAG].md`` (+ .json). Each table is one run; rel RMSE against
Cycles is noise-corrected (its two seeds), against exact it is per pixel over exact's mean.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from validation_suite import sampled_pixels, scene_with_truth, suite  # noqa: E402
from build_validation_scenes import RESOLUTION  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.demo import log  # noqa: E402
from visibility_diagnosis import exact_visibility  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def nearest_hits(origin, directions, triangles, t_min, chunk_rays=4096, chunk_triangles=64):
    """(R,) distance along each unit direction (R, 3) from ``origin`` to the nearest triangle hit
    past ``t_min`` (Möller–Trumbore); inf where none."""
    v0, e1, e2 = triangles[:, 0], triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    best = np.full(len(directions), np.inf)
    s = origin[None] - v0  # (T, 3)
    for r0 in range(0, len(directions), chunk_rays):
        dd = directions[r0:r0 + chunk_rays]
        nearest = np.full(len(dd), np.inf)
        for t0 in range(0, len(v0), chunk_triangles):
            a1, a2, st = e1[t0:t0 + chunk_triangles], e2[t0:t0 + chunk_triangles], s[t0:t0 + chunk_triangles]
            p = np.cross(dd[:, None, :], a2[None])
            det = np.einsum("rtk,tk->rt", p, a1)
            inv = 1.0 / np.where(np.abs(det) > 1e-14, det, np.inf)
            u = np.einsum("tk,rtk->rt", st, p) * inv
            q = np.cross(st, a1)  # (T, 3)
            v = np.einsum("rk,tk->rt", dd, q) * inv
            t = np.einsum("tk,tk->t", q, a2)[None] * inv
            ok = (u >= 0) & (v >= 0) & (u + v <= 1) & (t > t_min)
            nearest = np.minimum(nearest, np.where(ok, t, np.inf).min(axis=1))
        best[r0:r0 + chunk_rays] = nearest
    return best


def point_triangle_distance(points, triangles, chunk=256):
    """(K,) distance from each point (K, 3) to the nearest triangle (T, 3, 3) and (K,) its index."""
    best, which = np.full(len(points), np.inf), np.zeros(len(points), np.int64)
    for t0 in range(0, len(triangles), chunk):
        t = triangles[t0:t0 + chunk]
        a, b, c = t[:, 0], t[:, 1], t[:, 2]
        n = np.cross(b - a, c - a)
        n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
        d = np.einsum("ktj,tj->kt", points[:, None] - a[None], n)
        q = points[:, None] - d[..., None] * n[None]
        v0, v1, v2 = b - a, c - a, q - a[None]
        d00, d01, d11 = (v0 * v0).sum(-1), (v0 * v1).sum(-1), (v1 * v1).sum(-1)
        d20, d21 = (v2 * v0[None]).sum(-1), (v2 * v1[None]).sum(-1)
        den = np.maximum(d00 * d11 - d01 * d01, 1e-30)
        v, w = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
        inside = (v >= 0) & (w >= 0) & (v + w <= 1)

        def segment(x, y):
            e = y - x
            s = np.clip(((points[:, None] - x[None]) * e[None]).sum(-1) / np.maximum((e * e).sum(-1), 1e-30), 0, 1)
            return np.linalg.norm(points[:, None] - (x[None] + s[..., None] * e[None]), axis=-1)

        edge = np.minimum(np.minimum(segment(a, b), segment(b, c)), segment(c, a))
        distance = np.where(inside, np.abs(d), edge)
        k = distance.argmin(axis=1)
        here = distance[np.arange(len(points)), k]
        better = here < best
        best[better], which[better] = here[better], (t0 + k)[better]
    return best, which


def blocking_objects(depths, origins, position, normal, pairs, triangles, object_index, object_names):
    """For each (receiver, map) pair, the object of the nearest depth in front of the receiver among
    the 3 × 3 texels around its own (the bilinear filter's block lies inside them), "on" where the
    texel's point (origin + its centre direction × depth) lies within 1.5 texel footprints of that
    object's surface, "off" where it is nowhere near a surface; "none" where no texel is in front."""
    from vsgl_addon.reference import ism

    size = depths.shape[-1]
    centres = ism.texel_directions(size)
    p, m = pairs
    offsets, bias = ism.lookup_offsets(position[p] - origins[m], normal[p], size, 2.0)
    distance = np.linalg.norm(offsets, axis=-1)
    texel = ism.ism_texel(offsets, size)
    best = np.full(len(p), np.inf)
    best_row, best_column = np.zeros(len(p), np.int64), np.zeros(len(p), np.int64)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            column, row = ism.octahedral_wrap(texel[:, 0] + dx, texel[:, 1] + dy, size)
            stored = depths[m, row, column]
            nearer = (stored + bias < distance) & (stored < best)
            best = np.where(nearer, stored, best)
            best_row, best_column = np.where(nearer, row, best_row), np.where(nearer, column, best_column)
    found = np.isfinite(best)
    point = origins[m] + centres[best_row, best_column] * np.where(found, best, 0.0)[:, None]
    gap, index = point_triangle_distance(point, triangles)
    on = gap < 1.5 * best * np.sqrt(4.0 * np.pi) / size
    names = np.array([f"{object_names[object_index[i]]} {'on' if o else 'off'}" for i, o in zip(index, on)], object)
    names[~found] = "none"
    return names


def traced_maps(origins, min_distance, size, triangles):
    """(M, size, size) maps of the exact first hit through each texel centre (reference/ism.py's
    octahedral layout, [row, column])."""
    from vsgl_addon.reference.ism import texel_directions

    directions = texel_directions(size).reshape(-1, 3)
    return np.stack([nearest_hits(o, directions, triangles, near).reshape(size, size)
                     for o, near in zip(origins, min_distance)])


def lookup_texel_depth(depths, origins, position, normal):
    """(P, M) the depth each map holds at the texel of each receiver (as the lookup offsets it) and
    (P, M) the receiver's tested distance and bias (reference/ism.py lookup_offsets, the bilinear
    filter's two-texel footprint)."""
    from vsgl_addon.reference import ism

    size = depths.shape[-1]
    stored = np.empty((len(position), len(origins)))
    distance = np.empty_like(stored)
    bias = np.empty_like(stored)
    for m, origin in enumerate(origins):
        offsets, b = ism.lookup_offsets(position - origin, normal, size, 2.0)
        texel = ism.ism_texel(offsets, size)
        stored[:, m] = depths[m][texel[:, 1], texel[:, 0]]
        distance[:, m] = np.linalg.norm(offsets, axis=-1)
        bias[:, m] = b
    return stored, distance, bias


def disc_splat(points, normals, origin, size, min_distance, point_area, share):
    """A float64 splat variant (reference/ism.py splat's layout and square of splat_radius): each
    point a disc of area share² · point_area in its tangent plane, covering its own texel at its
    distance and the other texels of its square whose centre ray meets the disc, at that ray's
    distance to the plane (an oriented splat: the depth follows a grazing surface instead of
    standing at the point's own distance across the square)."""
    from vsgl_addon.reference import ism

    offsets = points - origin
    distance = np.linalg.norm(offsets, axis=-1)
    keep = np.isfinite(distance) & (distance > max(min_distance, 1e-300))
    offsets, distance, normals = offsets[keep], distance[keep], normals[keep]
    texel = ism.ism_texel(offsets, size)
    depth = np.full((size, size), ism.EMPTY)
    np.minimum.at(depth, (texel[:, 1], texel[:, 0]), distance)
    cos_theta = (normals * offsets).sum(axis=-1) / distance
    radius = ism.splat_radius(offsets, cos_theta, point_area, size)
    # The square wide enough for the disc seen face-on.
    reach = np.clip(np.ceil(math.sqrt(point_area / math.pi) * share / distance
                            / np.sqrt(ism.texel_solid_angle(offsets, size))), 0, ism.SPLAT_MAX_RADIUS)
    radius = np.maximum(radius, reach).astype(np.int64)
    centres = ism.texel_directions(size)
    disc2 = share * share * point_area / math.pi
    plane = (normals * offsets).sum(axis=-1)  # n · (p − o)
    for r in range(1, int(radius.max(initial=0)) + 1):
        here = radius >= r
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                if max(abs(dx), abs(dy)) != r:
                    continue
                column, row = ism.octahedral_wrap(texel[here, 0] + dx, texel[here, 1] + dy, size)
                d = centres[row, column]
                denominator = (normals[here] * d).sum(axis=-1)
                t = plane[here] / np.where(np.abs(denominator) > 1e-12, denominator, np.nan)
                hit = t[:, None] * d - offsets[here]
                inside = (t > 0) & ((hit * hit).sum(axis=-1) <= disc2)
                np.minimum.at(depth, (row[inside], column[inside]), t[inside])
    return depth


def plane_splat(points, normals, origin, size, min_distance, point_area):
    """A float64 splat variant: reference/ism.py splat's squares (splat_radius), each texel at the
    distance along its centre ray to the point's tangent plane instead of the point's own distance
    (the point's distance where the ray meets the plane behind the origin or beyond twice that)."""
    from vsgl_addon.reference import ism

    offsets = points - origin
    distance = np.linalg.norm(offsets, axis=-1)
    keep = np.isfinite(distance) & (distance > max(min_distance, 1e-300))
    offsets, distance, normals = offsets[keep], distance[keep], normals[keep]
    texel = ism.ism_texel(offsets, size)
    depth = np.full((size, size), ism.EMPTY)
    np.minimum.at(depth, (texel[:, 1], texel[:, 0]), distance)
    cos_theta = (normals * offsets).sum(axis=-1) / distance
    radius = ism.splat_radius(offsets, cos_theta, point_area, size)
    centres = ism.texel_directions(size)
    plane = (normals * offsets).sum(axis=-1)
    for r in range(1, int(radius.max(initial=0)) + 1):
        here = radius >= r
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                if max(abs(dx), abs(dy)) != r:
                    continue
                column, row = ism.octahedral_wrap(texel[here, 0] + dx, texel[here, 1] + dy, size)
                denominator = (normals[here] * centres[row, column]).sum(axis=-1)
                t = plane[here] / np.where(np.abs(denominator) > 1e-12, denominator, np.nan)
                t = np.where((t > 0) & (t <= 2.0 * distance[here]), t, distance[here])
                np.minimum.at(depth, (row, column), t)
    return depth


def close_gaps_rule(depth, rule):
    """reference/ism.py close_gaps (rule "old"), or with a further condition on each side of the
    gap within GAP_REACH: "step", a fall of more than GAP_MARGIN between consecutive texels holding
    depths (empty ones skipped; a hole's edge falls at once, a concave fold of one surface
    gradually); "texel", a depth k texels away nearer than (1 − GAP_MARGIN)^k times the texel's
    (a slope steeper than GAP_MARGIN per texel)."""
    from vsgl_addon.reference import ism

    if rule == "old":
        return ism.close_gaps(depth)
    size = depth.shape[0]
    rows, columns = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    best = np.full(depth.shape, ism.EMPTY)
    for dx, dy in ism.GAP_DIRECTIONS:
        sides, steps = [], []
        for sign in (-1, 1):
            nearest = np.full(depth.shape, ism.EMPTY)
            previous, stepped = depth, np.zeros(depth.shape, bool)
            for k in range(1, min(ism.GAP_REACH, size) + 1):
                column, row = ism.octahedral_wrap(columns + sign * k * dx, rows + sign * k * dy, size)
                here = depth[row, column]
                nearest = np.minimum(nearest, here)
                if rule == "texel":
                    stepped |= here < (1.0 - ism.GAP_MARGIN) ** k * depth
                else:
                    stepped |= here < (1.0 - ism.GAP_MARGIN) * previous
                previous = np.where(np.isfinite(here), here, previous)
            sides.append(nearest)
            steps.append(stepped)
        farther = np.maximum(sides[0], sides[1])
        gap = (farther < (1.0 - ism.GAP_MARGIN) * depth) & steps[0] & steps[1]
        best = np.minimum(best, np.where(gap, farther, ism.EMPTY))
    return np.minimum(depth, best)


def splat_normals(points, normals, origin, size, min_distance, point_area, depth, planes=False):
    """(size, size, 3) the normal of the point that won each texel of ``depth`` (reference/ism.py
    splat's squares, plane_splat's with ``planes``, or single texels with ``point_area`` 0), zero
    where none did."""
    from vsgl_addon.reference import ism

    offsets = points - origin
    distance = np.linalg.norm(offsets, axis=-1)
    keep = np.isfinite(distance) & (distance > max(min_distance, 1e-300))
    offsets, distance, normals = offsets[keep], distance[keep], normals[keep]
    texel = ism.ism_texel(offsets, size)
    radius = (ism.splat_radius(offsets, (normals * offsets).sum(-1) / distance, point_area, size)
              if point_area > 0.0 else np.zeros(len(offsets), np.int64))
    result = np.zeros((size, size, 3))
    for r in np.unique(radius):
        here = radius == r
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                column, row = ism.octahedral_wrap(texel[here, 0] + dx, texel[here, 1] + dy, size)
                value = distance[here]
                if planes and (dx or dy):
                    centre = ism.texel_directions(size)[row, column]
                    denominator = (normals[here] * centre).sum(axis=-1)
                    t = (normals[here] * offsets[here]).sum(-1) / np.where(np.abs(denominator) > 1e-12,
                                                                            denominator, np.nan)
                    value = np.where((t > 0) & (t <= 2.0 * value), t, value)
                won = depth[row, column] == value
                result[row[won], column[won]] = normals[here][won]
    return result


def close_gaps_planes(depth, normal):
    """reference/ism.py close_gaps, a gap also lying behind the tangent planes of both sides' nearest
    texels (their point: the texel centre's direction times the depth, with the winning point's
    normal), carried along its own direction by more than GAP_MARGIN: a slope or a concave fold
    continues its plane to the texel, a hole's far surface lies behind the near occluder's plane."""
    from vsgl_addon.reference import ism

    size = depth.shape[0]
    centres = ism.texel_directions(size)
    rows, columns = np.meshgrid(np.arange(size), np.arange(size), indexing="ij")
    best = np.full(depth.shape, ism.EMPTY)
    for dx, dy in ism.GAP_DIRECTIONS:
        sides, behind = [], []
        for sign in (-1, 1):
            nearest = np.full(depth.shape, ism.EMPTY)
            plane = np.zeros(depth.shape)
            for k in range(1, min(ism.GAP_REACH, size) + 1):
                column, row = ism.octahedral_wrap(columns + sign * k * dx, rows + sign * k * dy, size)
                here = depth[row, column]
                nearer = here < nearest
                nearest = np.where(nearer, here, nearest)
                n = normal[row, column]
                point = centres[row, column] * np.where(np.isfinite(here), here, 0.0)[..., None]
                denominator = (n * centres).sum(-1)
                reach = (n * point).sum(-1) / np.where(np.abs(denominator) > 1e-6, denominator, np.nan)
                # No plane (an empty texel, a ray along or away from it): the plane does not decide.
                reach = np.where(np.isfinite(reach) & (reach > 0) & (np.abs(n).sum(-1) > 0), reach, 0.0)
                plane = np.where(nearer, reach, plane)
            sides.append(nearest)
            behind.append(depth * (1.0 - ism.GAP_MARGIN) > plane)
        farther = np.maximum(sides[0], sides[1])
        gap = (farther < (1.0 - ism.GAP_MARGIN) * depth) & behind[0] & behind[1]
        best = np.minimum(best, np.where(gap, farther, ism.EMPTY))
    return np.minimum(depth, best)


def rebuilt_maps(points, origins, sets, min_distance, size, point_area, mode):
    """(M, size, size) the maps rebuilt in float64: "twin" (reference/ism.py splat, as the GPU),
    "share S" its splats with SPLAT_SHARE S, "radius 0" (single-texel splats), "disc S" (disc_splat of share S), "plane" (plane_splat); then
    gap closing (close_gaps_rule: suffix " step gaps" or " texel gaps"; close_gaps_planes: " plane
    gaps"; none with " no gaps"),
    pull-push."""
    from vsgl_addon.reference import ism

    rule = "old"
    for suffix, value in ((" no gaps", None), (" step gaps", "step"), (" texel gaps", "texel"),
                          (" plane gaps", "plane")):
        if mode.endswith(suffix):
            rule, mode = value, mode.removesuffix(suffix)
    result = []
    for origin, index, near in zip(origins, sets, min_distance):
        p, n = np.asarray(points.positions[index], np.float64), np.asarray(points.normals[index], np.float64)
        if mode == "twin":
            depth = ism.splat(p, origin, size, near, n, point_area)
        elif mode.startswith("share "):
            saved_share, ism.SPLAT_SHARE = ism.SPLAT_SHARE, float(mode.split()[1])
            try:
                depth = ism.splat(p, origin, size, near, n, point_area)
            finally:
                ism.SPLAT_SHARE = saved_share
        elif mode == "plane":
            depth = plane_splat(p, n, origin, size, near, point_area)
        elif mode == "radius 0":
            depth = ism.splat(p, origin, size, near)
        else:
            depth = disc_splat(p, n, origin, size, near, point_area, float(mode.split()[1]))
        if rule == "plane":
            if mode not in ("twin", "radius 0", "plane"):
                raise ValueError("plane gaps need the twin's, plane_splat's or single-texel splats")
            normal = splat_normals(p, n, origin, size, near, 0.0 if mode == "radius 0" else point_area, depth,
                                   planes=mode == "plane")
            depth = close_gaps_planes(depth, normal)
        elif rule is not None:
            depth = close_gaps_rule(depth, rule)
        result.append(ism.pull_push(depth))
    return np.stack(result)


BINS = {
    "distance / sigma_v": (0.0, 1.0, 2.0, 4.0, 8.0, np.inf),
    "cos incidence": (0.0, 0.2, 0.5, 0.8, 1.01),
    "sigma_v (m)": (0.0, 0.1, 0.2, 0.4, 0.8, np.inf),
    "origin clearance / sigma_v": (0.0, 0.5, 1.0, 2.0, np.inf),
}


def split(values, loss, bins):
    """Σ loss per bin of values (loss and values broadcast to (P, N))."""
    index = np.digitize(values, bins[1:-1])
    return [float(loss[index == k].sum()) for k in range(len(bins) - 1)]


def run_scene(name, path, stride, traced_sizes, variants, rebuilds=()):
    from vsgl_addon.pipeline import POINT_SETS, VSGL_OWN_REFLECTOR_SIGMAS, build_visibility
    from vsgl_addon.reference import ism
    from vsgl_addon.reference.vsgl_shading import diffuse_mode_for_kernel, shade, vsgl_visibility
    from vsgl_addon.passes.vsgl_shading import ISM_MAX_RADIUS
    from vsgl_addon.scene_points import triangle_areas

    width, height = RESOLUTION
    saved, truth, description = scene_with_truth(name, path, width, height)
    settings = saved.overridden(visibility=True)
    triangles = np.asarray(description.geometry.positions, np.float64)
    bench = Bench(description, width, height)
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride)
        material = bench.material_index[pick]
        vsgls, _ = bench.vsgls(settings)
        try:
            build_visibility(bench.scene_gpu, vsgls, settings)
            if rebuilds:
                points = bench.scene_gpu.scene_points(settings.ism_points, POINT_SETS, settings.seed)
                point_area = float(triangle_areas(triangles).sum()) / settings.ism_points
            first_map = 0
            per_table = []
            for table, atlas in zip(vsgls.table_arrays(), vsgls.isms):
                table = {k: np.asarray(v, np.float64) for k, v in table.items()}
                maps = atlas.count // len(table["variance"])
                if maps != 1:
                    raise SystemExit("one map per VSGL expected (pipeline.MAPS_PER_VSGL)")
                _, _, terms = shade(table, position, normal, view, rd, f0, alpha,
                                    diffuse_mode=diffuse_mode_for_kernel(settings.kernel), per_term=True)
                weight = (terms.sum(axis=3) @ LUMINANCE).sum(axis=2)  # (P, N): both lobes, one map
                depths = atlas.read()
                origins, sets, min_distance = ism.vsgl_map_origins(table, 1, first_map, POINT_SETS,
                                                                   VSGL_OWN_REFLECTOR_SIGMAS)
                first_map += atlas.count
                v = {"maps": vsgl_visibility(depths, 1, table, position, normal, ISM_MAX_RADIUS)[:, :, 0],
                     "exact": exact_visibility(table, 1, position, triangles, VSGL_OWN_REFLECTOR_SIGMAS)[:, :, 0]}
                traced = {}
                for size in traced_sizes:
                    traced[size] = traced_maps(origins, min_distance, size, triangles)
                    v[f"traced {size}"] = vsgl_visibility(traced[size], 1, table, position, normal,
                                                          ISM_MAX_RADIUS)[:, :, 0]
                for mode in rebuilds:
                    rebuilt = rebuilt_maps(points, origins, sets, min_distance, depths.shape[-1], point_area, mode)
                    v[f"float64 {mode}"] = vsgl_visibility(rebuilt, 1, table, position, normal, ISM_MAX_RADIUS)[:, :, 0]
                sigma = np.sqrt(np.maximum(table["diffuse_variance"], 0.0))
                offsets = position[:, None] - origins[None]
                dist = np.linalg.norm(offsets, axis=-1)
                cos_inc = np.abs((normal[:, None] * -offsets).sum(-1)) / np.maximum(dist, 1e-30)
                finest = traced[max(traced_sizes)]
                clearance = finest.reshape(len(origins), -1).min(axis=1)
                stored, tested, bias = lookup_texel_depth(depths, origins, position, normal)
                same = traced.get(depths.shape[-1])
                stored_traced = (lookup_texel_depth(same, origins, position, normal)[0]
                                 if same is not None else np.full_like(stored, np.nan))
                darker = np.nonzero(weight * (v.get(f"traced {depths.shape[-1]}", v["exact"]) - v["maps"]) > 0)
                blockers = blocking_objects(depths, origins, position, normal, darker, triangles,
                                            description.geometry.object_index, description.object_names)
                _, receiver_triangle = point_triangle_distance(position, triangles)
                receiver_object = np.array(description.object_names, object)[
                    description.geometry.object_index[receiver_triangle]]
                lost = weight[darker] * (v.get(f"traced {depths.shape[-1]}", v["exact"]) - v["maps"])[darker]
                by_blocker = {}
                for key, label in zip(("blocker", "receiver"), (blockers, receiver_object[darker[0]])):
                    for name_, value in zip(label, lost):
                        by_blocker.setdefault(key, {}).setdefault(name_, 0.0)
                        by_blocker[key][name_] += float(value)
                per_table.append(dict(weight=weight, v=v, sigma=sigma, by_blocker=by_blocker, dist=dist, cos=cos_inc,
                                      clearance=clearance, stored=stored, tested=tested, bias=bias,
                                      stored_traced=stored_traced, depths=depths, size=depths.shape[-1]))
            for points, size in variants:
                for atlas in vsgls.isms:
                    atlas.free()
                vsgls.isms.clear()
                build_visibility(bench.scene_gpu, vsgls, settings.overridden(ism_points=points, ism_size=size))
                for entry, table, atlas in zip(per_table, vsgls.table_arrays(), vsgls.isms):
                    table = {k: np.asarray(v, np.float64) for k, v in table.items()}
                    entry["v"][f"{points} points, {atlas.size}²"] = vsgl_visibility(
                        atlas.read(), 1, table, position, normal, ISM_MAX_RADIUS)[:, :, 0]
        finally:
            vsgls.free()
        names = bench.materials
    finally:
        bench.free()
    cycles = float((truth["indirect"][pick].astype(np.float64) @ LUMINANCE).sum())

    def cat(key):
        return np.concatenate([e[key] for e in per_table], axis=1)

    weight = cat("weight")
    v = {key: np.concatenate([e["v"][key] for e in per_table], axis=1) for key in per_table[0]["v"]}
    sigma = np.concatenate([e["sigma"] for e in per_table])
    clearance = np.concatenate([e["clearance"] for e in per_table])
    dist, cos_inc = cat("dist"), cat("cos")
    stored, tested, bias, stored_traced = cat("stored"), cat("tested"), cat("bias"), cat("stored_traced")
    kept = float((weight * v["exact"]).sum())
    a = (truth["diffuse_a"] + truth["glossy_a"])[pick].astype(np.float64) @ LUMINANCE
    b = (truth["diffuse_b"] + truth["glossy_b"])[pick].astype(np.float64) @ LUMINANCE
    per_pixel = {key: (weight * value).sum(axis=1) for key, value in v.items()}
    truth_mean = cycles / len(a)
    exact_pixels = per_pixel["exact"]
    result = {"pixels": int(pick.sum()), "vsgls": int(weight.shape[1]), "map_size": per_table[0]["size"],
              "ism_points": settings.ism_points, "cycles": cycles, "off": float(weight.sum()) / cycles,
              "ratios": {key: float((weight * value).sum()) / cycles for key, value in v.items()}}
    result["rel_rmse"] = {key: math.sqrt(max(float(np.mean((x - a) * (x - b))), 0.0)) / truth_mean
                          for key, x in per_pixel.items()}
    result["rel_rmse_exact"] = {key: float(np.sqrt(np.mean((x - exact_pixels) ** 2)) / exact_pixels.mean())
                                for key, x in per_pixel.items()}
    # Lost light against exact, as a share of what exact keeps (negative: the variant leaks).
    result["lost"] = {key: float((weight * (v["exact"] - value)).sum()) / kept for key, value in v.items()}
    base_traced = f"traced {result['map_size']}"
    parts = {"maps − exact": v["exact"] - v["maps"]}
    if base_traced in v:
        parts["traced − exact (projection, bias, filter)"] = v["exact"] - v[base_traced]
        parts["maps − traced (points, splat, pull-push)"] = v[base_traced] - v["maps"]
    breakdown = {}
    for part, difference in parts.items():
        loss = weight * difference
        rows = {"all": float(loss.sum()) / kept}
        for index in np.unique(material):
            here = material == index
            label = names[index] if 0 <= index < len(names) else str(index)
            rows[f"material {label}"] = float(loss[here].sum()) / kept
        per_bins = {}
        for label, bins in BINS.items():
            values = {"distance / sigma_v": dist / np.maximum(sigma, 1e-30)[None],
                      "cos incidence": cos_inc,
                      "sigma_v (m)": np.broadcast_to(sigma[None], loss.shape),
                      "origin clearance / sigma_v": np.broadcast_to((clearance / np.maximum(sigma, 1e-30))[None],
                                                                    loss.shape)}[label]
            per_bins[label] = [x / kept for x in split(values, loss, bins)]
        breakdown[part] = {"rows": rows, "bins": per_bins}
    result["breakdown"] = breakdown
    blockers = {}
    for entry in per_table:
        for key, values in entry["by_blocker"].items():
            for label, value in values.items():
                blockers.setdefault(key, {}).setdefault(label, 0.0)
                blockers[key][label] += value / kept
    result["darkened_by"] = {key: dict(sorted(values.items(), key=lambda kv: -kv[1])) for key, values in blockers.items()}
    # What the maps hold at the receiver's own texel, over the pairs the point set darkens.
    if base_traced in v:
        darker = weight * np.maximum(v[base_traced] - v["maps"], 0.0)
        front = stored + bias < tested  # the maps' own texel has something in front
        front_traced = stored_traced + bias < tested
        classes = {
            "maps' texel nearer, traced texel not": front & ~front_traced,
            "both texels nearer (the filter's other texels differ)": front & front_traced,
            "maps' texel not nearer (a filter neighbour is)": ~front,
        }
        total = float(darker.sum())
        result["point_classes"] = {label: float(darker[mask].sum()) / max(total, 1e-300) for label, mask in classes.items()}
        nearer = front & ~front_traced
        ratio = np.where(nearer, stored / np.maximum(stored_traced, 1e-30), np.nan)
        ratio_bins = (0.0, 0.25, 0.5, 0.75, 0.9, 1.0, np.inf)
        result["nearer_ratio_bins"] = {"bins": list(ratio_bins[:-1]),
                                       "share": [float(darker[nearer & (np.digitize(ratio, ratio_bins[1:-1]) == k)].sum())
                                                 / max(total, 1e-300) for k in range(len(ratio_bins) - 1)]}
    log(f"{name}: " + ", ".join(f"{k} {x:.3f}" for k, x in result["ratios"].items()))
    return result


def markdown(results, argv_text):
    lines = ["# Where the shadow maps hide more light than exact visibility", "",
             "The module documentation of `benchmarks/ism_over_occlusion.py` defines the rows.", "",
             f"`.venv/bin/python benchmarks/ism_over_occlusion.py {argv_text}`", ""]
    for name, r in results.items():
        lines += [f"## {name} ({r['pixels']} px, {r['vsgls']} VSGLs, maps {r['map_size']}², "
                  f"{r['ism_points']} points per map)", "",
                  "| visibility | mean / Cycles | rel RMSE (Cycles, noise-corrected) | rel RMSE against exact "
                  "| light lost against exact (share of exact's) |", "|---|---|---|---|---|",
                  f"| off | {r['off']:.3f} | | | |"]
        lines += [f"| {key} | {ratio:.3f} | {r['rel_rmse'][key]:.3f} | {r['rel_rmse_exact'][key]:.3f} "
                  f"| {r['lost'][key]:+.3f} |" for key, ratio in r["ratios"].items()]
        for part, b in r["breakdown"].items():
            lines += ["", f"**{part}**, light lost as a share of exact's: all {b['rows']['all']:+.3f}; "
                      + ", ".join(f"{k} {x:+.3f}" for k, x in b["rows"].items() if k != "all")]
            for label, shares in b["bins"].items():
                edges = BINS[label]
                lines.append(f"- by {label}: " + ", ".join(
                    f"[{edges[k]:g}, {edges[k + 1]:g}) {x:+.3f}" for k, x in enumerate(shares)))
        if "point_classes" in r:
            lines += ["", "Pairs the point set darkens (traced → maps), their lost light by what the maps' "
                      "texel at the receiver holds: " + "; ".join(f"{k} {x:.0%}" for k, x in r["point_classes"].items())
                      + ". Of the first class, by the maps' depth over the traced depth: "
                      + ", ".join(f"≥ {b:g}: {x:.0%}" for b, x in zip(r["nearer_ratio_bins"]["bins"],
                                                                     r["nearer_ratio_bins"]["share"])) + "."]
        for key, text in (("receiver", "the receiver's object"),
                          ("blocker", "the object holding the nearest depth in front among the receiver's 3 × 3 "
                                      "texels (on: that texel's point within 1.5 texels of its surface; off: "
                                      "nowhere near one; none: no texel in front, the filter's weights)")):
            if key in r.get("darkened_by", {}):
                lines += ["", f"Light the point set hides (traced → maps, share of exact's), by {text}: "
                          + ", ".join(f"{label} {x:.3f}" for label, x in r["darkened_by"][key].items() if x >= 0.0005) + "."]
        lines.append("")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["many_lights"])
    parser.add_argument("--stride", type=int, default=10)
    parser.add_argument("--traced-sizes", type=int, nargs="+", default=[64, 256])
    parser.add_argument("--variants", nargs="*", default=["16384:64", "4096:256", "16384:256"],
                        help="POINTS:SIZE of the GPU's maps rebuilt")
    parser.add_argument("--rebuilds", nargs="*", default=["twin", "radius 0", "disc 0.7071", "disc 1"],
                        help="float64 rebuilds of the maps (rebuilt_maps): twin, 'radius 0', 'disc SHARE', plane, "
                             "each optionally with ' no gaps', ' step gaps' or ' texel gaps'")
    parser.add_argument("--results-dir", type=Path, default=REPO / "benchmarks" / "results")
    parser.add_argument("--tag", default="", help="suffix of the results' file names")
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    variants = [tuple(int(x) for x in text.split(":")) for text in args.variants]
    results = {}
    for name, path, _ in suite():
        if name in args.only:
            start = time.perf_counter()
            results[name] = run_scene(name, path, args.stride, args.traced_sizes, variants, args.rebuilds)
            log(f"  ({time.perf_counter() - start:.0f} s)")
    argv_text = (f"--only {' '.join(args.only)} --stride {args.stride} --traced-sizes "
                 f"{' '.join(map(str, args.traced_sizes))} --variants {' '.join(args.variants)}"
                 + " --rebuilds" + "".join(f" '{mode}'" for mode in args.rebuilds)
                 + (f" --tag {args.tag}" if args.tag else ""))
    stem = "ism_over_occlusion" + (f"_{args.tag}" if args.tag else "")
    args.results_dir.mkdir(parents=True, exist_ok=True)
    text = markdown(results, argv_text)
    (args.results_dir / f"{stem}.md").write_text(text)
    (args.results_dir / f"{stem}.json").write_text(json.dumps({"command": argv_text, "results": results}, indent=1))
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
