# SPDX-License-Identifier: GPL-3.0-or-later
"""Where VSGL visibility's error comes from (not a test): imperfect shadow maps against exact
visibility, per scene of the validation suite.

    .venv/bin/python benchmarks/visibility_diagnosis.py [--only NAME ...] [--stride S] [--material NAME]

On every S-th pixel (both ways) of the suite's 240x180 camera G-buffer, each VSGL lobe's light is
computed by the float64 reference shading (reference/vsgl_shading.shade, per term) and weighted by
three visibilities:

* none (visibility off);
* the GPU's imperfect shadow maps, read back and looked up by the float64 twin
  (reference/vsgl_shading.vsgl_visibility: the shader's lookup, tested bit-close to it);
* exact: the segment from the receiver to the map's shadow origin ray-cast against every triangle
  of the scene (brute force), hits nearer the origin than the own-reflector radius left out as the
  maps leave those points out; and the bare segment to the VSGL's mean (no push, nothing left out).

Their means over the pixels, against Cycles' on the same pixels, separate the maps' error (ISM
against exact) from the VSGL model's (exact against Cycles: positions as Gaussians' means, the
diffuse approximation). Prints one line per scene and configuration. ``--material``: only the
pixels of that material (e.g. "Glossy tiles", sun_courtyard's north wall, whose courtyard face is
in the sun's shadow).

A second line gives what the diffuse lobe's own-reflector side (reference/vsgl_shading
vsgl_reflector_side, which the shader no longer applies: pipeline.VSGL_OWN_REFLECTOR_SIGMAS) would
do: the maps times the side, the side alone, exact visibility times the side, and the light the
side would take from bent clusters (planarity, the diffuse lobe's mean direction length over a
flat cluster's, under BENT_PLANARITY: clusters across corners, whose cap-of-normals model the side
assumes convex) against flat ones. ``--map-stages``
rebuilds every map with the float64 twin (reference/ism.py splat, close_gaps, pull_push; the
largest difference to the GPU's maps is printed) and gives the maps' light without gap closing.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from validation_suite import sampled_pixels, scene_with_truth, suite  # noqa: E402
from energy_budget import segments_blocked  # noqa: E402
from build_validation_scenes import RESOLUTION  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.demo import log  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
#: Clusters whose planarity is under this are "bent" in the side's split (the second line).
BENT_PLANARITY = 0.8


def segment_visible(receivers, origin, triangles, exclude_radius, receiver_offset=1e-3):
    """(P,) 1 where no triangle crosses the segment from each receiver to ``origin`` (Möller–Trumbore),
    hits within ``exclude_radius`` of the origin and within ``receiver_offset`` of the receiver left out."""
    ends = np.broadcast_to(origin, receivers.shape)
    length = np.maximum(np.linalg.norm(ends - receivers, axis=-1), 1e-30)
    blocked = segments_blocked(receivers, ends, triangles, t_min=receiver_offset / length,
                               t_max=1.0 - exclude_radius / length)
    return (~blocked).astype(np.float64)


def exact_visibility(table, maps_per_vsgl, position, triangles, exclude_sigmas, pushed=True):
    """(P, N, 2) exact visibility of each lobe's shadow origin (reference.ism.shadow_origin of the
    position the maps use: the VSGL's diffuse lobe's with one map per VSGL, else the lobe's), or of
    that position itself (``pushed=False``)."""
    from vsgl_addon.reference.ism import shadow_origin

    count = len(table["diffuse_variance"])
    result = np.ones((len(position), count, 2))
    for lobe, name in enumerate(("diffuse", "specular")):
        at = "diffuse_" if maps_per_vsgl == 1 else f"{name}_"
        means = table[f"{at}mean"]
        if pushed:
            means = shadow_origin(means, table[f"{at}variance"], table[f"{name}_axis"])
        sigma = np.sqrt(np.maximum(table[f"{at}variance"], 0.0))
        for i in range(count):
            if lobe == 1 and maps_per_vsgl == 1:
                result[:, i, 1] = result[:, i, 0]
                continue
            result[:, i, lobe] = segment_visible(position, np.asarray(means[i], np.float64), triangles,
                                                 exclude_sigmas * sigma[i])
    return result


def reference_maps(atlas, table, maps, first_map, points, point_area, gaps=True):
    """(M, S, S) the table's maps rebuilt by the float64 twin (pipeline.build_visibility's origins,
    point sets and own-reflector distance), with or without gap closing."""
    from vsgl_addon.pipeline import POINT_SETS, VSGL_OWN_REFLECTOR_SIGMAS
    from vsgl_addon.reference import ism

    origins, sets, min_distance = ism.vsgl_map_origins(table, maps, first_map, POINT_SETS,
                                                       VSGL_OWN_REFLECTOR_SIGMAS)
    result = []
    for origin, index, near in zip(origins, sets, min_distance):
        depth = ism.splat(points.positions[index], origin, atlas.size, near, points.normals[index], point_area)
        result.append(ism.pull_push(ism.close_gaps(depth) if gaps else depth))
    return np.stack(result)


def diagnose(name, path, stride, settings_overrides, material=None, map_stages=False):
    from vsgl_addon.pipeline import POINT_SETS, VSGL_OWN_REFLECTOR_SIGMAS, build_visibility
    from vsgl_addon.reference.vsgl_shading import (FLAT_DIFFUSE_AXIS_LENGTH, diffuse_mode_for_kernel, shade,
                                                   vsgl_reflector_side, vsgl_visibility)
    from vsgl_addon.passes.vsgl_shading import ISM_MAX_RADIUS
    from vsgl_addon.scene_points import triangle_areas

    width, height = RESOLUTION
    saved, truth, description = scene_with_truth(name, path, width, height)
    settings = saved.overridden(visibility=True, **settings_overrides)
    triangles = np.asarray(description.geometry.positions, np.float64)
    bench = Bench(description, width, height)
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride,
                                                                      None if material is None else [material])
        vsgls, _ = bench.vsgls(settings)
        try:
            build_visibility(bench.scene_gpu, vsgls, settings)
            sums = {key: 0.0 for key in ("off", "ism", "exact", "exact_mean0", "maps", "side", "exact_side",
                                         "side_bent", "side_flat", "no_gaps")}
            over = under = map_error = 0.0
            first_map = 0
            if map_stages:
                points = bench.scene_gpu.scene_points(settings.ism_points, POINT_SETS, settings.seed)
                point_area = float(triangle_areas(triangles).sum()) / settings.ism_points
            for table, atlas in zip(vsgls.table_arrays(), vsgls.isms):
                table = {k: np.asarray(v, np.float64) for k, v in table.items()}
                maps = atlas.count // len(table["variance"])
                _, _, terms = shade(table, position, normal, view, rd, f0, alpha,
                                    diffuse_mode=diffuse_mode_for_kernel(settings.kernel), per_term=True)
                weight = (terms.sum(axis=3) @ LUMINANCE)  # (P, N, 2)
                depths = atlas.read()
                v_ism = vsgl_visibility(depths, maps, table, position, normal, ISM_MAX_RADIUS)
                v_maps = vsgl_visibility(depths, maps, table, position, normal, ISM_MAX_RADIUS, reflector_side=True)
                side = np.ones(v_ism.shape)
                side[:, :, 0] = vsgl_reflector_side(table["diffuse_mean"][None], table["diffuse_axis"][None],
                                                    table["diffuse_sharpness"][None], position[:, None])
                v_exact = exact_visibility(table, maps, position, triangles, VSGL_OWN_REFLECTOR_SIGMAS)
                v_exact0 = exact_visibility(table, maps, position, triangles, 0.0, pushed=False)
                sharpness = table["diffuse_sharpness"]
                bent = sharpness / (1.0 + sharpness) / FLAT_DIFFUSE_AXIS_LENGTH < BENT_PLANARITY  # (N,)
                taken = weight[:, :, 0] * v_ism[:, :, 0] * (1.0 - side[:, :, 0])  # (P, N)
                sums["off"] += weight.sum()
                sums["ism"] += (weight * v_ism).sum()
                sums["exact"] += (weight * v_exact).sum()
                sums["exact_mean0"] += (weight * v_exact0).sum()
                sums["maps"] += (weight * v_maps).sum()
                sums["side"] += (weight * side).sum()
                sums["exact_side"] += (weight * v_exact * side).sum()
                sums["side_bent"] += taken[:, bent].sum()
                sums["side_flat"] += taken[:, ~bent].sum()
                over += (weight * np.maximum(v_exact - v_ism, 0)).sum()
                under += (weight * np.maximum(v_ism - v_exact, 0)).sum()
                if map_stages:
                    rebuilt = reference_maps(atlas, table, maps, first_map, points, point_area)
                    # float32 rounding moves a point across a texel edge now and then (a silhouette's
                    # texel then holds the other surface): the share of texels that differ.
                    same = np.isclose(rebuilt, depths, rtol=1e-4, atol=0.0) | (np.isinf(rebuilt) & np.isinf(depths))
                    map_error = max(map_error, float(1.0 - same.mean()))
                    no_gaps = reference_maps(atlas, table, maps, first_map, points, point_area, gaps=False)
                    sums["no_gaps"] += (weight * vsgl_visibility(no_gaps, maps, table, position, normal,
                                                                 ISM_MAX_RADIUS)).sum()
                first_map += atlas.count
        finally:
            vsgls.free()
    finally:
        bench.free()
    cycles = float((truth["indirect"][pick] @ LUMINANCE).sum())
    line = (f"{name}{'' if material is None else f' ({material})'} {settings_overrides}: pixels {pick.sum()}, ours/Cycles off {sums['off'] / cycles:.3f}, "
            f"ISM {sums['ism'] / cycles:.3f}, exact (shadow origin, {VSGL_OWN_REFLECTOR_SIGMAS} sigma excluded) {sums['exact'] / cycles:.3f}, "
            f"exact (bare segment to the mean) {sums['exact_mean0'] / cycles:.3f}; ISM over-shadows "
            f"{over / sums['off']:.3f} and leaks {under / sums['off']:.3f} of the unshadowed light")
    log(line)
    split = (f"  with the own-reflector side: ISM x side {sums['maps'] / cycles:.3f}, the side alone {sums['side'] / cycles:.3f}, "
             f"exact x side {sums['exact_side'] / cycles:.3f}; the side would take {sums['side_bent'] / cycles:.3f} of Cycles' "
             f"light from bent clusters (planarity < {BENT_PLANARITY}), {sums['side_flat'] / cycles:.3f} from flat ones")
    if map_stages:
        split += (f"; maps without gap closing {sums['no_gaps'] / cycles:.3f} (float64 rebuild; its texels "
                  f"off the GPU's by more than 1e-4: {map_error:.2g} of them)")
    log(split)
    return sums, cycles


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["occluder", "cornell_box", "closed_room"])
    parser.add_argument("--stride", type=int, default=6)
    parser.add_argument("--vsgl-count", type=int, default=None)
    parser.add_argument("--ism-points", type=int, default=None)
    parser.add_argument("--material", default=None, help="only the pixels of this material")
    parser.add_argument("--map-stages", action="store_true",
                        help="rebuild the maps with the float64 twin, and without gap closing")
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    overrides = {name: value for name, value in (("vsgl_count", args.vsgl_count), ("ism_points", args.ism_points))
                 if value is not None}
    for name, path, _ in suite():
        if name in args.only:
            start = time.perf_counter()
            diagnose(name, path, args.stride, overrides, args.material, args.map_stages)
            log(f"  ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
