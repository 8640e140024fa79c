# SPDX-License-Identifier: GPL-3.0-or-later
"""Where the imperfect shadow maps let light through an occluder (not a test): each VSGL map
against the exact depth map from the same origin, per receiver and per texel.

    .venv/bin/python benchmarks/ism_holes.py [--only NAME ...] [--stride S] [--seed K]
        [--vsgl-count N] [--ism-points P] [--ism-size S] [--surface-types TYPE ...] [--append] [--results-dir DIR]

Per scene (one RSM view, the scene's settings, visibility on), on every S-th pixel of the suite's
camera G-buffer, the VSGLs' light (reference/vsgl_shading.shade, per lobe) with each lobe's
visibility from:

* *maps*: the GPU's imperfect shadow maps (the shader's lookup, reference/vsgl_shading.vsgl_visibility);
* *ideal maps*: the same lookup in the exact depth map from the same shadow origin (the nearest
  triangle hit along each texel centre's direction, hits within the own-reflector distance left out
  as the splat leaves those points out): what a map without holes would give, so maps − ideal is
  the point sampling's part (too few points on an occluder, splat and pull-push holes) and
  ideal − exact the lookup's (texel size, bias, filter);
* *exact*: the segment to the shadow origin ray-cast (visibility_diagnosis.exact_visibility).

Each figure is the light summed over the receivers / Cycles' there. Per texel of every map, against
its ideal map: an *occluder texel* is one whose exact hit lies on an object other than the
farthest-reaching one seen by the map (the ground, in the courtyard); a *hole* is an occluder texel
whose map depth lies more than HOLE_MARGIN × the exact depth behind it. A hole is classed by the raw
splat (before gap closing and pull-push, reference.ism.splat of the map's point set): *seen
through* (a farther point landed there), *filled* (no point landed: gap closing or pull-push gave
its depth). Per occluder object: the maps' points on it (the map's set, past the own-reflector
distance), its footprint in texels, its holes, weighted by the leak the maps' lookups gave.
``--surface-types``: the light types whose maps keep their surfaces (pipeline.SURFACE_LIGHT_TYPES;
none given: no light's), instead of the default.
Writes ``benchmarks/results/ism_holes.md`` (+ .json).
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
#: A map texel is a hole when its depth lies this share of the exact depth behind it.
HOLE_MARGIN = 0.1


def nearest_hits(origin, directions, triangles, t_min, chunk=4096):
    """(R,) distance to the nearest triangle hit past ``t_min`` along unit ``directions`` (R, 3) from
    ``origin`` (Möller–Trumbore; inf where nothing), and (R,) the hit triangle (-1)."""
    v0, e1, e2 = triangles[:, 0], triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    best = np.full(len(directions), np.inf)
    which = np.full(len(directions), -1, np.int64)
    for r0 in range(0, len(directions), chunk):
        dd = directions[r0:r0 + chunk]
        p = np.cross(dd[:, None, :], e2[None])
        det = np.einsum("rtk,tk->rt", p, e1)
        inv = 1.0 / np.where(np.abs(det) > 1e-14, det, np.inf)
        s = origin[None, :] - v0
        u = np.einsum("tk,rtk->rt", s, p) * inv
        q = np.cross(s, e1)
        v = np.einsum("rk,tk->rt", dd, q) * inv
        t = np.einsum("tk,tk->t", q, e2)[None, :] * inv
        t = np.where((u >= 0) & (v >= 0) & (u + v <= 1) & (t > t_min), t, np.inf)
        best[r0:r0 + chunk] = t.min(axis=1)
        which[r0:r0 + chunk] = np.where(np.isfinite(t.min(axis=1)), t.argmin(axis=1), -1)
    return best, which


def analyse(name, path, stride, overrides, internals=None):
    from vsgl_addon.passes.vsgl_shading import ISM_MAX_RADIUS
    from vsgl_addon.pipeline import POINT_SETS, VSGL_OWN_REFLECTOR_SIGMAS, build_visibility
    from vsgl_addon.reference import ism
    from vsgl_addon.reference.vsgl_shading import diffuse_mode_for_kernel, shade, vsgl_visibility
    from vsgl_addon.scene_points import triangle_areas

    width, height = RESOLUTION
    saved, truth, description = scene_with_truth(name, path, width, height)
    settings = saved.overridden(visibility=True, **overrides)
    geometry = description.geometry
    triangles = np.asarray(geometry.positions, np.float64)
    owners = np.asarray(geometry.object_index, np.int64)
    names = list(description.object_names)
    bench = Bench(description, width, height)
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride)
        vsgls, _ = bench.vsgls(settings)
        try:
            build_visibility(bench.scene_gpu, vsgls, settings)
            tables = [{k: np.asarray(v, np.float64) for k, v in t.items()} for t in vsgls.table_arrays()]
            atlases = [(atlas.count, atlas.size, atlas.read(), atlas.surfaces, atlas.normal_offset) for atlas in vsgls.isms]
        finally:
            vsgls.free()
        points = bench.scene_gpu.scene_points(settings.ism_points, POINT_SETS, settings.seed)
        point_area = float(triangle_areas(geometry.positions).sum()) / settings.ism_points
        per_table = []
        first_map = 0
        start = time.perf_counter()
        for table, (atlas_count, size, depths, surfaces, offset) in zip(tables, atlases):
            count = len(table["diffuse_variance"])
            maps = atlas_count // count
            _, _, terms = shade(table, position, normal, view, rd, f0, alpha,
                                diffuse_mode=diffuse_mode_for_kernel(settings.kernel), per_term=True)
            weight = terms.sum(axis=3) @ LUMINANCE  # (P, N, 2)
            origins, sets, near = ism.vsgl_map_origins(table, maps, first_map, POINT_SETS, VSGL_OWN_REFLECTOR_SIGMAS)
            first_map += atlas_count
            directions = ism.texel_directions(size).reshape(-1, 3)
            ideal = np.empty_like(depths)
            hit_object = np.empty(depths.shape, np.int64)
            raw = np.empty_like(depths)
            for m, (origin, index, dist) in enumerate(zip(origins, sets, near)):
                t, tri = nearest_hits(origin, directions, triangles, dist)
                ideal[m] = t.reshape(size, size)
                hit_object[m] = np.where(tri >= 0, owners[np.maximum(tri, 0)], -1).reshape(size, size)
                raw[m] = ism.splat(points.positions[index], origin, size, dist, points.normals[index], point_area,
                                   plane_depth=ism.SPLAT_PLANE_DEPTH if surfaces else 0.0,
                                   max_radius=ism.SURFACE_SPLAT_MAX_RADIUS if surfaces else None)
            per_table.append(dict(
                table=table, maps=maps, count=count, size=size, weight=weight, depths=depths, ideal=ideal,
                hit_object=hit_object, raw=raw, origins=origins, sets=sets, near=near, surfaces=surfaces,
                v_maps=vsgl_visibility(depths, maps, table, position, normal, ISM_MAX_RADIUS, surfaces=offset),
                v_ideal=vsgl_visibility(ideal, maps, table, position, normal, ISM_MAX_RADIUS, surfaces=offset),
                v_exact=exact_visibility(table, maps, position, triangles, VSGL_OWN_REFLECTOR_SIGMAS)))
        log(f"  {name}: {first_map} maps and their ideal maps in {time.perf_counter() - start:.0f} s")
    finally:
        bench.free()
    cycles = truth["indirect"][pick].astype(np.float64) @ LUMINANCE
    if internals is not None:
        internals.update(points=points, point_area=point_area, position=position, normal=normal, cycles=cycles, names=names, tables=per_table,
                         material=bench.material_index[pick])
    weight = np.concatenate([t["weight"] for t in per_table], axis=1)
    v_maps, v_ideal, v_exact = (np.concatenate([t[k] for t in per_table], axis=1)
                                for k in ("v_maps", "v_ideal", "v_exact"))
    count = weight.shape[1]
    size = per_table[0]["size"]
    material = bench.material_index[pick]
    subsets = {"all": np.ones(len(cycles), bool)}
    for index in np.unique(material):
        here = material == index
        if here.sum() >= 8 and cycles[here].sum() > 0.0:
            subsets[bench.materials[index] if 0 <= index < len(bench.materials) else str(index)] = here
    rows = {}
    for label, here in subsets.items():
        total = float(cycles[here].sum())
        rows[label] = {key: float((weight[here] * v[here]).sum()) / total for key, v in
                       (("off", 1.0 + 0 * v_maps), ("maps", v_maps), ("ideal", v_ideal), ("exact", v_exact))}
        rows[label]["pixels"] = int(here.sum())

    # Per map: its leak (maps over exact, positive part) as a share of Cycles' light.
    leak_maps, stats = [], []
    for t in per_table:
        leak = (np.clip(t["v_maps"] - t["v_exact"], 0.0, None) * t["weight"]).sum(axis=0) / float(cycles.sum())
        leak_maps.append(leak.sum(axis=1) if t["maps"] == 1 else leak.reshape(-1))
    leak_map = np.concatenate(leak_maps)
    seen = np.concatenate([t["hit_object"][t["hit_object"] >= 0] for t in per_table])
    background = int(np.bincount(seen).argmax())
    w = leak_map / max(leak_map.sum(), 1e-300)
    columns = {}
    worst_rows = []
    offset = 0
    for t in per_table:
        hit, depths, ideal, raw = t["hit_object"], t["depths"], t["ideal"], t["raw"]
        occluder = (hit >= 0) & (hit != background)
        hole = occluder & ~(depths <= ideal * (1.0 + HOLE_MARGIN))
        through = hole & np.isfinite(raw)
        flat = lambda a: a.reshape(len(t["origins"]), -1).sum(axis=1).astype(np.float64)  # noqa: E731
        for obj in np.unique(hit[occluder]):
            on = hit == obj
            obj_tris = owners == obj
            counts = []
            for origin, index, dist in zip(t["origins"], t["sets"], t["near"]):
                d = np.linalg.norm(points.positions[index].astype(np.float64) - origin, axis=-1)
                counts.append(int((obj_tris[points.triangle[index]] & (d > dist)).sum()))
            c = columns.setdefault(names[obj], {"counts": [], "footprint": [], "holes": [], "through": [], "w": []})
            c["counts"].append(np.asarray(counts, np.float64))
            c["footprint"].append(flat(on))
            c["holes"].append(flat(hole & on))
            c["through"].append(flat(through & on))
            c["w"].append(w[offset:offset + len(t["origins"])])
        for m in range(len(t["origins"])):
            worst_rows.append({"map": offset + m, "leak": float(leak_map[offset + m]),
                               "origin": np.round(t["origins"][m], 2).tolist(),
                               "sigma": float(np.sqrt(t["table"]["diffuse_variance"][m // t["maps"]])),
                               "occluder texels": int(occluder[m].sum()), "holes": int(hole[m].sum()),
                               "seen through": int(through[m].sum())})
        offset += len(t["origins"])
    per_object = {}
    for obj, c in columns.items():
        counts, footprint, holes, through_, wo = (np.concatenate(c[k]) for k in ("counts", "footprint", "holes", "through", "w"))
        seen_by = footprint > 0
        per_object[obj] = {
            "maps seeing it": int(seen_by.sum()),
            "points (mean over maps seeing it)": float(counts[seen_by].mean()) if seen_by.any() else 0.0,
            "footprint texels (mean)": float(footprint[seen_by].mean()) if seen_by.any() else 0.0,
            "hole share (all texels)": float(holes.sum() / max(footprint.sum(), 1.0)),
            "seen-through share of holes": float(through_.sum() / max(holes.sum(), 1.0)),
            "points (leak-weighted)": float((wo * counts).sum() / max(wo.sum(), 1e-300)),
            "footprint (leak-weighted)": float((wo * footprint).sum() / max(wo.sum(), 1e-300)),
            "hole share (leak-weighted)": float((wo * holes).sum() / max((wo * footprint).sum(), 1e-300)),
        }
    worst = sorted(worst_rows, key=lambda r: -r["leak"])[:8]
    return {"rows": rows, "objects": per_object, "worst": worst, "background": names[background],
            "vsgl_count": count, "ism_size": size, "ism_points": settings.ism_points,
            "point_area": point_area}


def markdown(results, argv_text, first=True):
    lines = ["# Where the shadow maps let light through: maps against exact depth maps", "",
             "The module documentation of `benchmarks/ism_holes.py` defines every figure.", ""] if first else [""]
    lines += [f"`.venv/bin/python benchmarks/ism_holes.py {argv_text}`", ""]
    lines += ["| scene / receivers | px | off | maps | ideal maps | exact | maps − ideal | ideal − exact |",
              "|---|---|---|---|---|---|---|---|"]
    for name, r in results.items():
        for label, row in r["rows"].items():
            title = (f"**{name}** (N = {r['vsgl_count']}, {r['ism_size']}², {r['ism_points']} points, "
                     f"{r['point_area']:.3f} m² each)" if label == "all" else f"{name}: {label}")
            lines.append(f"| {title} | {row['pixels']} | {row['off']:.3f} | {row['maps']:.3f} | {row['ideal']:.3f} | "
                         f"{row['exact']:.3f} | {row['maps'] - row['ideal']:+.3f} | {row['ideal'] - row['exact']:+.3f} |")
    lines += ["", "Occluders (every object but the background the most texels see):", "",
              "| scene | occluder | maps seeing it | points on it (mean) | footprint texels (mean) | hole share | "
              "seen through / holes | leak-weighted: points | footprint | hole share |", "|---" * 10 + "|"]
    for name, r in results.items():
        for obj, o in r["objects"].items():
            lines.append(f"| {name} | {obj} | {o['maps seeing it']} | {o['points (mean over maps seeing it)']:.1f} | "
                         f"{o['footprint texels (mean)']:.1f} | {o['hole share (all texels)']:.3f} | "
                         f"{o['seen-through share of holes']:.3f} | {o['points (leak-weighted)']:.1f} | "
                         f"{o['footprint (leak-weighted)']:.1f} | {o['hole share (leak-weighted)']:.3f} |")
    lines += ["", "The maps with the largest leak (maps − exact, positive part, share of Cycles' light):", ""]
    for name, r in results.items():
        for w in r["worst"]:
            lines.append(f"- {name} map {w['map']}: {w['leak']:+.4f}, origin {w['origin']}, σ_v {w['sigma']:.2f} m, "
                         f"{w['occluder texels']} occluder texels, {w['holes']} holes ({w['seen through']} seen through)")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["sun_courtyard"])
    parser.add_argument("--stride", type=int, default=10)
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--vsgl-count", type=int, default=None)
    parser.add_argument("--ism-points", type=int, default=None)
    parser.add_argument("--ism-size", type=int, default=None)
    parser.add_argument("--surface-types", nargs="*", default=None,
                        help="light types whose maps keep their surfaces instead of pipeline.SURFACE_LIGHT_TYPES")
    parser.add_argument("--append", action="store_true")
    parser.add_argument("--results-dir", type=Path, default=REPO / "benchmarks" / "results")
    args = parser.parse_args(argv)
    overrides = {k: v for k, v in (("seed", args.seed), ("vsgl_count", args.vsgl_count),
                                   ("ism_points", args.ism_points), ("ism_size", args.ism_size)) if v is not None}
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    ensure_gpu_context()
    if args.surface_types is not None:
        from vsgl_addon import pipeline

        pipeline.SURFACE_LIGHT_TYPES = tuple(args.surface_types)
    results = {}
    for name, path, _ in suite():
        if name in args.only:
            results[name] = analyse(name, path, args.stride, overrides)
    argv_text = " ".join(sys.argv[1:] if argv is None else argv)
    args.results_dir.mkdir(parents=True, exist_ok=True)
    md, js = args.results_dir / "ism_holes.md", args.results_dir / "ism_holes.json"
    text = markdown(results, argv_text, first=not (args.append and md.exists()))
    with open(md, "a" if args.append and md.exists() else "w") as f:
        f.write(text)
    old = json.loads(js.read_text()) if args.append and js.exists() else []
    js.write_text(json.dumps(old + [{"command": argv_text, "results": results}], indent=1))
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
