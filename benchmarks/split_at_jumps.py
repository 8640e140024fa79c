# SPDX-License-Identifier: GPL-3.0-or-later
"""The validation suite with and without the VSGL kernels' descent off RSM depth discontinuities
(not a test).

    .venv/bin/python benchmarks/split_at_jumps.py [--only NAME ...] [--seeds K ...] [--counts N ...]
        [--normal-agreement A] [--snap on|off] [--max-descent L] [--light-types TYPE ...] [--output NAME]

000 §4's kernels filter the RSM in its image plane, so a kernel across a depth discontinuity
clusters two surfaces (benchmarks/courtyard_leak.py measures what that costs the sun courtyard);
for the lights of pipeline.SPLIT_LIGHT_TYPES such a kernel descends a level at a time until it holds no
texel beside a jump (reference.vsgl.kernel_level_unstraddled; the GPU's twin in
glsl/vsgl_generation/vsgl_kernels.comp.glsl). Per scene of benchmarks/validation_suite.py (its
scenes, settings, 240x180 and cached Cycles truths), with visibility on, 000's kernels ("off":
SPLIT_LIGHT_TYPES empty) and the descending ones ("on") rendered in the same run, the second of two frames each, against
the truth: mean ours / Cycles, noise-corrected and robust relative RMSE
(validation_suite.frame_errors). ``--seeds``: each figure the mean over these seeds' frames, with
its range; ``--counts``: the VSGL budget N instead of the scene's (one row per N);
``--normal-agreement``: reference.vsgl.NORMAL_AGREEMENT instead of its value (0: every kernel over
a jump descends, whichever way its surfaces face); ``--snap``: reference.vsgl.SNAP_TO_TEXEL;
``--max-descent``: reference.vsgl.MAX_DESCENT; ``--light-types``: pipeline.SPLIT_LIGHT_TYPES (the
light types whose kernels descend; the others keep 000's).

Writes ``benchmarks/results/split_at_jumps.{md,json}`` (``--output``) and prints the markdown.
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
from validation_suite import frame_errors, scene_with_truth, suite  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
KEYS = ("mean_ratio", "rel", "rel_robust")


def _over_seeds(figures: list[dict]) -> dict:
    return {key: float(np.mean([f[key] for f in figures])) for key in KEYS} | {
        f"{key}_range": float(np.ptp([f[key] for f in figures])) for key in KEYS}


def measure(name: str, path: Path, width: int, height: int, seeds=None, count=None) -> dict:
    from vsgl_addon import pipeline
    from vsgl_addon.renderer import FrameRenderer

    settings, truth, description = scene_with_truth(name, path, width, height)
    if count is not None:
        settings = settings.overridden(vsgl_count=count)
    renderer = FrameRenderer()
    saved = pipeline.SPLIT_LIGHT_TYPES
    seeds = [settings.seed] if not seeds else list(seeds)
    row = {"scene": name, "vsgl_count": settings.vsgl_count, "settings": str(settings), "seeds": seeds}

    def figures() -> dict:
        measured = []
        for seed in seeds:
            for _ in range(2):
                frame = renderer.render(description, settings.overridden(visibility=True, seed=seed), width, height)
            both, _ = frame_errors(truth, frame)
            measured.append({key: both[key] for key in KEYS})
        return _over_seeds(measured)

    try:
        for split in (False, True):
            pipeline.SPLIT_LIGHT_TYPES = saved if split else ()
            row["on" if split else "off"] = cell = figures()
            print(f"{name} N = {settings.vsgl_count} split {split}: mean {cell['mean_ratio']:.3f}, "
                  f"rel {cell['rel']:.3f}, robust {cell['rel_robust']:.3f}", flush=True)
    finally:
        pipeline.SPLIT_LIGHT_TYPES = saved
        renderer.free()
    return row


def markdown(rows, command: str, seconds: float, normal_agreement: float, snap: bool, max_descent: int) -> str:
    from vsgl_addon import pipeline

    several = any(len(r["seeds"]) > 1 for r in rows)
    lines = ["# VSGL kernels off RSM depth discontinuities: the suite before / after", "",
             f"`{command}`; run {seconds:.0f} s. The module documentation of `benchmarks/split_at_jumps.py` "
             "says what is measured. Each cell: mean indirect ours / Cycles, noise-corrected relative RMSE "
             "(robust relative RMSE), visibility on; off: 000's kernels; on: kernels descend off depth "
             "discontinuities (pipeline.SPLIT_LIGHT_TYPES, NORMAL_AGREEMENT "
             f"{normal_agreement:g}, SNAP_TO_TEXEL {snap}, MAX_DESCENT {max_descent}; lights {' '.join(pipeline.SPLIT_LIGHT_TYPES)}); change: of the relative RMSE, on / off − 1."
             + (" Over seeds " + ", ".join(str(k) for k in rows[0]["seeds"]) + ": each figure their mean, ± half "
                "its range over them." if several else ""), "",
             "| scene | N | off | on | change of rel RMSE |", "|---|---|---|---|---|"]
    for r in rows:
        cells = [r["off"], r["on"]]
        lines.append(f"| {r['scene']} | {r['vsgl_count']} | " + " | ".join(
            " / ".join(f"{c[key]:.3f}" + (f" ± {c[key + '_range'] / 2:.3f}" if several else "")
                       for key in KEYS[:2]) + f" ({c['rel_robust']:.3f})" for c in cells)
            + f" | {r['on']['rel'] / r['off']['rel'] - 1.0:+.1%} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", help="only these scenes of the validation suite")
    parser.add_argument("--seeds", nargs="+", type=int, help="seeds to average over (default: the scene's)")
    parser.add_argument("--counts", nargs="+", type=int, help="VSGL budgets N instead of the scene's")
    parser.add_argument("--normal-agreement", type=float, default=None,
                        help="reference.vsgl.NORMAL_AGREEMENT instead of its value (0: no normal gate)")
    parser.add_argument("--snap", choices=("on", "off"), default=None,
                        help="reference.vsgl.SNAP_TO_TEXEL instead of its value")
    parser.add_argument("--light-types", nargs="+", default=None,
                        help="pipeline.SPLIT_LIGHT_TYPES instead of its value (e.g. SUN POINT SPOT AREA)")
    parser.add_argument("--max-descent", type=int, default=None,
                        help="reference.vsgl.MAX_DESCENT instead of its value")
    parser.add_argument("--output", default="split_at_jumps", help="results file name, without suffix")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    ensure_gpu_context()
    if args.normal_agreement is not None or args.snap is not None or args.max_descent is not None:
        from vsgl_addon.passes import vsgl_generation
        from vsgl_addon.reference import vsgl

        if args.normal_agreement is not None:
            vsgl.NORMAL_AGREEMENT = args.normal_agreement
        if args.snap is not None:
            vsgl.SNAP_TO_TEXEL = args.snap == "on"
        if args.max_descent is not None:
            vsgl.MAX_DESCENT = args.max_descent
        vsgl_generation.PASS.free_shaders()  # their defines are read when the shader compiles
    from vsgl_addon import pipeline

    if args.light_types is not None:
        pipeline.SPLIT_LIGHT_TYPES = tuple(args.light_types)
    width, height = RESOLUTION
    rows = [measure(name, path, width, height, args.seeds, count)
            for name, path, _ in suite() if not args.only or name in args.only
            for count in (args.counts or [None])]
    command = ".venv/bin/python benchmarks/split_at_jumps.py " + " ".join(
        (["--only"] + args.only if args.only else []) + (["--seeds"] + [str(k) for k in args.seeds] if args.seeds else [])
        + (["--counts"] + [str(n) for n in args.counts] if args.counts else [])
        + ([] if args.normal_agreement is None else ["--normal-agreement", f"{args.normal_agreement:g}"])
        + ([] if args.snap is None else ["--snap", args.snap])
        + ([] if args.max_descent is None else ["--max-descent", str(args.max_descent)])
        + ([] if args.light_types is None else ["--light-types"] + args.light_types)
        + ([] if args.output == "split_at_jumps" else ["--output", args.output]))
    from vsgl_addon.reference import vsgl

    text = markdown(rows, command.strip(), time.perf_counter() - started, vsgl.NORMAL_AGREEMENT,
                    vsgl.SNAP_TO_TEXEL, vsgl.MAX_DESCENT)
    (RESULTS / f"{args.output}.md").write_text(text)
    (RESULTS / f"{args.output}.json").write_text(json.dumps(rows, indent=1, default=str))
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
