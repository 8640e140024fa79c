# SPDX-License-Identifier: GPL-3.0-or-later
"""Glossy VPLs with stochastic light culling (004) on the suite's caustic_panel scene, against its
cached Cycles truth (not a test). It composes the pass by hand, unshadowed, to isolate the culling:
δ's time and error against brute force (the renderer's frame with the pass, visibility and the
filter is measured by benchmarks/validation_suite.py).

    .venv/bin/python benchmarks/vpl_caustics.py [--deltas 1e-5 1e-4 1e-3 1e-2] [--samples S]

Per light: its RSM views (the scene's RSM size), every texel of a sharp reflector (GGX alpha =
roughness^2 < alpha_c, the scene's caustic_roughness) as a glossy VPL (flux Phi Rs from the RSM,
w_i towards the light); the tiled pass shades the camera G-buffer's diffuse lobes. Images, all
unshadowed (the scene has no occluder between panel and wall):

* off: VSGLs alone (every reflector's flux), diffuse + specular;
* on: the diffuse receivers' VSGLs without the sharp reflectors' specular flux (the rectangle
  proxies' split, passes/rsm.py) + the VPL image, and the same specular image as off;
* VPL alone, and brute force (delta = 0, every VPL).

Figures: relative RMSE over covered pixels and the mean inside the caustic region (Cycles' brightest
2 % of covered pixels), against the truth; per delta the culling + shading time relative to brute
force, VPLs listed per pixel, and the VPL image's relative RMSE against brute force (S frames
averaged). Writes benchmarks/results/vpl_caustics.{md,json} and vpl_caustics_delta.png.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(REPO / "tools"))

from build_validation_scenes import scene_path  # noqa: E402
from gpu_timing import finish  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.truth import load_reference  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
WIDTH, HEIGHT = 240, 180
CAUSTIC_FRACTION = 0.02


def collect_vpls(bench, description, settings):
    from vsgl_addon.passes.rsm import render_rsm_views
    from vsgl_addon.reference import rsm as rsm_ref
    from vsgl_addon.reference import vpl_culling as vc

    parts = []
    for index, light in enumerate(description.lights):
        for view in render_rsm_views(bench.scene_gpu, index, size=settings.rsm_size):
            arrays = view.to_numpy()
            view.free()
            position = arrays.rsm.position
            incoming = rsm_ref.incoming_directions(light, position)
            vpls = vc.glossy_vpls_from_rsm(position, arrays.rsm.normal, incoming, arrays.rsm.flux_specular,
                                           np.ones_like(arrays.rsm.flux_specular), arrays.roughness ** 2,
                                           settings.caustic_roughness)
            parts.append(vpls)
    keys = ("position", "normal", "incoming", "flux", "rs", "roughness")
    return {k: np.concatenate([p[k] for p in parts]) if parts else np.zeros((0, 3)) for k in keys}


def vpl_image(bench, description, vpls, delta, seed=0, frame=0):
    from vsgl_addon.passes import vpl_culling

    camera = description.camera
    start = time.perf_counter()
    result = vpl_culling.run(bench.inputs.position, bench.inputs.normal, bench.inputs.diffuse_reflectance, vpls,
                             camera.view_matrix(), camera.projection_matrix(), delta, seed, frame)
    finish(result.radiance)
    seconds = time.perf_counter() - start
    image = result.read()[..., :3].astype(np.float64)
    counts = result.read_counts()
    result.free()
    return image, seconds, counts


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--deltas", type=float, nargs="+", default=[1e-5, 1e-4, 1e-3, 1e-2])
    parser.add_argument("--samples", type=int, default=4)
    args = parser.parse_args(argv)

    import bpy

    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.pipeline import render_scene_vsgls
    from vsgl_addon.renderer import scene_proxies
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    from vsgl_addon import register

    register()  # scene.vsgl exists only with the add-on registered
    ensure_gpu_context()
    path = scene_path("caustic_panel")
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    scene = bpy.context.scene
    settings = VSGLSettings.from_properties(scene.vsgl)
    truth = load_reference(scene, WIDTH, HEIGHT, 8192, False, name="caustic_panel", source=path, dtype=np.float16)
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    bench = Bench(description, WIDTH, HEIGHT)
    try:
        mask = bench.coverage > 0.0
        target = truth["indirect"].astype(np.float64)
        a = (truth["diffuse_a"] + truth["glossy_a"]).astype(np.float64)
        b = (truth["diffuse_b"] + truth["glossy_b"]).astype(np.float64)
        luminance = target[mask].mean(axis=-1)
        caustic = np.zeros_like(mask)
        caustic[mask] = luminance >= np.quantile(luminance, 1.0 - CAUSTIC_FRACTION)

        def figures(image):
            x = image[mask]
            corrected = np.sqrt(max(float(np.mean((x - a[mask]) * (x - b[mask]))), 0.0))
            return {"rel": corrected / float(target[mask].mean()),
                    "caustic_mean": float(image[caustic].mean()),
                    "caustic_ratio": float(image[caustic].mean() / target[caustic].mean()),
                    "mean_ratio": float(x.mean() / target[mask].mean())}

        unshadowed = settings.overridden(visibility=False)
        whole, _ = bench.vsgls(unshadowed)
        diffuse_all, specular_all, _ = bench.shade(whole.tables())
        whole.free()
        proxies = [proxy for proxy, _ in scene_proxies(description, settings)]
        split = render_scene_vsgls(bench.scene_gpu, unshadowed, receiver_lobe="glossy", proxies=proxies)
        diffuse_split, _, _ = bench.shade(split.tables())
        split.free()
        vpls = collect_vpls(bench, description, settings)
        brute, brute_seconds, _ = vpl_image(bench, description, vpls, 0.0)
        vpl_image(bench, description, vpls, 0.0)  # warm
        brute, brute_seconds, _ = vpl_image(bench, description, vpls, 0.0)
        rows = {"vpls": int(len(vpls["roughness"])), "proxies": len(proxies), "truth_mean": float(target[mask].mean()),
                "truth_caustic_mean": float(target[caustic].mean()), "brute_seconds": brute_seconds}
        rows["off"] = figures(diffuse_all + specular_all)
        rows["on_brute"] = figures(diffuse_split + brute + specular_all)
        rows["vpl_alone_brute"] = figures(brute)
        rows["vsgl_without_cell"] = figures(diffuse_split + specular_all)
        sweep = []
        for delta in args.deltas:
            total = np.zeros_like(brute)
            seconds = 0.0
            listed = 0.0
            for frame in range(args.samples):
                image, s, counts = vpl_image(bench, description, vpls, delta, 0, frame)
                total += image
                seconds += s
                listed += counts.sum() * 256 / (WIDTH * HEIGHT)
            image = total / args.samples
            ref = brute[mask]
            rel_vs_brute = float(np.sqrt(np.mean((image[mask] - ref) ** 2)) / max(ref.mean(), 1e-30))
            on = figures(diffuse_split + image + specular_all)
            sweep.append({"delta": delta, "seconds_per_frame": seconds / args.samples,
                          "time_vs_brute": seconds / args.samples / brute_seconds,
                          "listed_per_pixel": listed / args.samples, "rel_vs_brute": rel_vs_brute,
                          "on": on})
            print(f"delta {delta:g}: time {sweep[-1]['time_vs_brute']:.3f}x brute, rel vs brute {rel_vs_brute:.3f}, "
                  f"listed/px {sweep[-1]['listed_per_pixel']:.1f}, on rel {on['rel']:.3f} caustic {on['caustic_ratio']:.3f}",
                  flush=True)
        rows["sweep"] = sweep
    finally:
        bench.free()
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "vpl_caustics.json").write_text(json.dumps(rows, indent=2))
    lines = ["# Glossy VPLs on caustic_panel (240x180, unshadowed, against Cycles)", "",
             f"VPLs: {rows['vpls']}; Cycles mean {rows['truth_mean']:.4g}, caustic region mean "
             f"{rows['truth_caustic_mean']:.4g}", "",
             "| image | rel RMSE | mean / Cycles | caustic mean / Cycles |", "|---|---|---|---|"]
    for key in ("off", "vsgl_without_cell", "vpl_alone_brute", "on_brute"):
        f = rows[key]
        lines.append(f"| {key} | {f['rel']:.3f} | {f['mean_ratio']:.3f} | {f['caustic_ratio']:.3f} |")
    lines += ["", f"| delta | time / brute | listed per pixel | rel RMSE vs brute (S={args.samples}) | on: rel RMSE | on: caustic / Cycles |",
              "|---|---|---|---|---|---|"]
    for s in rows["sweep"]:
        lines.append(f"| {s['delta']:g} | {s['time_vs_brute']:.3f} | {s['listed_per_pixel']:.1f} | {s['rel_vs_brute']:.3f} "
                     f"| {s['on']['rel']:.3f} | {s['on']['caustic_ratio']:.3f} |")
    text = "\n".join(lines) + "\n"
    (RESULTS / "vpl_caustics.md").write_text(text)
    print(text)
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(5, 3.5))
        ax.loglog([s["time_vs_brute"] for s in rows["sweep"]], [max(s["rel_vs_brute"], 1e-6) for s in rows["sweep"]], "o-")
        for s in rows["sweep"]:
            ax.annotate(f"δ={s['delta']:g}", (s["time_vs_brute"], max(s["rel_vs_brute"], 1e-6)))
        ax.set_xlabel("time / brute force")
        ax.set_ylabel(f"relative RMSE vs brute force (S={args.samples})")
        fig.tight_layout()
        fig.savefig(RESULTS / "vpl_caustics_delta.png", dpi=100)
    except ImportError:
        print("matplotlib missing: no plot")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
