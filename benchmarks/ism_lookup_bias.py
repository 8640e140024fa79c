# SPDX-License-Identifier: GPL-3.0-or-later
"""The validation suite with VSGL visibility at several shadow-map lookup biases (not a test).

    .venv/bin/python benchmarks/ism_lookup_bias.py [--biases O:D:B:S ...] [--only NAME ...] [--seeds K ...]

A lookup in a lobe's imperfect shadow map needs a bias, or the surface a receiver lies on shadows
it (acne); too much, and the light of a VSGL behind a thin wall leaks through it. Two forms
(reference.ism.lookup_offsets, passes/ism.py set_lookup_bias): O = 0, the slope-scaled depth bias
of the filter's footprint (reference.ism.ism_bias: at grazing incidence up to nine footprints,
0.2–0.6 m at the sun courtyard's shaded face, against a 0.2 m wall); O > 0, the receiver moved
along its normal by O filter footprints times the sine of its incidence, with D texel footprints
of depth bias left; B > 0, a receiver facing away from the map's origin moved B filter footprints
away from it, with 1 mm of depth bias (B = 0: biased as the others); S > 0, the bilinear lookup's
bias at most S times the depth spread of its four texels plus D texel footprints. Per scene of benchmarks/validation_suite.py (its scenes, settings, 240x180 and
cached Cycles truths), per bias: visibility on, the second of two frames (the first compiles the
shaders of that bias) against the truth: mean ours / Cycles, noise-corrected and robust relative
RMSE (validation_suite.frame_errors). The first column is visibility off, the same for every bias;
every bias is measured in the same run. ``--seeds``: each figure the mean over frames of these
seeds, with its range. The VPL pass's lookups (its shadows) take the same bias.

Writes ``benchmarks/results/ism_lookup_bias.{md,json}`` and prints the markdown.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from build_validation_scenes import RESOLUTION  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.metrics import Errors  # noqa: E402
from validation_suite import frame_errors, scene_with_truth, suite  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
#: O:D:B:S (missing trailing values: D 0.5, B 0, S 0), the first the slope-scaled depth bias alone.
BIASES = ("0:0.5:0:0", "1:1:0:0", "2:1:0:0", "0:0.5:1:0", "0:1:0:2")
KEYS = ("mean_ratio", "rel", "rel_robust")


def _parse(bias: str) -> tuple[float, float, float, float]:
    parts = [float(p) for p in bias.split(":")]
    return tuple(parts + [0.5, 0.0, 0.0][len(parts) - 1:])[:4]


def _over_seeds(figures: list[dict]) -> dict:
    return {key: float(np.mean([f[key] for f in figures])) for key in KEYS} | {
        f"{key}_range": float(np.ptp([f[key] for f in figures])) for key in KEYS}


def measure(name: str, path: Path, biases, width: int, height: int, seeds=None) -> dict:
    from vsgl_addon.passes import ism as ism_pass
    from vsgl_addon.reference import ism
    from vsgl_addon.renderer import FrameRenderer

    settings, truth, description = scene_with_truth(name, path, width, height)
    bench = Bench(description, width, height)
    material_index, materials = bench.material_index, bench.materials
    bench.free()
    renderer = FrameRenderer()
    saved = ism.NORMAL_OFFSET, ism.NORMAL_OFFSET_DEPTH, ism.BACK_OFFSET, ism.SPREAD_BIAS
    seeds = [settings.seed] if not seeds else list(seeds)
    row = {"scene": name, "settings": str(settings), "seeds": seeds, "biases": {}}

    def figures(visibility: bool) -> dict:
        measured = []
        for seed in seeds:
            for _ in range(2):
                frame = renderer.render(description, settings.overridden(visibility=visibility, seed=seed),
                                        width, height)
            both, ours = frame_errors(truth, frame)
            regions = Errors(truth, frame.coverage).by_region(ours, material_index, materials)
            measured.append({key: both[key] for key in KEYS}
                            | {f"mean_ratio {m}": r["mean_ratio"] for m, r in regions.items()})
        return _over_seeds(measured) | {key: float(np.mean([f[key] for f in measured]))
                                        for key in measured[0] if key.startswith("mean_ratio ")}

    try:
        row["off"] = figures(False)
        for bias in biases:
            ism_pass.set_lookup_bias(*_parse(bias))
            row["biases"][bias] = cell = figures(True)
            print(f"{name} O:D:B:S = {bias}: mean {cell['mean_ratio']:.3f}, rel {cell['rel']:.3f}, "
                  f"robust {cell['rel_robust']:.3f}; " + ", ".join(
                      f"{key[11:]} {value:.3f}" for key, value in cell.items() if key.startswith("mean_ratio ")),
                  flush=True)
    finally:
        ism_pass.set_lookup_bias(*saved)
        renderer.free()
    return row


def _head(bias: str) -> str:
    offset, depth, back, spread = _parse(bias)
    head = "depth bias" if offset == 0.0 else f"normal offset {offset:g}, depth {depth:g}"
    return (head + (f", back {back:g}" if back > 0.0 else "")
            + (f", at most {spread:g} spread + {depth:g} texels" if spread > 0.0 else ""))


def markdown(rows, biases, command: str, seconds: float) -> str:
    several = any(len(r["seeds"]) > 1 for r in rows)
    lines = ["# VSGL visibility at several shadow-map lookup biases", "",
             f"`{command}`; run {seconds:.0f} s. The module documentation of `benchmarks/ism_lookup_bias.py` "
             "says what is measured. Each cell: mean indirect ours / Cycles, noise-corrected relative RMSE "
             "(robust relative RMSE), the scene's saved settings; off: visibility off; depth bias: the "
             "slope-scaled depth bias of the filter's footprint; normal offset O, depth D: the receiver "
             "moved O filter footprints along its normal (times the sine of its incidence), D texel "
             "footprints of depth bias left; back B: receivers facing away from the origin moved B filter "
             "footprints away from it."
             + (" Over seeds " + ", ".join(str(k) for k in rows[0]["seeds"]) + ": each figure their mean, ± half "
                "its range over them." if several else ""), "",
             "| scene | off | " + " | ".join(_head(b) for b in biases) + " |", "|---|---|" + "---|" * len(biases)]
    for r in rows:
        cells = [r["off"]] + [r["biases"][b] for b in biases]
        lines.append(f"| {r['scene']} | " + " | ".join(
            " / ".join(f"{c[key]:.3f}" + (f" ± {c[key + '_range'] / 2:.3f}" if several else "")
                       for key in KEYS[:2]) + f" ({c['rel_robust']:.3f})" for c in cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--biases", nargs="+", default=list(BIASES),
                        help="O:D:B:S, normal offset (filter footprints; 0 the depth bias) : depth bias left "
                             "(texels) : back offset (filter footprints; 0 none) : spread cap (0 none)")
    parser.add_argument("--only", nargs="+", help="only these scenes of the validation suite")
    parser.add_argument("--seeds", nargs="+", type=int, help="seeds to average over (default: the scene's)")
    parser.add_argument("--output", default="ism_lookup_bias", help="results file name, without suffix")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    ensure_gpu_context()
    width, height = RESOLUTION
    rows = [measure(name, path, args.biases, width, height, args.seeds)
            for name, path, _ in suite() if not args.only or name in args.only]
    command = ".venv/bin/python benchmarks/ism_lookup_bias.py " + " ".join(
        ["--biases"] + list(args.biases) + (["--only"] + args.only if args.only else [])
        + (["--seeds"] + [str(k) for k in args.seeds] if args.seeds else []))
    text = markdown(rows, args.biases, command.strip(), time.perf_counter() - started)
    (RESULTS / f"{args.output}.md").write_text(text)
    (RESULTS / f"{args.output}.json").write_text(json.dumps(rows, indent=1, default=str))
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
