# SPDX-License-Identifier: GPL-3.0-or-later
"""Which VSGLs bring the excess light of a scene with visibility, and on which receivers (not a
test): each VSGL against its own cluster of RSM texels, with and without exact visibility.

    .venv/bin/python benchmarks/courtyard_leak.py [--only NAME ...] [--counts N ...] [--stride S]
        [--seed K] [--ism-points P] [--ism-size S] [--generation gpu|reference] [--split-at-jumps on|off]
        [--max-slope T]
        [--append] [--results-dir DIR]

A VSGL of 000 §4 is a kernel on the RSM: trilinear filtering at (x_i, l_i) is linear in the
level-0 texels, so it is a weighted cluster Σ_j c_ij VPL_j (c_ij the bilinear weights of the two
mip levels spread over their 2^l × 2^l blocks, scaled so that Σ_j c_ij lum(Φ_j(Rd + Rs)_j) is the
VSGL's power: Eq. 5's M / (N p̄) read off the table). Every RSM texel is a VPL with its exact lobes
(energy_budget.vpl_light) and every receiver–VPL segment is ray-cast, so per receiver p and VSGL i

* U_pi = Σ_j c_ij L_pj (the cluster unshadowed), T_pi = Σ_j c_ij L_pj V_pj (the cluster with exact
  visibility): T / U is the share of the cluster's light that truly arrives;
* the VSGL's own light off_pi (reference/vsgl_shading.shade, the scene's diffuse mode), and
  off_pi · T_pi / U_pi: the VSGL with its cluster's true visible share ("VSGL, true share"), which
  separates the visibility error (maps or exact from the shadow origin against the true share)
  from the lobe and position model's own error (off against U);
* maps_pi and exact_pi: the VSGL with the GPU's shadow maps (vsgl_visibility) and with the
  segment to its shadow origin ray-cast (visibility_diagnosis.exact_visibility).

Each VSGL is classed by its cluster: the RSM texels' surfaces (the scene's triangles grouped by
object, the texel's nearest), its largest surface's share of the cluster's luminance power
(straddling below STRADDLE_SHARE), and where its shadow origin lies: inside a closed object's box,
in free space, or within OWN_SURFACE_SIGMAS σ_v of the cluster's largest surface ("on"). Per class
and receiver material: the excess of the maps and of the exact rows over the true share (the
visibility's leak, as a share of Cycles' light on those receivers) and the class's VSGL count.
``--generation reference``: the VSGLs made by the float64 generation from the GPU's RSM (same
lattice) and their maps by the float64 splat (visibility_diagnosis.reference_maps);
``--split-at-jumps``: the kernels' descent off RSM depth discontinuities for every light or none
(pipeline.SPLIT_LIGHT_TYPES; the reference generation's split_at_jumps); ``--max-slope``: the
maps' lookup with the slope-scaled bias capped at tan θ = T (reference.ism.ISM_MAX_SLOPE).
Writes ``benchmarks/results/courtyard_leak.md`` (+ .json).
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
from energy_budget import segments_blocked, vpl_light  # noqa: E402
from energy_budget import view_vpls as texel_vpls  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.demo import log  # noqa: E402
from visibility_diagnosis import exact_visibility  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
#: A cluster whose largest surface holds less than this share of its power straddles surfaces.
STRADDLE_SHARE = 0.9
#: Bins (m) of a shadow origin's distance to the nearest object other than its cluster's main one.
CLEARANCE_BINS = ((0.0, 0.25), (0.25, 0.5), (0.5, 1.0), (1.0, 2.0), (2.0, 4.0), (4.0, math.inf))
#: A shadow origin within this many σ_v of its cluster's main surface's plane lies "on" it.
OWN_SURFACE_SIGMAS = 0.75


def view_vpls(view_arrays, light):
    """Every covered, lit texel of one RSM view as a VPL (energy_budget.view_vpls, positions, normals
    and flux in float64 for the ray casts) and its flat texel index row · W + column."""
    vpls = texel_vpls(view_arrays, light)
    for name in ("position", "normal", "flux"):
        vpls[name] = np.asarray(vpls[name], np.float64)
    return vpls


def kernel_weights(center, level, size):
    """(N, size²) the trilinear filter of 000 Eq. 5 as weights on the level-0 texels (each row sums
    to 1): bilinear (CLAMP_TO_EDGE, reference/mipmap.bilinear) at levels ⌊l⌋ and ⌊l⌋ + 1, each mip
    texel the mean of its 2^L × 2^L block."""
    top = int(round(math.log2(size)))
    weights = np.zeros((len(center), size, size))
    for i, (uv, l) in enumerate(zip(np.asarray(center, np.float64), np.asarray(level, np.float64))):
        l = min(max(float(l), 0.0), float(top))
        lower = min(int(math.floor(l)), top)
        for L, share in ((lower, 1.0 - (l - lower)), (min(lower + 1, top), l - lower)):
            if share <= 0.0:
                continue
            side = size >> L
            s, t = uv[0] * side - 0.5, uv[1] * side - 0.5
            j0, i0 = int(math.floor(s)), int(math.floor(t))
            fx, fy = s - j0, t - i0
            block = 1 << L
            for di, wy in ((0, 1.0 - fy), (1, fy)):
                for dj, wx in ((0, 1.0 - fx), (1, fx)):
                    row = min(max(i0 + di, 0), side - 1)
                    col = min(max(j0 + dj, 0), side - 1)
                    weights[i, row * block:(row + 1) * block, col * block:(col + 1) * block] += (
                        share * wy * wx / (block * block))
    return weights.reshape(len(center), -1)


def surface_of(points, triangles, owners):
    """(M,) the owner (object index) of each point's nearest triangle (by plane distance within the
    triangle's bounding box grown by 1 cm; the points are the RSM's, on the triangles)."""
    v0, v1, v2 = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    n = np.cross(v1 - v0, v2 - v0)
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
    low = np.minimum(np.minimum(v0, v1), v2) - 0.01
    high = np.maximum(np.maximum(v0, v1), v2) + 0.01
    best = np.full(len(points), np.inf)
    owner = np.full(len(points), -1)
    for t in range(len(triangles)):
        inside = np.all((points >= low[t]) & (points <= high[t]), axis=-1)
        d = np.abs((points - v0[t]) @ n[t])
        better = inside & (d < best)
        best = np.where(better, d, best)
        owner = np.where(better, owners[t], owner)
    return owner


def cluster_plane_distance(point, vpls, weight, on):
    """|n̄ · (point − ȳ)|: the distance of ``point`` from the plane of the cluster's texels ``on``
    its main surface (their power-weighted mean position ȳ and normal n̄)."""
    w = np.where(on, weight, 0.0)
    if w.sum() <= 0.0:
        return math.inf
    y = (w[:, None] * vpls["position"]).sum(axis=0) / w.sum()
    n = (w[:, None] * vpls["normal"]).sum(axis=0)
    n /= max(np.linalg.norm(n), 1e-30)
    return float(abs((point - y) @ n))


def object_boxes(triangles, owners):
    """{owner: (low, high)} the bounding box of each object's triangles."""
    return {o: (triangles[owners == o].reshape(-1, 3).min(axis=0), triangles[owners == o].reshape(-1, 3).max(axis=0))
            for o in np.unique(owners)}


def analyse(name, path, stride, vsgl_count, seed=None, extra=None, generation="gpu", split_at_jumps=None, max_slope=None):
    from vsgl_addon.pipeline import VSGL_OWN_REFLECTOR_SIGMAS, build_visibility
    from vsgl_addon.passes.vsgl_shading import ISM_MAX_RADIUS
    from vsgl_addon.reference.ism import shadow_origin
    from vsgl_addon.reference.vsgl_shading import diffuse_mode_for_kernel, shade, vsgl_visibility

    width, height = RESOLUTION
    saved, truth, description = scene_with_truth(name, path, width, height)
    overrides = {key: value for key, value in (("vsgl_count", vsgl_count), ("seed", seed)) if value is not None}
    overrides.update(extra or {})
    settings = saved.overridden(visibility=True, **overrides)
    geometry = description.geometry
    triangles = np.asarray(geometry.positions, np.float64)
    owners = np.asarray(geometry.object_index, np.int64)
    object_names = list(description.object_names)
    original_names = list(object_names)
    bench = Bench(description, width, height)
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride)
        material = bench.material_index[pick]
        vsgls, _ = bench.vsgls(settings)
        try:
            build_visibility(bench.scene_gpu, vsgls, settings)
            tables = vsgls.table_arrays()
            if len(tables) != 1 or len(vsgls.generations) != 1:
                raise SystemExit(f"{name}: {len(vsgls.generations)} RSM views; this benchmark reads one")
            table = {k: np.asarray(v, np.float64) for k, v in tables[0].items()}
            light_index, view_index, _ = vsgls.generations[0]
            rsm_view = vsgls.views_by_light[light_index][view_index]
            arrays = rsm_view.to_numpy()
            atlas = vsgls.isms[0]
            count = len(table["variance"])
            maps = atlas.count // count
            depths = atlas.read()
            if generation == "reference":
                # The same RSM, lattice and settings through the float64 generation, its maps by
                # the float64 twin of the splat, gap closing and pull-push.
                from vsgl_addon.pipeline import POINT_SETS, _rotation
                from vsgl_addon.reference.vsgl import generate_vsgls
                from vsgl_addon.scene_points import triangle_areas
                from visibility_diagnosis import reference_maps

                made = generate_vsgls(arrays.rsm, count, k=settings.k, kernel=settings.kernel,
                                      rotation=_rotation(settings.seed, light_index, view_index),
                                      positional_distribution=settings.positional_distribution,
                                      split_at_jumps=split_at_jumps)
                table = {k: np.asarray(made[k], np.float64) for k in table if k in made}
                points = bench.scene_gpu.scene_points(settings.ism_points, POINT_SETS, settings.seed)
                point_area = float(triangle_areas(description.geometry.positions).sum()) / settings.ism_points
                depths = reference_maps(atlas, table, maps, 0, points, point_area)
            _, _, terms = shade(table, position, normal, view, rd, f0, alpha,
                                diffuse_mode=diffuse_mode_for_kernel(settings.kernel), per_term=True)
            weight = terms.sum(axis=3) @ LUMINANCE  # (P, N, 2)
            from vsgl_addon.reference import ism

            saved_slope = ism.ISM_MAX_SLOPE
            try:
                ism.ISM_MAX_SLOPE = saved_slope if max_slope is None else max_slope
                v_maps = vsgl_visibility(depths, maps, table, position, normal, ISM_MAX_RADIUS, surfaces=atlas.normal_offset)
            finally:
                ism.ISM_MAX_SLOPE = saved_slope
            v_exact = exact_visibility(table, maps, position, triangles, VSGL_OWN_REFLECTOR_SIGMAS)
            vpls = view_vpls(arrays, rsm_view.light)
        finally:
            vsgls.free()
        names = bench.materials
    finally:
        bench.free()

    size = arrays.rsm.position.shape[0]
    start = time.perf_counter()
    light, _, _ = vpl_light(vpls, position, normal, view, rd, f0, alpha, "exact")
    visible = np.ones_like(light)
    for p in range(len(position)):
        lit = np.flatnonzero(light[p] > 0.0)
        if len(lit):
            starts = np.broadcast_to(position[p], (len(lit), 3))
            visible[p, lit] = ~segments_blocked(starts, vpls["position"][lit], triangles)
    log(f"  {name} N={count}: {len(vpls['flux'])} VPLs ray-cast in {time.perf_counter() - start:.0f} s")

    kernel = kernel_weights(table["kernel_center"], table["kernel_level"], size)[:, vpls["texel"]]  # (N, M)
    vpl_power = vpls["flux"] * (vpls["rd"] + vpls["rs"]) @ LUMINANCE
    raw = kernel @ vpl_power
    scale = np.where(raw > 0.0, (table["power"] @ LUMINANCE) / np.maximum(raw, 1e-300), 0.0)
    c = kernel * scale[:, None]
    unshadowed = light @ c.T  # (P, N)
    shadowed = (light * visible) @ c.T
    share = np.where(unshadowed > 0.0, shadowed / np.maximum(unshadowed, 1e-300), 1.0)
    off = weight.sum(axis=2)
    stages = {"vpl_off": unshadowed, "vpl_vis": shadowed, "vsgl_off": off, "vsgl_true": off * share,
              "vsgl_maps": (weight * v_maps).sum(axis=2), "vsgl_exact": (weight * v_exact).sum(axis=2)}

    # The clusters' surfaces and where their shadow origins lie.
    texel_owner = surface_of(vpls["position"], triangles, owners)
    # A surface that reaches past the others' bounds (a ground under walls) is two surfaces: its
    # texels within the bounds of every other object's triangles (in x, y) and those outside.
    region_names = list(object_names)
    for o in range(len(object_names)):
        others = triangles[owners != o].reshape(-1, 3)
        mine = triangles[owners == o].reshape(-1, 3)
        if not len(others) or not len(mine):
            continue
        low, high = others.min(axis=0), others.max(axis=0)
        if np.all(mine[:, :2].min(axis=0) < low[:2]) and np.all(mine[:, :2].max(axis=0) > high[:2]):
            outside = (texel_owner == o) & ~np.all((vpls["position"][:, :2] >= low[:2])
                                                   & (vpls["position"][:, :2] <= high[:2]), axis=-1)
            texel_owner = np.where(outside, len(region_names), texel_owner)
            region_names.append(f"{object_names[o]} (outside the others' bounds)")
            region_names[o] = f"{object_names[o]} (within the others' bounds)"
    object_names = region_names
    own = np.zeros((count, len(object_names)))
    for o in range(len(object_names)):
        own[:, o] = c[:, texel_owner == o] @ vpl_power[texel_owner == o]
    main = own.argmax(axis=1)
    main_share = own.max(axis=1) / np.maximum(own.sum(axis=1), 1e-300)
    origin = shadow_origin(table["diffuse_mean"], table["diffuse_variance"], table["diffuse_axis"])
    sigma = np.sqrt(np.maximum(table["diffuse_variance"], 0.0))
    boxes = object_boxes(triangles, owners)
    inside = np.zeros(count, bool)
    for o, (low, high) in boxes.items():
        if np.all(high - low > 0.05):  # a closed solid, not a plane
            inside |= np.all((origin > low) & (origin < high), axis=-1)
    plane_distance = np.array([cluster_plane_distance(origin[i], vpls, c[i] * vpl_power, texel_owner == main[i])
                               for i in range(count)])
    on_surface = plane_distance <= OWN_SURFACE_SIGMAS * sigma
    classes = np.where(inside, "origin inside a solid",
                       np.where(main_share < STRADDLE_SHARE,
                                np.where(on_surface, "straddling, origin on its main surface",
                                         "straddling, origin in free space"),
                                "one surface"))

    # The origin's distance to the nearest object other than its cluster's main one (their boxes).
    clearance = np.full(count, np.inf)
    for o, (low, high) in boxes.items():
        gap = np.linalg.norm(np.maximum(np.maximum(low - origin, origin - high), 0.0), axis=-1)
        mine = np.array([region_names[main[i]].split(" (")[0] == original_names[o] for i in range(count)])
        clearance = np.where(mine, clearance, np.minimum(clearance, gap))
    cycles = truth["indirect"][pick].astype(np.float64) @ LUMINANCE
    subsets = {"all": np.ones(len(cycles), bool)}
    for index in np.unique(material):
        here = material == index
        if here.sum() >= 8 and cycles[here].sum() > 0.0:
            subsets[names[index] if 0 <= index < len(names) else str(index)] = here
    rows = {}
    for label, here in subsets.items():
        truth_sum = float(cycles[here].sum())
        row = {key: float(v[here].sum()) / truth_sum for key, v in stages.items()}
        row["classes"] = {}
        for cls in np.unique(classes):
            which = classes == cls
            row["classes"][str(cls)] = {
                "vsgls": int(which.sum()),
                "off": float(off[here][:, which].sum()) / truth_sum,
                "vpl_off": float(unshadowed[here][:, which].sum()) / truth_sum,
                "vpl_vis": float(shadowed[here][:, which].sum()) / truth_sum,
                "true": float(stages["vsgl_true"][here][:, which].sum()) / truth_sum,
                "maps": float(stages["vsgl_maps"][here][:, which].sum()) / truth_sum,
                "exact": float(stages["vsgl_exact"][here][:, which].sum()) / truth_sum}
        by_main = {}
        for o in np.unique(main):
            which = main == o
            by_main[object_names[o]] = {
                "vsgls": int(which.sum()),
                "straddling": int((which & (main_share < STRADDLE_SHARE)).sum()),
                "vpl_vis": float(shadowed[here][:, which].sum()) / truth_sum,
                "true": float(stages["vsgl_true"][here][:, which].sum()) / truth_sum,
                "maps": float(stages["vsgl_maps"][here][:, which].sum()) / truth_sum,
                "exact": float(stages["vsgl_exact"][here][:, which].sum()) / truth_sum}
        row["main_surface"] = by_main
        by_clearance = {}
        for low_edge, high_edge in CLEARANCE_BINS:
            which = (clearance >= low_edge) & (clearance < high_edge)
            by_clearance[f"{low_edge:g}-{high_edge:g} m"] = {
                "vsgls": int(which.sum()),
                "vpl_vis": float(shadowed[here][:, which].sum()) / truth_sum,
                "true": float(stages["vsgl_true"][here][:, which].sum()) / truth_sum,
                "maps": float(stages["vsgl_maps"][here][:, which].sum()) / truth_sum,
                "exact": float(stages["vsgl_exact"][here][:, which].sum()) / truth_sum}
        row["clearance"] = by_clearance
        rows[label] = row
    leak = (stages["vsgl_maps"] - stages["vsgl_true"]).sum(axis=0)
    top = np.argsort(-leak)[:8]
    worst = [{"vsgl": int(i), "leak": float(leak[i] / cycles.sum()), "class": str(classes[i]),
              "main": object_names[main[i]], "main_share": float(main_share[i]), "sigma": float(sigma[i]),
              "mean": [round(float(x), 2) for x in table["diffuse_mean"][i]],
              "axis": [round(float(x), 2) for x in table["diffuse_axis"][i]],
              "surfaces": {object_names[o]: round(float(own[i, o] / own[i].sum()), 3)
                           for o in np.argsort(-own[i])[:3] if own[i, o] > 0.0}} for i in top]
    kernel_sum = c.sum(axis=0)
    return {"pixels": int(pick.sum()), "vsgl_count": count, "vpls": len(vpls["flux"]), "rows": rows,
            "worst": worst, "median_sigma": float(np.median(sigma)),
            "mean_level": float(np.mean(table["kernel_level"])),
            "coverage": float((kernel_sum * vpl_power).sum() / vpl_power.sum())}


def markdown(results, argv_text, first=True):
    lines = ["# Where a scene's VSGL visibility leaks: per VSGL against its own cluster", "",
             "The module documentation of `benchmarks/courtyard_leak.py` defines every figure. Each figure: "
             "light summed over the subset's receivers / Cycles' there (mean ours / Cycles). *VPL off / vis*: "
             "the VSGLs' clusters of RSM texels as VPLs with exact lobes, unshadowed / ray-cast; *true share*: "
             "each VSGL times its cluster's ray-cast visible share (the target of any visibility); *maps*, "
             "*exact*: the VSGL with the GPU's shadow maps, with its shadow origin ray-cast. Leak = maps − true "
             "share.", ""] if first else [""]
    lines += [f"`.venv/bin/python benchmarks/courtyard_leak.py {argv_text}`", ""]
    lines += ["| scene, N / receivers | VPL off | VPL vis | VSGL off | VSGL true share | VSGL maps | VSGL exact | leak (maps) | leak (exact) |",
              "|---|---|---|---|---|---|---|---|---|"]
    for key, r in results.items():
        for label, row in r["rows"].items():
            title = f"**{key}** ({r['pixels']} px, {r['vsgl_count']} VSGLs, median σ_v {r['median_sigma']:.2f} m, mean kernel level {r.get('mean_level', math.nan):.2f})" \
                if label == "all" else f"{key}: {label}"
            lines.append(f"| {title} | {row['vpl_off']:.3f} | {row['vpl_vis']:.3f} | {row['vsgl_off']:.3f} | "
                         f"{row['vsgl_true']:.3f} | {row['vsgl_maps']:.3f} | {row['vsgl_exact']:.3f} | "
                         f"{row['vsgl_maps'] - row['vsgl_true']:+.3f} | {row['vsgl_exact'] - row['vsgl_true']:+.3f} |")
    lines += ["", "By cluster class (see the module documentation): VSGLs, then per receiver subset the excess of "
              "the maps over the clusters' ray-cast VPLs (VSGL maps − VPL vis, share of Cycles' light there) = "
              "the model's part (true share − VPL vis: the VSGL's own lobes and Gaussian against its cluster, "
              "at the cluster's visible share) + the leak (maps − true share); in brackets the exact shadow "
              "origin's leak (exact − true share).", ""]
    labels = [label for label in next(iter(results.values()))["rows"]]
    lines += ["| scene, N | class | VSGLs | " + " | ".join(labels) + " |", "|---|---|---|" + "---|" * len(labels)]
    for key, r in results.items():
        for cls, first_row in r["rows"]["all"]["classes"].items():
            cells = []
            for label in labels:
                c = r["rows"].get(label, {}).get("classes", {}).get(cls)
                cells.append("" if c is None else f"{c['maps'] - c['vpl_vis']:+.3f} = {c['true'] - c['vpl_vis']:+.3f} "
                             f"{c['maps'] - c['true']:+.3f} ({c['exact'] - c['true']:+.3f})")
            lines.append(f"| {key} | {cls} | {first_row['vsgls']} | " + " | ".join(cells) + " |")
    lines += ["", "By the cluster's main surface (the object holding most of its power): VSGLs (straddling), then "
              "per receiver subset as above.", ""]
    lines += ["| scene, N | main surface | VSGLs (straddling) | " + " | ".join(labels) + " |",
              "|---|---|---|" + "---|" * len(labels)]
    for key, r in results.items():
        for surface, first_row in r["rows"]["all"]["main_surface"].items():
            cells = []
            for label in labels:
                c = r["rows"].get(label, {}).get("main_surface", {}).get(surface)
                cells.append("" if c is None else f"{c['maps'] - c['vpl_vis']:+.3f} = {c['true'] - c['vpl_vis']:+.3f} "
                             f"{c['maps'] - c['true']:+.3f} ({c['exact'] - c['true']:+.3f})")
            lines.append(f"| {key} | {surface} | {first_row['vsgls']} ({first_row['straddling']}) | "
                         + " | ".join(cells) + " |")
    lines += ["", "By the shadow origin's distance to the nearest object other than its cluster's main surface "
              "(its bounding box): VSGLs, then per receiver subset as above.", ""]
    lines += ["| scene, N | origin's clearance | VSGLs | " + " | ".join(labels) + " |",
              "|---|---|---|" + "---|" * len(labels)]
    for key, r in results.items():
        for band, first_row in r["rows"]["all"]["clearance"].items():
            cells = []
            for label in labels:
                c = r["rows"].get(label, {}).get("clearance", {}).get(band)
                cells.append("" if c is None else f"{c['maps'] - c['vpl_vis']:+.3f} = {c['true'] - c['vpl_vis']:+.3f} "
                             f"{c['maps'] - c['true']:+.3f} ({c['exact'] - c['true']:+.3f})")
            lines.append(f"| {key} | {band} | {first_row['vsgls']} | " + " | ".join(cells) + " |")
    lines += ["", "The largest leaks (maps − true share over all receivers, share of Cycles' light):", ""]
    for key, r in results.items():
        for w in r["worst"][:5]:
            lines.append(f"- {key} VSGL {w['vsgl']}: {w['leak']:+.3f}, {w['class']}, σ_v {w['sigma']:.2f} m, "
                         f"mean {w['mean']}, axis {w['axis']}, surfaces {w['surfaces']}")
    lines += ["", "Kernel coverage (Σ_i c_ij over the RSM's power, 1 for K = 1 without gaps): " + "; ".join(
        f"{key} {r['coverage']:.3f}" for key, r in results.items()) + "."]
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["sun_courtyard"])
    parser.add_argument("--counts", nargs="+", type=int, default=[64, 256, 1024])
    parser.add_argument("--stride", type=int, default=10)
    parser.add_argument("--seed", type=int, default=None, help="the lattice seed instead of the scene's")
    parser.add_argument("--ism-points", type=int, default=None, help="points per shadow map instead of the scene's")
    parser.add_argument("--ism-size", type=int, default=None, help="shadow map side instead of the scene's")
    parser.add_argument("--generation", choices=("gpu", "reference"), default="gpu",
                        help="the VSGLs and maps of the GPU, or of the float64 twins from the GPU's RSM")
    parser.add_argument("--split-at-jumps", choices=("on", "off"), default=None,
                        help="the kernels' descent off depth discontinuities for every light (on) or none "
                             "(off) instead of pipeline.SPLIT_LIGHT_TYPES (and in the reference generation)")
    parser.add_argument("--max-slope", type=float, default=None,
                        help="the maps' float64 lookup with this cap of the slope-scaled bias (reference/ism.py "
                             "ISM_MAX_SLOPE; the maps stay as built)")
    parser.add_argument("--append", action="store_true")
    parser.add_argument("--results-dir", type=Path, default=REPO / "benchmarks" / "results")
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    extra = {key: value for key, value in (("ism_points", args.ism_points), ("ism_size", args.ism_size))
             if value is not None}
    if args.split_at_jumps is not None:
        from vsgl_addon import pipeline
        from vsgl_addon.scene_description import LIGHT_TYPES

        pipeline.SPLIT_LIGHT_TYPES = LIGHT_TYPES if args.split_at_jumps == "on" else ()
    results = {}
    for name, path, _ in suite():
        if name in args.only:
            for count in args.counts:
                start = time.perf_counter()
                results[f"{name} N={count}"] = analyse(name, path, args.stride, count, args.seed, extra,
                                                       args.generation,
                                                       None if args.split_at_jumps is None else args.split_at_jumps == "on",
                                                       args.max_slope)
                log(f"  ({time.perf_counter() - start:.0f} s)")
    argv_text = (f"--only {' '.join(args.only)} --counts {' '.join(map(str, args.counts))} --stride {args.stride}"
                 + ("" if args.seed is None else f" --seed {args.seed}")
                 + "".join(f" --{key.replace('_', '-')} {value}" for key, value in extra.items())
                 + ("" if args.generation == "gpu" else f" --generation {args.generation}")
                 + ("" if args.split_at_jumps is None else f" --split-at-jumps {args.split_at_jumps}")
                 + ("" if args.max_slope is None else f" --max-slope {args.max_slope}"))
    target = args.results_dir / "courtyard_leak.md"
    append = args.append and target.is_file()
    text = markdown(results, argv_text, first=not append)
    args.results_dir.mkdir(parents=True, exist_ok=True)
    with target.open("a" if append else "w") as out:
        out.write(text)
    (args.results_dir / "courtyard_leak.json").write_text(json.dumps({"argv": argv_text, "results": results}, indent=1))
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
