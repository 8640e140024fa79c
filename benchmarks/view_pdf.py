# SPDX-License-Identifier: GPL-3.0-or-later
"""The view-dependent PDF (000 §5, reference/brsm.py) against the light PDF, per suite scene (not a test).

    .venv/bin/python benchmarks/view_pdf.py [--only NAME ...] [--results-dir DIR]

Per scene of benchmarks/validation_suite.py (its cached Cycles truths, 240x180, each scene's saved
settings: N = 256, visibility on), one frame with ``pdf = light`` and one with ``pdf = view``, after
a warm-up frame: mean indirect ours / Cycles and the noise-corrected relative RMSE, and the frame
time (informative). Targets (the issue's): on a scene whose light's footprint is much larger than
the view (sun_courtyard: a sun over a 40 m ground) the view PDF's relative RMSE at least 20 % lower;
no scene worse by more than 5 %. Writes ``view_pdf.{md,json}`` and prints the markdown.
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

from validation_suite import TRUTH_SAMPLES, open_scene, suite  # noqa: E402
from tradeoff.demo import RESULTS_DIR  # noqa: E402
from tradeoff.metrics import Errors  # noqa: E402
from tradeoff.truth import load_reference  # noqa: E402

WIDTH, HEIGHT = 240, 180
LARGE_FOOTPRINT = "sun_courtyard"


def measure(name: str, path: Path) -> dict:
    import bpy

    from vsgl_addon.renderer import FrameRenderer
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    scene = open_scene(path)
    settings = VSGLSettings.from_properties(scene.vsgl)
    truth = load_reference(scene, WIDTH, HEIGHT, TRUTH_SAMPLES[name], False, name=name, source=path,
                           dtype=np.float32 if name == "demo" else np.float16)
    scene = open_scene(path)
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    renderer = FrameRenderer()
    row = {"scene": name}
    try:
        renderer.render(description, settings, WIDTH, HEIGHT)  # warm-up
        for pdf in ("light", "view"):
            frame = renderer.render(description, settings.overridden(pdf=pdf), WIDTH, HEIGHT)
            errors = Errors(truth, frame.coverage)(frame.indirect_diffuse, frame.indirect_specular)
            row[pdf] = {"mean_ratio": errors["mean_ratio"], "rel": errors["rel"],
                        "frame_seconds": float(sum(frame.timings.values())),
                        "view_pdf": frame.plan.decisions["view_pdf"].reason}
    finally:
        renderer.free()
    row["rel_change"] = row["view"]["rel"] / row["light"]["rel"] - 1.0
    print(f"{name}: rel RMSE light {row['light']['rel']:.3f}, view {row['view']['rel']:.3f} "
          f"({100 * row['rel_change']:+.1f} %)", flush=True)
    return row


def markdown(rows) -> str:
    lines = ["# View PDF (000 §5) against the light PDF", "",
             "`.venv/bin/python benchmarks/view_pdf.py`; 240×180, each scene's saved settings (N = 256, visibility "
             "on), the validation suite's cached Cycles truths; noise-corrected relative RMSE. Targets: "
             f"{LARGE_FOOTPRINT} at least 20 % lower with the view PDF, no scene worse by more than 5 %.", "",
             "| scene | mean light | mean view | rel RMSE light | rel RMSE view | change | frame ms light | "
             "frame ms view |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['light']['mean_ratio']:.3f} | {r['view']['mean_ratio']:.3f} | "
                     f"{r['light']['rel']:.3f} | {r['view']['rel']:.3f} | {100 * r['rel_change']:+.1f} % | "
                     f"{r['light']['frame_seconds'] * 1e3:.0f} | {r['view']['frame_seconds'] * 1e3:.0f} |")
    large = [r for r in rows if r["scene"] == LARGE_FOOTPRINT]
    if large:
        met = large[0]["rel_change"] <= -0.20
        lines += ["", f"{LARGE_FOOTPRINT}: {100 * large[0]['rel_change']:+.1f} % (target ≤ −20 %: "
                  f"{'met' if met else 'missed'})."]
    worst = max(rows, key=lambda r: r["rel_change"])
    lines += [f"Worst scene: {worst['scene']} {100 * worst['rel_change']:+.1f} % (target ≤ +5 %: "
              f"{'met' if worst['rel_change'] <= 0.05 else 'missed'})."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", help="only these scenes")
    parser.add_argument("--results-dir", type=Path, default=RESULTS_DIR)
    args = parser.parse_args(argv)
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    ensure_gpu_context()
    rows = [measure(name, path) for name, path, _ in suite() if not args.only or name in args.only]
    text = markdown(rows)
    args.results_dir.mkdir(parents=True, exist_ok=True)
    (args.results_dir / "view_pdf.md").write_text(text, encoding="utf-8")
    (args.results_dir / "view_pdf.json").write_text(json.dumps(rows, indent=2), encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
