# SPDX-License-Identifier: GPL-3.0-or-later
"""MRP-ASG (001) on the validation suite against each scene's cached Cycles truth (not a test).

    .venv/bin/python benchmarks/mrp_asg_suite.py [--only NAME ...] [--no-sweep]

Per scene of benchmarks/validation_suite.py (its scenes, the polished metal floor and the demo),
with the scene's saved settings (the add-on's defaults for the suite's scenes), one frame at
240x180 after a warm-up frame, with glossy reflectors on (the default) and off (VSGLs alone):

* indirect specular relative RMSE against Cycles' GlossInd·GlossCol and total indirect relative
  RMSE (both noise-corrected, tradeoff.metrics.Errors), mean indirect ours / Cycles, the number of
  proxies; per material (the demo's gold sphere, the new scene's objects): mean ours / Cycles;
* cost: the MRP-ASG pass's time over the VSGL shading time of the same frame (N = 256 on the demo);
* on occluded_reflector, MRP-ASG also without its proxy-to-receiver shadows (mirror shadow maps):
  what those shadows change, per material (the wall behind the block against the open one);
* disk-radius sweep (r_d = 0.01 … 1 m) on the demo and the polished metal floor: specular and total
  relative RMSE and the pass's time; a plot.

Writes benchmarks/results/mrp_asg_suite.{md,json} and mrp_asg_disk_radius.png, prints the markdown.
The truths must be cached (benchmarks/validation_suite.py --reference-only makes them).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from tradeoff.demo import RESULTS_DIR, log  # noqa: E402
from tradeoff.metrics import Errors  # noqa: E402
from validation_suite import scene_with_truth, suite  # noqa: E402

RADII = (0.01, 0.03, 0.1, 0.3, 1.0)
SWEEP_SCENES = ("demo", "polished_metal_floor")
# Scenes whose per-material figures are reported, and where MRP-ASG is also measured without its
# proxy-to-receiver shadows (the mirror shadow maps of passes/mrp_visibility.py).
REGION_SCENES = SWEEP_SCENES + ("occluded_reflector",)
MIRROR_SCENES = ("occluded_reflector",)
WIDTH, HEIGHT = 240, 180


def _frame(renderer, description, settings, mirror_maps=True):
    """The second of two frames (the first warms up shaders and llvmpipe); ``mirror_maps=False``:
    MRP-ASG without its proxy-to-receiver shadows, everything else the same."""
    if mirror_maps:
        renderer.render(description, settings, WIDTH, HEIGHT)
        return renderer.render(description, settings, WIDTH, HEIGHT)
    from vsgl_addon.renderer import SceneLights

    lights = SceneLights.build(description, settings)
    try:
        maps, lights.mirror_maps = lights.mirror_maps, None
        if maps is not None:
            maps.free()
        camera = description.camera
        args = (lights, settings, WIDTH, HEIGHT, camera.view_matrix(), camera.projection_matrix())
        renderer.render_view(*args)
        return renderer.render_view(*args)
    finally:
        lights.free()


def _material_index(description):
    from tradeoff.bench import Bench

    bench = Bench(description, WIDTH, HEIGHT)
    try:
        return bench.material_index, bench.materials
    finally:
        bench.free()


def measure(name, path, sweep: bool) -> dict:

    from vsgl_addon.renderer import FrameRenderer

    settings, truth, description = scene_with_truth(name, path, WIDTH, HEIGHT)
    material_index, materials = _material_index(description)
    renderer = FrameRenderer()
    out = {"scene": name, "settings": str(settings)}
    try:
        images = {"Cycles": truth["indirect"]}
        variants = [("vsgl", False, True), ("mrp", True, True)]
        if name in MIRROR_SCENES:
            variants.append(("mrp_unshadowed", True, False))
        for label, on, mirror in variants:
            frame = _frame(renderer, description, settings.overridden(glossy_reflectors=on), mirror)
            if mirror:
                images["VSGLs alone" if not on else "with MRP-ASG"] = frame.indirect_diffuse + frame.indirect_specular
            errors = Errors(truth, frame.coverage)
            figures = errors(frame.indirect_diffuse, frame.indirect_specular)
            ours = (frame.indirect_diffuse + frame.indirect_specular).astype(np.float64)
            regions = errors.by_region(ours, material_index, materials)
            out[label] = {"rel": figures["rel"], "rel_specular": figures["rel_specular"],
                          "mean_ratio": figures["mean_ratio"], "share_specular": figures["share_specular"],
                          "proxies": int(frame.counts.get("proxies", 0)),
                          "vsgl_shading_seconds": float(frame.timings["vsgl_shading"]),
                          "mrp_seconds": float(frame.timings.get("mrp_asg", 0.0)),
                          "frame_seconds": float(sum(frame.timings.values())),
                          "regions": {k: {"mean_ratio": v["mean_ratio"], "error_share": v["error_share"]}
                                      for k, v in regions.items()}}
        out["cost_ratio"] = out["mrp"]["mrp_seconds"] / out["mrp"]["vsgl_shading_seconds"]
        if name in REGION_SCENES:
            comparison(images, RESULTS_DIR / f"mrp_asg_{name}_indirect.png", name)
        if sweep and out["mrp"]["proxies"]:
            rows = []
            for radius in RADII:
                frame = _frame(renderer, description, settings.overridden(disk_radius=radius))
                errors = Errors(truth, frame.coverage)
                figures = errors(frame.indirect_diffuse, frame.indirect_specular)
                regions = errors.by_region((frame.indirect_diffuse + frame.indirect_specular).astype(np.float64),
                                           material_index, materials)
                rows.append({"radius": radius, "rel": figures["rel"], "rel_specular": figures["rel_specular"],
                             "region_means": {k: v["mean_ratio"] for k, v in regions.items()},
                             "mrp_seconds": float(frame.timings["mrp_asg"]),
                             "vsgl_shading_seconds": float(frame.timings["vsgl_shading"])})
            out["sweep"] = rows
    finally:
        renderer.free()
    return out


def comparison(images, path: Path, title: str) -> None:
    """Indirect light side by side (x / (1 + x) tone map, sRGB-like gamma; row 0 = bottom)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    order = ["VSGLs alone", "with MRP-ASG", "Cycles"]
    figure, axes = plt.subplots(1, 3, figsize=(10.5, 2.9))
    for axis, label in zip(axes, order):
        image = np.clip(np.asarray(images[label], np.float64)[..., :3], 0.0, None)
        axis.imshow((image / (1.0 + image)) ** (1.0 / 2.2), origin="lower")
        axis.set_title(f"{title}: {label}", fontsize=9)
        axis.axis("off")
    figure.tight_layout()
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=100)
    plt.close(figure)


def markdown(results) -> str:
    lines = ["| scene | proxies | indirect specular rel. RMSE, VSGL → MRP-ASG | total indirect rel. RMSE, VSGL → MRP-ASG "
             "| mean ours/Cycles, VSGL → MRP-ASG | MRP-ASG / VSGL shading time |", "|---|---|---|---|---|---|"]
    for r in results:
        v, m = r["vsgl"], r["mrp"]
        lines.append(f"| {r['scene']} | {m['proxies']} | {v['rel_specular']:.3f} → {m['rel_specular']:.3f} | "
                     f"{v['rel']:.3f} → {m['rel']:.3f} | {v['mean_ratio']:.3f} → {m['mean_ratio']:.3f} | "
                     f"{r['cost_ratio']:.3f} |")
    lines += ["", "Per material, mean ours / Cycles (VSGL → MRP-ASG):", ""]
    for r in results:
        if r["scene"] in REGION_SCENES:
            for material, v in r["vsgl"]["regions"].items():
                m = r["mrp"]["regions"][material]
                lines.append(f"- {r['scene']}, {material}: {v['mean_ratio']:.3f} → {m['mean_ratio']:.3f} "
                             f"(error share {v['error_share']:.2f} → {m['error_share']:.2f})")
    for r in results:
        if "mrp_unshadowed" in r:
            u, m = r["mrp_unshadowed"], r["mrp"]
            lines += ["", f"MRP-ASG's proxy-to-receiver shadows (mirror shadow maps) on {r['scene']}, without → with:", "",
                      f"- indirect specular rel. RMSE {u['rel_specular']:.3f} → {m['rel_specular']:.3f}, "
                      f"total {u['rel']:.3f} → {m['rel']:.3f}, mean ours/Cycles {u['mean_ratio']:.3f} → "
                      f"{m['mean_ratio']:.3f}"]
            for material, v in u["regions"].items():
                w = m["regions"][material]
                lines.append(f"- {material}: mean ours/Cycles {v['mean_ratio']:.3f} → {w['mean_ratio']:.3f} "
                             f"(error share {v['error_share']:.2f} → {w['error_share']:.2f})")
    for r in results:
        if "sweep" in r:
            lines += ["", f"Disk-radius sweep, {r['scene']}:", "",
                      "| r_d (m) | indirect specular rel. RMSE | total rel. RMSE | mean ours/Cycles per material | "
                      "MRP-ASG time (ms) | MRP-ASG / VSGL shading |",
                      "|---|---|---|---|---|---|"]
            for s in r["sweep"]:
                means = ", ".join(f"{k} {v:.3f}" for k, v in s["region_means"].items())
                lines.append(f"| {s['radius']:g} | {s['rel_specular']:.3f} | {s['rel']:.3f} | {means} | "
                             f"{s['mrp_seconds'] * 1e3:.1f} | {s['mrp_seconds'] / s['vsgl_shading_seconds']:.3f} |")
    return "\n".join(lines) + "\n"


def plot(results, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (error_axis, time_axis) = plt.subplots(1, 2, figsize=(9, 3.5))
    for r in results:
        if "sweep" not in r:
            continue
        radii = [s["radius"] for s in r["sweep"]]
        error_axis.plot(radii, [s["rel_specular"] for s in r["sweep"]], "o-", label=f"{r['scene']} specular")
        error_axis.plot(radii, [s["rel"] for s in r["sweep"]], "s--", label=f"{r['scene']} total")
        error_axis.axhline(r["vsgl"]["rel_specular"], ls=":", color="grey")
        time_axis.plot(radii, [s["mrp_seconds"] * 1e3 for s in r["sweep"]], "o-", label=r["scene"])
    for axis in (error_axis, time_axis):
        axis.set_xscale("log")
        axis.set_xlabel("disk radius r_d (m)")
        axis.legend(fontsize=7)
    error_axis.set_ylabel("relative RMSE vs Cycles (dotted: VSGL alone, specular)")
    time_axis.set_ylabel("MRP-ASG pass (ms, llvmpipe)")
    figure.tight_layout()
    figure.savefig(path, dpi=110)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+")
    parser.add_argument("--no-sweep", action="store_true")
    args = parser.parse_args(argv)
    from vsgl_addon import register, unregister
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    ensure_gpu_context()
    results = []
    try:
        for name, path, _ in suite():
            if args.only and name not in args.only:
                continue
            log(f"{name} ...")
            results.append(measure(name, path, not args.no_sweep and name in SWEEP_SCENES))
    finally:
        unregister()
    text = markdown(results)
    suffix = "" if not args.only else "_" + "_".join(args.only)
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    (RESULTS_DIR / f"mrp_asg_suite{suffix}.md").write_text(text, encoding="utf-8")
    (RESULTS_DIR / f"mrp_asg_suite{suffix}.json").write_text(json.dumps(results, indent=2), encoding="utf-8")
    if any("sweep" in r for r in results):
        plot(results, RESULTS_DIR / f"mrp_asg_disk_radius{suffix}.png")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
