# SPDX-License-Identifier: GPL-3.0-or-later
"""The Rendered viewport's steps after a light move, without the window (not a test).

    .venv/bin/python benchmarks/refinement_steps.py [--baseline REV] [--rounds 2] [--repeats 3]
                                                    [--steps 24] [--no-write]

demo.blend with its saved settings, a view_pipeline.ViewPipeline on the real passes (bpy module,
llvmpipe) through the camera at 1311 × 786, scale 0.25 (the window of benchmarks/interactive.py):
after a warm-up move, the first light is moved ``--repeats`` times and the pipeline stepped
``--steps`` times after each move (the coarse image, then the samples' light passes and bands).
Per step its kind: the coarse image (light passes and view), a step of the samples' light passes
(a whole build before the staged builds, a part of one since), a band. After the moves, one more
move and the steps until the first full-resolution sample is complete: their summed time (the work
of one sample at 1311 × 786), their count and the longest. Variants in ``--rounds``
fresh processes each, alternating (checkout_ab.alternate; the shared 2-core machine's load varies:
read the ratios): this checkout and, with ``--baseline REV``, an export of commit REV. Each process
also converges 2 samples at 164 × 98 with the default step budget (so the staged builds are split)
and saves the drawn image: the two checkouts' images are compared (they must be identical).
Writes benchmarks/results/refinement_steps.{md,json} unless --no-write.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from checkout_ab import REPO, alternate, extract_commit, open_scene, run_child, write_results  # noqa: E402
from first_coarse_image import _draw  # noqa: E402

REGION = (1311, 786)
SCALE = 0.25
BUDGET = 0.06
CONVERGE_REGION = (164, 98)


def measure(repo: Path, repeats: int, steps: int, image: Path) -> dict:
    bpy, settings, light = open_scene(repo, "demo")
    import numpy as np

    from vsgl_addon.scene import extract_scene
    from vsgl_addon.view_pipeline import ViewPipeline

    def describe():
        return extract_scene(bpy.context.evaluated_depsgraph_get())

    camera = describe().camera
    view, projection = camera.view_matrix(), camera.projection_matrix()
    moves = []
    pipeline = ViewPipeline()
    try:
        pipeline.request_view(view, projection, REGION)
        for index in range(repeats + 1):
            light.location.x += 0.05 * (1 if index % 2 == 0 else -1)
            bpy.context.view_layer.update()
            pipeline.mark_scene_dirty()
            first = pipeline.steps
            for _ in range(steps):
                pipeline.step(describe, settings, SCALE, 8)
            entries = [e for e in pipeline.history if e["index"] >= first]
            if any("error" in e for e in entries):
                raise RuntimeError(next(e["error"] for e in entries if "error" in e))
            if index:
                moves.append([{"work": e["work"], "seconds": e["seconds"],
                               "light": "light_seconds" in e and e["work"] != "lights",
                               "complete": e.get("lights_complete", "light_seconds" in e)} for e in entries])
        # One more move, then steps until the first full-resolution sample is in: its work.
        light.location.x += 0.05
        bpy.context.view_layer.update()
        pipeline.mark_scene_dirty()
        pipeline.step(describe, settings, SCALE, 8)
        sample_steps = []
        while pipeline.samples < 1 and len(sample_steps) < 20000:
            pipeline.step(describe, settings, SCALE, 8)
            sample_steps.append(pipeline.history[-1]["seconds"])
        full_sample = {"seconds": sum(sample_steps), "steps": len(sample_steps), "max": max(sample_steps)}
    finally:
        pipeline.free()
    converge = ViewPipeline()
    try:
        converge.request_view(view, projection, CONVERGE_REGION)
        while converge.step(describe, settings, SCALE, 2) is not None:
            pass
        np.save(image, _draw(converge, np, CONVERGE_REGION))
    finally:
        converge.free()
    return {"moves": moves, "full_sample": full_sample}


def summarise(children: list[dict]) -> dict:
    moves = [m for child in children for m in child["moves"]]
    coarse = [m[0]["seconds"] for m in moves]
    refinement = [s for m in moves for s in m[1:]]
    light = [s["seconds"] for s in refinement if s["light"]]
    bands = [s["seconds"] for s in refinement if not s["light"]]
    seconds = [s["seconds"] for s in refinement]
    return {"coarse_ms": statistics.median(coarse) * 1000,
            "refinement_median_ms": statistics.median(seconds) * 1000, "refinement_max_ms": max(seconds) * 1000,
            "over_budget": sum(s > BUDGET for s in seconds) / len(seconds),
            "light_step_median_ms": statistics.median(light) * 1000 if light else None,
            "light_step_max_ms": max(light) * 1000 if light else None, "light_steps": len(light),
            "builds": sum(1 for s in refinement if s["light"] and s["complete"]),
            "band_median_ms": statistics.median(bands) * 1000, "band_max_ms": max(bands) * 1000,
            "steps": len(refinement),
            "full_sample_s": statistics.median(child["full_sample"]["seconds"] for child in children),
            "full_sample_steps": statistics.median(child["full_sample"]["steps"] for child in children),
            "full_sample_max_ms": max(child["full_sample"]["max"] for child in children) * 1000}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", default=None)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--steps", type=int, default=24)
    parser.add_argument("--no-write", action="store_true")
    parser.add_argument("--child", type=Path, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--repo", type=Path, default=REPO, help=argparse.SUPPRESS)
    arguments = parser.parse_args(argv)
    if arguments.child is not None:
        print(json.dumps(measure(arguments.repo, arguments.repeats, arguments.steps, arguments.child)))
        return 0
    import numpy as np

    with tempfile.TemporaryDirectory() as temporary:
        temporary = Path(temporary)
        variants = [("current", REPO)]
        if arguments.baseline:
            variants.insert(0, ("baseline", extract_commit(arguments.baseline, temporary / "baseline")))
        counter = iter(range(10 ** 6))
        children = alternate(variants, arguments.rounds, lambda label, repo: run_child(
            Path(__file__), ["--child", str(temporary / f"{label}_{next(counter)}.npy"), "--repo", str(repo),
                             "--repeats", str(arguments.repeats), "--steps", str(arguments.steps)],
            sys.executable, timeout=3600))
        rows = {label: summarise(children[label]) for label, _ in variants}
        images = {label: [np.load(path) for path in sorted(temporary.glob(f"{label}_*.npy"))] for label, _ in variants}

        def differ(old, new):
            return float(np.abs(old - new).max() / max(float(np.abs(old).max()), 1e-30))

        # The bands are sized by measured times, and the VPLs' denoise filters within a band's rows
        # (docs/architecture.md): two processes of one checkout may differ at band edges.
        difference = {f"{label} vs {label}": max(differ(images[label][0], other) for other in images[label][1:])
                      for label, _ in variants if len(images[label]) > 1}
        if arguments.baseline:
            difference["baseline vs current"] = max(differ(old, new) for old in images["baseline"]
                                                    for new in images["current"])
    labels = [label for label, _ in variants]
    lines = ["| | " + " | ".join(labels) + (" | after / before |" if len(labels) == 2 else " |"),
             "|---|" + "---|" * (len(labels) + (len(labels) == 2))]
    for key, name in (("coarse_ms", "change → first image (the coarse step)"),
                      ("refinement_median_ms", "refinement step median"), ("refinement_max_ms", "refinement step max"),
                      ("light_step_median_ms", "samples' light-pass step median"),
                      ("light_step_max_ms", "samples' light-pass step max"),
                      ("band_median_ms", "band median"), ("band_max_ms", "band max"),
                      ("full_sample_s", "first full-resolution sample after a move: work (s)"),
                      ("full_sample_steps", "its steps"), ("full_sample_max_ms", "its longest step")):
        values = [rows[label][key] for label in labels]
        ratio = f" {values[1] / values[0]:.2f} |" if len(values) == 2 and None not in values else ""
        digits = 1 if key == "full_sample_s" else 0
        lines.append(f"| {name} | " + " | ".join("–" if v is None else f"{v:.{digits}f}" for v in values) + f" |{ratio}")
    lines.append("| refinement steps > 60 ms | " + " | ".join(f"{100 * rows[l]['over_budget']:.0f} %" for l in labels)
                 + " |" + (" |" if len(labels) == 2 else ""))
    lines.append("| light-pass steps / builds completed | " + " | ".join(
        f"{rows[l]['light_steps']} / {rows[l]['builds']}" for l in labels) + " |" + (" |" if len(labels) == 2 else ""))
    text = "\n".join(lines)
    print(text)
    print(f"converged image (2 samples at 164×98), largest difference over largest value: {difference}")
    if not arguments.no_write:
        import os

        command = "    .venv/bin/python benchmarks/refinement_steps.py " + " ".join(argv if argv is not None else sys.argv[1:])
        write_results("refinement_steps", {"rows": rows, "image_difference": difference, "children": children},
                      "# The Rendered viewport's steps after a light move, without the window\n\n"
                      f"demo.blend, its saved settings, 1311×786 at scale 0.25, {arguments.steps} steps after each of "
                      f"{arguments.repeats} moves per process, {arguments.rounds} processes per checkout alternating; "
                      "medians, ms." + (f" Before: commit {arguments.baseline}; after: this checkout." if arguments.baseline else "")
                      + f" Load average at the end: {os.getloadavg()[0]:.2f}. Command:\n\n{command}\n\n{text}\n\n"
                      + "Converged image (2 samples at 164×98, default step budget: the staged builds split), "
                      "largest absolute difference over the largest value between processes: "
                      + ", ".join(f"{k} {v:.1e}" for k, v in difference.items()) + ".\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
