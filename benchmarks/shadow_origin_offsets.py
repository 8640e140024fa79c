# SPDX-License-Identifier: GPL-3.0-or-later
"""The validation suite with VSGL visibility at several shadow origin offsets (not a test).

    .venv/bin/python benchmarks/shadow_origin_offsets.py [--offsets S ...] [--only NAME ...] [--seeds K ...]

Each VSGL lobe's imperfect shadow map is centred on its shadow origin, its mean moved S σ_v along
its axis (reference.ism.shadow_origin; 000 §5 gives every VSGL a map, and a VSGL is a Gaussian of
positions, so where in it the map sits is a choice). Per scene of benchmarks/validation_suite.py
(its scenes, settings, 240x180 and cached Cycles truths), per offset: the maps built at S on the
GPU and the shading's lookups centred there (passes/ism.py set_shadow_origin_sigmas), visibility
on, the second of two frames (the first compiles the shaders of that offset) against the truth:
mean ours / Cycles, noise-corrected and robust relative RMSE (validation_suite.frame_errors).
The first column, visibility off, is the same for every offset. ``--seeds``: each figure the mean
over frames of these seeds (the scene points, the maps' point sets and the VSGL kernels' rotation
change with it), with its range: how far a figure moves without the offset changing.

Writes ``benchmarks/results/shadow_origin_offsets.{md,json}`` and prints the markdown.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from build_validation_scenes import RESOLUTION  # noqa: E402
from validation_suite import frame_errors, scene_with_truth, suite  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
OFFSETS = (0.5, 0.75, 1.0, 1.5)


KEYS = ("mean_ratio", "rel", "rel_robust")


def _over_seeds(figures: list[dict]) -> dict:
    return {key: float(np.mean([f[key] for f in figures])) for key in KEYS} | {
        f"{key}_range": float(np.ptp([f[key] for f in figures])) for key in KEYS}


def measure(name: str, path: Path, offsets, width: int, height: int, seeds=None) -> dict:
    from vsgl_addon.passes import ism as ism_pass
    from vsgl_addon.reference import ism
    from vsgl_addon.renderer import FrameRenderer

    settings, truth, description = scene_with_truth(name, path, width, height)
    renderer = FrameRenderer()
    saved = ism.SHADOW_ORIGIN_SIGMAS
    seeds = [settings.seed] if not seeds else list(seeds)
    row = {"scene": name, "settings": str(settings), "seeds": seeds, "offsets": {}}

    def figures(visibility: bool) -> dict:
        measured = []
        for seed in seeds:
            for _ in range(2):
                frame = renderer.render(description, settings.overridden(visibility=visibility, seed=seed),
                                        width, height)
            both, _ = frame_errors(truth, frame)
            measured.append({key: both[key] for key in KEYS})
        return _over_seeds(measured)

    try:
        row["off"] = figures(False)
        for sigmas in offsets:
            ism_pass.set_shadow_origin_sigmas(sigmas)
            row["offsets"][repr(float(sigmas))] = cell = figures(True)
            print(f"{name} S = {sigmas}: mean {cell['mean_ratio']:.3f}, rel {cell['rel']:.3f}, "
                  f"robust {cell['rel_robust']:.3f}", flush=True)
    finally:
        ism_pass.set_shadow_origin_sigmas(saved)
        renderer.free()
    return row


def markdown(rows, offsets, command: str, seconds: float) -> str:
    heads = " | ".join(f"S = {s:g}" for s in offsets)
    several = any(len(r["seeds"]) > 1 for r in rows)
    lines = ["# VSGL visibility at several shadow origin offsets", "",
             f"`{command}`; run {seconds:.0f} s. The module documentation of "
             "`benchmarks/shadow_origin_offsets.py` says what is measured. Each cell: mean indirect ours / "
             "Cycles, noise-corrected relative RMSE (robust relative RMSE), the scene's saved settings, "
             "visibility on with the maps built and looked up S σ_v off each lobe's mean; off: visibility off."
             + (" Over seeds " + ", ".join(str(k) for k in rows[0]["seeds"]) + ": each figure their mean, ± half "
                "its range over them." if several else ""), "",
             f"| scene | off | {heads} |", "|---|---|" + "---|" * len(offsets)]
    for r in rows:
        cells = [r["off"]] + [r["offsets"][repr(float(s))] for s in offsets]
        lines.append(f"| {r['scene']} | " + " | ".join(
            " / ".join(f"{c[key]:.3f}" + (f" ± {c[key + '_range'] / 2:.3f}" if several else "")
                       for key in KEYS[:2]) + f" ({c['rel_robust']:.3f})" for c in cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--offsets", nargs="+", type=float, default=list(OFFSETS), help="shadow origin offsets, σ_v")
    parser.add_argument("--only", nargs="+", help="only these scenes of the validation suite")
    parser.add_argument("--seeds", nargs="+", type=int, help="seeds to average over (default: the scene's)")
    parser.add_argument("--output", default="shadow_origin_offsets", help="results file name, without suffix")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    ensure_gpu_context()
    width, height = RESOLUTION
    rows = [measure(name, path, args.offsets, width, height, args.seeds)
            for name, path, _ in suite() if not args.only or name in args.only]
    command = ".venv/bin/python benchmarks/shadow_origin_offsets.py " + " ".join(
        (["--offsets"] + [f"{s:g}" for s in args.offsets]) + (["--only"] + args.only if args.only else [])
        + (["--seeds"] + [str(k) for k in args.seeds] if args.seeds else []))
    text = markdown(rows, args.offsets, command.strip(), time.perf_counter() - started)
    (RESULTS / f"{args.output}.md").write_text(text)
    (RESULTS / f"{args.output}.json").write_text(json.dumps(rows, indent=1, default=str))
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
