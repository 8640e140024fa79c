# SPDX-License-Identifier: GPL-3.0-or-later
"""Budget mode's first coarse image in the viewport: predicted against measured (not a test).

    .venv/bin/python benchmarks/budget_coarse_prediction.py [--baseline REV] [--scenes demo ...]
                                                            [--rounds 2] [--repeats 4] [--no-write]

Per scene: its saved settings in Manual mode, a view_pipeline.ViewPipeline through the camera at
1311 × 786 (the window of benchmarks/interactive.py), scale 0.25, stepped until its coarse image
keeps a guide; then the settings switch to Budget (60 ms), as an artist does in the panel, and the
pipeline is stepped until the coarse image of the new light passes. That image's size is the one
budget.coarse_factor picked from the cost model (built in: no calibration in the cache), and its
entry holds the predicted and the measured view render (view passes, resolve) and the whole step
(light passes included). ``--repeats`` fresh pipelines per process, ``--rounds`` processes per
checkout, alternating with ``--baseline REV`` (absolute times are noisy on this shared 2-core
machine). Writes benchmarks/results/budget_coarse_prediction.{md,json} unless --no-write.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from checkout_ab import (add_scene_arguments, baseline_sentence, child_arguments, compare_scenes, open_scene,
                         run_as_child, write_results)

REGION = (1311, 786)
SCALE = 0.25
BUDGET_MS = 60.0
SCENES = ("demo", "cornell_box", "polished_metal_floor")


def measure(repo: Path, scene: str, repeats: int, image: Path | None) -> dict:
    bpy, settings, _ = open_scene(repo, scene)
    import numpy as np

    from vsgl_addon.scene import extract_scene
    from vsgl_addon.view_pipeline import ViewPipeline

    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    view_matrix, projection = description.camera.view_matrix(), description.camera.projection_matrix()
    budgeted = settings.overridden(quality_mode="budget", time_budget_ms=BUDGET_MS)
    entries = []
    for _ in range(repeats):
        pipeline = ViewPipeline()
        try:
            pipeline.request_view(view_matrix, projection, REGION)
            for _ in range(3):  # Manual: light passes, the coarse image, a sample band (the guide is kept)
                pipeline.step(lambda: description, settings, SCALE, 2)
            start = len(pipeline.history)
            coarse = []
            for _ in range(4):  # the switch: the new light passes, then their coarse image
                pipeline.step(lambda: description, budgeted, SCALE, 2)
                coarse = [e for e in list(pipeline.history)[start:] if e.get("level") == "coarse"]
                if coarse:
                    break
            entry = coarse[0]
            entries.append({"size": list(entry["size"]), "predicted": entry.get("predicted_view_seconds"),
                            "view": entry["view_seconds"], "step": entry["seconds"]})
        finally:
            pipeline.free()
    if image is not None:
        np.savez(image, size=np.array(entries[-1]["size"]))
    return {"entries": entries}


def _medians(children) -> dict:
    entries = [entry for child in children for entry in child["entries"]]
    return {"sizes": sorted({tuple(entry["size"]) for entry in entries}),
            "predicted": statistics.median(entry["predicted"] for entry in entries),
            "view": statistics.median(entry["view"] for entry in entries),
            "view_range": [min(entry["view"] for entry in entries), max(entry["view"] for entry in entries)],
            "step": statistics.median(entry["step"] for entry in entries),
            "step_range": [min(entry["step"] for entry in entries), max(entry["step"] for entry in entries)],
            "steps_over_budget": sum(entry["step"] > BUDGET_MS / 1000 for entry in entries),
            "steps": len(entries)}


def _summary(row: dict) -> dict:
    return {key: [round(1000 * v, 1) for v in value] if key.endswith("_range") else
            round(1000 * value, 1) if isinstance(value, float) else value for key, value in row.items()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_scene_arguments(parser, SCENES, 4, "switches to Budget per process")
    arguments = parser.parse_args(child_arguments(argv))
    if run_as_child(arguments, measure):
        return 0
    rows = compare_scenes(Path(__file__).resolve(), arguments, _medians, _summary, lambda old, new: [],
                          timeout=1800)
    if arguments.no_write:
        return 0
    lines = ["# Budget mode's first coarse image in the viewport: predicted against measured\n",
             f"Each scene's saved settings, its camera at {REGION[0]}×{REGION[1]}, scale {SCALE}, the bpy module "
             f"(llvmpipe); Manual until the guide is kept, then the switch to Budget ({BUDGET_MS:.0f} ms): the coarse "
             f"image of the new light passes, {arguments.rounds} processes × {arguments.repeats} switches per "
             "checkout (benchmarks/budget_coarse_prediction.py); ms, medians (range)." + baseline_sentence(arguments.baseline)
             + "\n",
             "| scene | checkout | coarse size | predicted view | measured view | step | steps over the budget |",
             "|---|---|---|---|---|---|---|"]
    for row in rows:
        for label in ("baseline", "current"):
            if label not in row:
                continue
            r = row[label]
            name = arguments.baseline if label == "baseline" else "this"
            lines.append(f"| {row['scene']} | {name} | {', '.join('×'.join(map(str, s)) for s in r['sizes'])} | "
                         f"{1000 * r['predicted']:.0f} | {1000 * r['view']:.0f} ({1000 * r['view_range'][0]:.0f}–"
                         f"{1000 * r['view_range'][1]:.0f}) | {1000 * r['step']:.0f} ({1000 * r['step_range'][0]:.0f}–"
                         f"{1000 * r['step_range'][1]:.0f}) | {r['steps_over_budget']} of {r['steps']} |")
    write_results("budget_coarse_prediction", rows, "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
