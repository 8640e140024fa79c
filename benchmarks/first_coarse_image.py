# SPDX-License-Identifier: GPL-3.0-or-later
"""Change → first coarse image in the Rendered viewport's pipeline, without the window (not a test).

    .venv/bin/python benchmarks/first_coarse_image.py [--baseline REV] [--rounds 2] [--repeats 4]
                                                      [--scene demo] [--output STEM] [--no-write]

demo.blend with its saved settings, a view_pipeline.ViewPipeline on the real passes (bpy module,
llvmpipe) through the camera at 1311 × 786 (the window of benchmarks/interactive.py), scale 0.25: the
first light is moved and the pipeline stepped once (the light passes of the new state, then the
coarse image), ``--repeats`` times per process after one warm-up move that compiles the shaders.
Per step: its seconds, its light passes' and its view render's. Variants, each in ``--rounds`` fresh
processes, alternating round by round (checkout_ab.alternate; absolute times are noisy on this shared
2-core machine, read the ratios): this checkout with the preview's light passes
(view_pipeline.preview_light_settings) and without (``preview_lights=False``: the settings' own, as
before), and with ``--baseline REV`` an export of commit REV. Each current process also steps the
pipeline until its samples converged (2 samples at 164 × 98) with and without the preview and
compares the two accumulated images (they must be identical) and the coarse images against the
converged one per pass (combined, indirect diffuse, indirect specular: relative RMSE and mean).
Writes benchmarks/results/first_coarse_image.{md,json} (``--output`` another stem) unless --no-write.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

from checkout_ab import REPO, alternate, extract_commit, open_scene, run_child, write_results
REGION = (1311, 786)
SCALE = 0.25
CONVERGE_REGION = (164, 98)
CONVERGE_SAMPLES = 2


def measure(repo: Path, scene: str, repeats: int, preview: bool | None) -> dict:
    """The steps in this process, the add-on imported from ``repo``; ``preview`` None: the
    checkout's ViewPipeline as it is (a baseline without the option)."""
    bpy, settings, light = open_scene(repo, scene)
    import numpy as np

    from vsgl_addon.scene import extract_scene
    from vsgl_addon.view_pipeline import ViewPipeline

    def describe():
        return extract_scene(bpy.context.evaluated_depsgraph_get())

    def pipeline_of():
        return ViewPipeline() if preview is None else ViewPipeline(preview_lights=preview)

    camera = describe().camera
    view, projection = camera.view_matrix(), camera.projection_matrix()
    steps = []
    pipeline = pipeline_of()
    try:
        pipeline.request_view(view, projection, REGION)
        for index in range(repeats + 1):
            light.location.x += 0.05 * (1 if index % 2 == 0 else -1)
            bpy.context.view_layer.update()
            pipeline.mark_scene_dirty()
            pipeline.step(describe, settings, SCALE, 2)
            entry = pipeline.history[-1]
            if "error" in entry:
                raise RuntimeError(entry["error"])
            if index:
                steps.append({"seconds": entry["seconds"], "light_seconds": entry.get("light_seconds", 0.0),
                              "view_seconds": entry.get("view_seconds", 0.0), "size": list(entry.get("size") or ()),
                              "preview_lights": bool(entry.get("preview_lights", False))})
    finally:
        pipeline.free()
    row = {"steps": steps}
    if preview is not None:
        row["converged"] = converged_images(bpy, np, describe, settings, view, projection)
    return row


#: The passes whose coarse image is compared with the converged one.
COMPARED_PASSES = ("combined", "indirect_diffuse", "indirect_specular")


def _draw(pipeline, np, size, view_pass="combined"):
    import gpu

    offscreen = gpu.types.GPUOffScreen(*size, format="RGBA32F")
    try:
        with offscreen.bind():
            framebuffer = gpu.state.active_framebuffer_get()
            framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0))
            gpu.state.viewport_set(0, 0, *size)
            assert pipeline.draw(view_pass)
            buffer = framebuffer.read_color(0, 0, size[0], size[1], 4, 0, "FLOAT")
        buffer.dimensions = size[0] * size[1] * 4
        return np.array(buffer, np.float32).reshape(size[1], size[0], 4)[..., :3]
    finally:
        offscreen.free()


def converged_images(bpy, np, describe, settings, view, projection) -> dict:
    """With and without the preview: the coarse image and the converged one at CONVERGE_REGION, per
    pass of COMPARED_PASSES (the coarse image's relative RMSE and mean against the converged one
    without the preview)."""
    from vsgl_addon.view_pipeline import ViewPipeline

    images = {}
    for preview in (True, False):
        pipeline = ViewPipeline(step_budget=1e9, preview_lights=preview)
        try:
            pipeline.request_view(view, projection, CONVERGE_REGION)
            pipeline.step(describe, settings, SCALE, CONVERGE_SAMPLES)
            for view_pass in COMPARED_PASSES:
                images[("coarse", preview, view_pass)] = _draw(pipeline, np, CONVERGE_REGION, view_pass)
            while pipeline.step(describe, settings, SCALE, CONVERGE_SAMPLES) is not None:
                pass
            for view_pass in COMPARED_PASSES:
                images[("converged", preview, view_pass)] = _draw(pipeline, np, CONVERGE_REGION, view_pass)
        finally:
            pipeline.free()
    result = {"identical": all(np.array_equal(images[("converged", True, p)], images[("converged", False, p)])
                               for p in COMPARED_PASSES),
              "largest_difference": max(float(np.max(np.abs(images[("converged", True, p)] - images[("converged", False, p)])))
                                        for p in COMPARED_PASSES)}
    for view_pass in COMPARED_PASSES:
        reference = images[("converged", False, view_pass)].astype(np.float64)
        norm = float(np.sqrt(np.mean(reference ** 2)))
        for preview, name in ((True, "preview"), (False, "full")):
            image = images[("coarse", preview, view_pass)].astype(np.float64)
            suffix = "" if view_pass == "combined" else f"_{view_pass}"
            result[f"coarse_rmse_{name}{suffix}"] = float(np.sqrt(np.mean((image - reference) ** 2)) / max(norm, 1e-30))
            result[f"coarse_mean_{name}{suffix}"] = float(image.mean() / max(reference.mean(), 1e-30))
    return result


def _median(steps, key):
    return statistics.median(step[key] for step in steps)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="demo")
    parser.add_argument("--repeats", type=int, default=4)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--baseline", default=None)
    parser.add_argument("--no-write", action="store_true")
    parser.add_argument("--output", default="first_coarse_image", help="results' file stem (benchmarks/results)")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--repo", type=Path, default=REPO, help=argparse.SUPPRESS)
    arguments = parser.parse_args(argv)
    if arguments.child is not None:
        preview = {"on": True, "off": False, "as-is": None}[arguments.child]
        print(json.dumps(measure(arguments.repo, arguments.scene, arguments.repeats, preview)))
        return 0

    with tempfile.TemporaryDirectory() as temporary:
        variants = [("preview", REPO), ("no preview", REPO)]
        if arguments.baseline is not None:
            variants.append((arguments.baseline, extract_commit(arguments.baseline, Path(temporary) / "baseline")))
        child = {"preview": "on", "no preview": "off"}

        def run(label, repo):
            return run_child(Path(__file__).resolve(), ["--child", child.get(label, "as-is"), "--repo", str(repo),
                                                        "--scene", arguments.scene, "--repeats", str(arguments.repeats)],
                             sys.executable, timeout=3600)

        results = alternate(variants, arguments.rounds, run)
    rows = {}
    for label, _ in variants:
        steps = [step for child_row in results[label] for step in child_row["steps"]]
        rows[label] = {"seconds": _median(steps, "seconds"), "light_seconds": _median(steps, "light_seconds"),
                       "view_seconds": _median(steps, "view_seconds"), "steps": steps,
                       "converged": [child_row.get("converged") for child_row in results[label] if "converged" in child_row]}
    print(json.dumps({label: {key: row[key] for key in ("seconds", "light_seconds", "view_seconds")}
                      for label, row in rows.items()}))
    if arguments.no_write:
        return 0
    reference = arguments.baseline or "no preview"
    lines = ["# Change → first coarse image, without the window\n",
             f"{arguments.scene}, its saved settings, a light moved, {REGION[0]}×{REGION[1]} at scale {SCALE}; "
             f"median of {arguments.rounds} processes × {arguments.repeats} steps per variant, alternating "
             "(benchmarks/first_coarse_image.py), ms. The step is the light passes of the new state and the "
             "coarse image (its view render: passes, full-resolution guide, resolve).\n",
             f"| variant | step | light passes | view render | coarse image (median pixels) | step / {reference} |",
             "|---|---|---|---|---|---|"]
    for label, row in rows.items():
        pixels = statistics.median(step["size"][0] * step["size"][1] for step in row["steps"] if step["size"])
        lines.append(f"| {label} | {1000 * row['seconds']:.0f} | {1000 * row['light_seconds']:.0f} | "
                     f"{1000 * row['view_seconds']:.0f} | {pixels:.0f} | {row['seconds'] / rows[reference]['seconds']:.2f} |")
    checks = [c for c in rows["preview"]["converged"] + rows["no preview"]["converged"] if c]
    if checks:
        lines.append(f"\nConverged ({CONVERGE_SAMPLES} samples at {CONVERGE_REGION[0]}×{CONVERGE_REGION[1]}) with "
                     "and without the preview: "
                     + ("identical" if all(c["identical"] for c in checks) else "DIFFERENT")
                     + f" in {len(checks)} of {len(checks)} processes (largest difference "
                     f"{max(c['largest_difference'] for c in checks):.1e}). The coarse image against that "
                     "converged image, per pass (median over the processes; mean: the coarse image's / the "
                     "converged one's):\n")
        lines += ["| pass | rel RMSE, preview | rel RMSE, without | mean, preview | mean, without |",
                  "|---|---|---|---|---|"]
        for view_pass in COMPARED_PASSES:
            suffix = "" if view_pass == "combined" else f"_{view_pass}"
            figures = [statistics.median(c[f"coarse_{kind}_{name}{suffix}"] for c in checks)
                       for kind in ("rmse", "mean") for name in ("preview", "full")]
            lines.append(f"| {view_pass} | " + " | ".join(f"{value:.3f}" for value in figures) + " |")
    write_results(arguments.output, rows, "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
