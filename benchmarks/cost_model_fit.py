# SPDX-License-Identifier: GPL-3.0-or-later
"""Budget mode's built-in cost model (vsgl_addon/budget.py FALLBACK_COEFFICIENTS) refitted on this
machine, and the VPL pass's time against its interleave (not a test).

    .venv/bin/python benchmarks/cost_model_fit.py [--only NAME ...] [--results-dir DIR]

Per scene of the validation suite (240x180, its saved settings with the passes Budget runs there,
budget_render.calibrate's frames after a warm-up frame), plus, where the VPL pass runs, four
frames at N = 256, RSM 128², δ = 10⁻³, full resolution and interleave 1 / 2 / 4 / 8 (the pass's
median over three frames each, after one). Every frame's per-step timings and features
(budget.frame_features) are pooled and fitted (budget.fit, the built-in coefficients as its weak
prior): the coefficients to paste into FALLBACK_COEFFICIENTS, and per scene the predicted /
measured frame time of the built-in and the refitted model (no per-scene correction). Writes
``benchmarks/results/cost_model_fit.{md,json}``.
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

from build_validation_scenes import RESOLUTION  # noqa: E402
from checkout_ab import write_results  # noqa: E402
from validation_suite import budget_scene, measure_suite  # noqa: E402
from tradeoff.demo import log  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
INTERLEAVES = ("1", "2", "4", "8")
SWEEP_FRAMES = 3


def measure_scene(name, path) -> dict:
    from vsgl_addon.budget import Candidate, CostModel, scaled_size
    from vsgl_addon.budget_render import CALIBRATION, _features, _remember_vpls, _render
    from vsgl_addon.renderer import FrameRenderer

    width, height = RESOLUTION
    _, _, description, plan, fixed = budget_scene(name, path)
    model = CostModel.fallback()  # only its per-scene VPL count is used
    renderer = FrameRenderer()
    samples, sweep = [], []

    def frame(candidate):
        chosen = candidate.apply(fixed)
        size = scaled_size(width, height, candidate.scale)
        images = _render(renderer, description, chosen, size, (width, height), None)
        _remember_vpls(model, description, images.plan, chosen, images.counts)
        features = _features(model, description, images.plan, chosen, size, (width, height))
        return images, {"features": {k: [float(v) for v in values] for k, values in features.items()},
                        "timings": {k: float(images.timings.get(k, 0.0)) for k in features}}

    try:
        for index, candidate in enumerate((CALIBRATION[0], *CALIBRATION)):
            _, sample = frame(candidate)
            if index:
                samples.append(sample)
        if plan.runs("vpl_pass"):
            for interleave in INTERLEAVES:
                candidate = Candidate(256, 128, 1e-3, interleave, 1.0)
                frame(candidate)
                measured = [frame(candidate) for _ in range(SWEEP_FRAMES)]
                samples += [sample for _, sample in measured]
                pass_ms = [1e3 * sample["timings"]["vpl_culling"] for _, sample in measured]
                sweep.append({"interleave": interleave, "vpl_pass_ms": float(np.median(pass_ms)),
                              "vpls": int(measured[-1][0].counts.get("vpls", 0)),
                              "features": measured[-1][1]["features"]["vpl_culling"]})
                log(f"{name}: interleave {interleave}: VPL pass {sweep[-1]['vpl_pass_ms']:.0f} ms")
    finally:
        renderer.free()
    log(f"{name}: {len(samples)} frames")
    return {"scene": name, "vpl_pass": plan.runs("vpl_pass"), "samples": samples, "sweep": sweep}


def ratios(coefficients: dict, samples: list) -> list[float]:
    """Predicted / measured frame time of each sample under ``coefficients``."""
    from vsgl_addon.budget import CostModel

    model = CostModel(coefficients)
    return [model.predict({k: np.asarray(v) for k, v in s["features"].items()}) / max(sum(s["timings"].values()), 1e-9)
            for s in samples]


def markdown(results, old, new, command, seconds) -> str:
    from vsgl_addon.budget import CostModel, STEP_FEATURES

    lines = ["# Budget's built-in cost model, refitted", "",
             f"`{command}`; 240x180; run {seconds:.0f} s. The module documentation of "
             "`benchmarks/cost_model_fit.py` defines the frames and the fit.", "",
             "Predicted / measured frame time per scene (median, range over its frames), no per-scene correction:", "",
             "| scene | frames | built-in: median | built-in: range | refitted: median | refitted: range |",
             "|---|---|---|---|---|---|"]
    everything = []
    for result in results:
        a, b = ratios(old, result["samples"]), ratios(new, result["samples"])
        everything.append((a, b))
        lines.append(f"| {result['scene']} | {len(a)} | {np.median(a):.2f} | {min(a):.2f}-{max(a):.2f} | "
                     f"{np.median(b):.2f} | {min(b):.2f}-{max(b):.2f} |")
    a = [x for pair in everything for x in pair[0]]
    b = [x for pair in everything for x in pair[1]]
    lines.append(f"| all | {len(a)} | {np.median(a):.2f} | {min(a):.2f}-{max(a):.2f} | {np.median(b):.2f} | "
                 f"{min(b):.2f}-{max(b):.2f} |")
    lines += ["", "The VPL pass against its interleave (N = 256, RSM 128², δ = 10⁻³, full resolution): measured "
              "median, its ratio to interleave 1, and the built-in and refitted models' predictions:", "",
              "| scene | VPLs | interleave | VPL pass ms | / interleave 1 | built-in ms | refitted ms |",
              "|---|---|---|---|---|---|---|"]
    for result in results:
        if not result["sweep"]:
            continue
        first = result["sweep"][0]["vpl_pass_ms"]
        for row in result["sweep"]:
            features = np.asarray(row["features"])
            predicted = [1e3 * CostModel(c).predict({"vpl_culling": features}) for c in (old, new)]
            lines.append(f"| {result['scene']} | {row['vpls']} | {row['interleave']} | {row['vpl_pass_ms']:.0f} | "
                         f"{row['vpl_pass_ms'] / first:.2f} | {predicted[0]:.0f} | {predicted[1]:.0f} |")
    lines += ["", "Refitted coefficients (seconds per feature unit, budget.STEP_FEATURES' units):", "", "```python"]
    for step, values in new.items():
        names = ", ".join(STEP_FEATURES[step])
        lines.append(f'    "{step}": ({", ".join(f"{v:.2g}" for v in values)}),  # {names}')
    lines += ["```"]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+")
    parser.add_argument("--results-dir", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    started = time.perf_counter()
    results = measure_suite(measure_scene, args.only)
    from vsgl_addon.budget import FALLBACK_COEFFICIENTS, fit

    old = {step: list(values) for step, values in FALLBACK_COEFFICIENTS.items()}
    new = fit([sample for result in results for sample in result["samples"]])
    command = "benchmarks/cost_model_fit.py" + (f" --only {' '.join(args.only)}" if args.only else "")
    text = markdown(results, old, new, f".venv/bin/python {command}", time.perf_counter() - started)
    write_results("cost_model_fit", {"results": results, "built_in": old, "refitted": new}, text, args.results_dir)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
