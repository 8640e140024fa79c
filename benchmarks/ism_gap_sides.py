# SPDX-License-Identifier: GPL-3.0-or-later
"""Non-sun maps that keep their surfaces, rebuilt in float64 (not a test): which splat and gap rule
gives back the light the point maps hide without letting it through the occluders.

    .venv/bin/python benchmarks/ism_gap_sides.py [--only NAME ...] [--stride S] [--variants P:R:G:U ...] [--tag TAG]

Per scene (one RSM view, the scene's settings, visibility on), on every S-th pixel of the suite's
240x180 camera G-buffer, each VSGL's light is the float64 reference shading (reference/vsgl_shading
.shade, both lobes, luminance) times its visibility from: *gpu*, the GPU's maps; *exact*, the segment
to the shadow origin ray-cast (visibility_diagnosis.exact_visibility); and per variant P:R:G:U the
maps of the tables whose maps do not keep their surfaces rebuilt by reference/ism.py from the GPU's
point sets: splat ``plane_depth`` P (0: the point's distance), radius cap R, close_gaps
``continued`` G (0/1; −1 no gap closing) with a side whose plane is unknown taken as U (plane_continued_unknown), then pull-push; the lookup is the
slope-scaled depth bias (``surfaces`` False). Tables whose lookups take the normal offset (sun lights) keep
the GPU's maps. Per scene and per material: Σ light / Cycles' there; rel RMSE against Cycles is
noise-corrected (its two seeds) over the subset. Writes ``benchmarks/results/ism_gap_sides[_TAG].md``
(+ .json).
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


def plane_continued_unknown(unknown_sides):
    """reference.ism._plane_continued where a side's plane is unknown: U = 0 as the reference (the
    texel is no gap); 1, the side's nearest depth stands where the texel beyond it is empty or the
    plane turns away; 2, also where the texel beyond lies more than GAP_MARGIN off the side's nearest
    depth (another surface: the two texels give no plane)."""
    from vsgl_addon.reference import ism

    def continued(depth, scale, columns, rows, dx, dy, at, size):
        column, row = ism.octahedral_wrap(columns + at * dx, rows + at * dy, size)
        near_w = scale[row, column] / depth[row, column]
        column, row = ism.octahedral_wrap(columns + (at + 1) * dx, rows + (at + 1) * dy, size)
        beyond_w = scale[row, column] / depth[row, column]
        w = near_w + at * (near_w - beyond_w)
        known = (w > 0.0) & (beyond_w > 0.0) & (near_w > 0.0)
        if unknown_sides >= 2:
            known &= np.abs(near_w - beyond_w) <= ism.GAP_MARGIN * near_w
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(known, scale / np.where(known, w, 1.0), 0.0 if unknown_sides else ism.EMPTY)

    return continued


def rebuild(points, origins, sets, near, size, point_area, variant):
    from vsgl_addon.reference import ism

    plane, radius, continued, unknown = variant
    saved = ism._plane_continued
    if unknown:
        ism._plane_continued = plane_continued_unknown(unknown)
    try:
        maps = []
        for origin, index, dist in zip(origins, sets, near):
            depth = ism.splat(points.positions[index], origin, size, dist, points.normals[index], point_area,
                              plane_depth=plane, max_radius=radius)
            maps.append(ism.pull_push(depth if continued < 0 else ism.close_gaps(depth, bool(continued))))
    finally:
        ism._plane_continued = saved
    return np.stack(maps)


def parse(text):
    p, r, g, u = text.split(":")
    return float(p), int(r), int(g), int(u)


def run_scene(name, path, stride, variants):
    from vsgl_addon.passes.vsgl_shading import ISM_MAX_RADIUS
    from vsgl_addon.pipeline import POINT_SETS, VSGL_OWN_REFLECTOR_SIGMAS, build_visibility
    from vsgl_addon.reference import ism
    from vsgl_addon.reference.vsgl_shading import diffuse_mode_for_kernel, shade, vsgl_visibility
    from vsgl_addon.scene_points import triangle_areas

    width, height = RESOLUTION
    saved, truth, description = scene_with_truth(name, path, width, height)
    settings = saved.overridden(visibility=True)
    triangles = np.asarray(description.geometry.positions, np.float64)
    bench = Bench(description, width, height)
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride)
        material = bench.material_index[pick]
        names = bench.materials
        vsgls, _ = bench.vsgls(settings)
        try:
            build_visibility(bench.scene_gpu, vsgls, settings)
            tables = [{k: np.asarray(v, np.float64) for k, v in t.items()} for t in vsgls.table_arrays()]
            atlases = [(atlas.count, atlas.size, atlas.read(), atlas.surfaces, atlas.normal_offset) for atlas in vsgls.isms]
        finally:
            vsgls.free()
        points = bench.scene_gpu.scene_points(settings.ism_points, POINT_SETS, settings.seed)
        point_area = float(triangle_areas(triangles).sum()) / settings.ism_points
    finally:
        bench.free()
    light = {}
    first_map = 0
    for table, (count, size, depths, surfaces, offset) in zip(tables, atlases):
        maps = count // len(table["diffuse_variance"])
        _, _, terms = shade(table, position, normal, view, rd, f0, alpha,
                            diffuse_mode=diffuse_mode_for_kernel(settings.kernel), per_term=True)
        weight = terms.sum(axis=3) @ LUMINANCE  # (P, N, 2)
        origins, sets, near = ism.vsgl_map_origins(table, maps, first_map, POINT_SETS, VSGL_OWN_REFLECTOR_SIGMAS)
        first_map += count
        v = {"off": np.ones_like(weight),
             "gpu": vsgl_visibility(depths, maps, table, position, normal, ISM_MAX_RADIUS, surfaces=offset),
             "exact": exact_visibility(table, maps, position, triangles, VSGL_OWN_REFLECTOR_SIGMAS)}
        for text in variants:
            rebuilt = depths if offset else rebuild(points, origins, sets, near, size, point_area, parse(text))
            v[text] = vsgl_visibility(rebuilt, maps, table, position, normal, ISM_MAX_RADIUS, surfaces=offset)
        for key, value in v.items():
            light[key] = light.get(key, 0.0) + (weight * value).sum(axis=(1, 2))
    cycles = truth["indirect"][pick].astype(np.float64) @ LUMINANCE
    a = (truth["diffuse_a"] + truth["glossy_a"])[pick].astype(np.float64) @ LUMINANCE
    b = (truth["diffuse_b"] + truth["glossy_b"])[pick].astype(np.float64) @ LUMINANCE
    result = {"pixels": int(pick.sum()), "ratio": {}, "rel_rmse": {}, "materials": {}}
    for key, x in light.items():
        result["ratio"][key] = float(x.sum() / cycles.sum())
        result["rel_rmse"][key] = math.sqrt(max(float(np.mean((x - a) * (x - b))), 0.0)) / float(cycles.mean())
        for index in np.unique(material):
            here = material == index
            label = names[index] if 0 <= index < len(names) else str(index)
            result["materials"].setdefault(label, {})[key] = float(x[here].sum() / max(cycles[here].sum(), 1e-300))
    log(f"{name}: " + ", ".join(f"{k} {result['ratio'][k]:.3f}/{result['rel_rmse'][k]:.3f}" for k in light))
    return result


def markdown(results, argv_text, variants):
    keys = ["off", "gpu", "exact", *variants]
    lines = ["# Non-sun maps that keep their surfaces: splat and gap sides, float64 rebuilds", "",
             f"`{argv_text}`", "",
             "The module documentation of `benchmarks/ism_gap_sides.py` defines every figure. Variant "
             "P:R:G:U = splat plane depth, radius cap, continued gap sides, unknown sides "
             "(plane_continued_unknown); 0:3:0:0 is the point maps (the GPU's before SURFACE_LIGHT_TYPES took every light), 1:8:1:0 the maps that keep their surfaces. Each cell: "
             "Σ light / Cycles, noise-corrected rel RMSE.", "",
             "| scene / material | px | " + " | ".join(keys) + " |", "|" + "---|" * (len(keys) + 2)]
    for name, r in results.items():
        lines.append(f"| **{name}** | {r['pixels']} | " + " | ".join(
            f"{r['ratio'][k]:.3f} / {r['rel_rmse'][k]:.3f}" for k in keys) + " |")
        for label, ratios in r["materials"].items():
            lines.append(f"| {name}: {label} | | " + " | ".join(f"{ratios[k]:.3f}" for k in keys) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["occluder", "many_lights"])
    parser.add_argument("--stride", type=int, default=10)
    parser.add_argument("--variants", nargs="+", default=["0:3:0:0", "1:3:1:0", "1:3:1:1", "1:3:1:2"])
    parser.add_argument("--tag", default="")
    args = parser.parse_args(argv)
    argv_text = ".venv/bin/python benchmarks/ism_gap_sides.py " + " ".join(sys.argv[1:] if argv is None else argv)
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    ensure_gpu_context()
    scenes = {n: p for n, p, _ in suite()}
    results = {}
    start = time.perf_counter()
    for name in args.only:
        results[name] = run_scene(name, scenes[name], args.stride, args.variants)
    text = markdown(results, argv_text, args.variants) + f"\nRun {time.perf_counter() - start:.0f} s.\n"
    stem = "ism_gap_sides" + (f"_{args.tag}" if args.tag else "")
    out = REPO / "benchmarks" / "results"
    (out / f"{stem}.md").write_text(text)
    (out / f"{stem}.json").write_text(json.dumps({"command": argv_text, "results": results}, indent=1))
    print(text)


if __name__ == "__main__":
    main()
