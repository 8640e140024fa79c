# SPDX-License-Identifier: GPL-3.0-or-later
"""The validation suite with VSGL visibility at several shadow-map sides and point counts (not a test).

    .venv/bin/python benchmarks/ism_resolution.py [--configs POINTS:SIZE ...] [--only NAME ...] [--seeds K ...]

The imperfect shadow maps hide more light than exact visibility from the same origin through
their point set's rendering, not their projection (benchmarks/ism_over_occlusion.py: ray-traced
64² maps match exact visibility): sized splats and gap closing grow every silhouette, and close
concave folds, by a few texels, so the light hidden shrinks with the texel, while the points per
texel must stay to keep a near occluder's holes closed. Per scene of benchmarks/validation_suite.py
(its scenes, settings, 240x180 and cached Cycles truths), per POINTS:SIZE: the scene's settings with
``ism_points`` and ``ism_size`` replaced, visibility on, the second of two frames (the first compiles
and warms up) against the truth: mean ours / Cycles, noise-corrected and robust relative RMSE
(validation_suite.frame_errors), each the mean over the seeds with its range; and the second frame's
wall-clock time over the scene's settings' (a shared machine: a rough ratio). The first column,
visibility off, is the same for every configuration.

Writes ``benchmarks/results/ism_resolution.{md,json}`` and prints the markdown.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import suite_sweep
from validation_suite import frame_errors, scene_with_truth


def measure(name, path, configs, width: int, height: int, seeds=None) -> dict:
    from vsgl_addon.renderer import FrameRenderer

    settings, truth, description = scene_with_truth(name, path, width, height)
    seeds = [settings.seed] if not seeds else list(seeds)
    renderer = FrameRenderer()
    row = {"scene": name, "settings": str(settings), "seeds": seeds, "configs": {}, "seconds": {}}

    def figures(**overrides):
        measured, seconds = [], []
        for seed in seeds:
            for _ in range(2):
                start = time.perf_counter()
                frame = renderer.render(description, settings.overridden(seed=seed, **overrides), width, height)
                elapsed = time.perf_counter() - start
            seconds.append(elapsed)
            both, _ = frame_errors(truth, frame)
            measured.append({k: both[k] for k in suite_sweep.KEYS})
        return suite_sweep.over_seeds(measured), float(np.mean(seconds))

    try:
        row["off"], _ = figures(visibility=False)
        for config in configs:
            points, size = (int(x) for x in config.split(":"))
            row["configs"][config], row["seconds"][config] = cell, _ = figures(
                visibility=True, ism_points=points, ism_size=size)
            print(f"{name} {config}: mean {cell['mean_ratio']:.3f}, rel {cell['rel']:.3f}, "
                  f"robust {cell['rel_robust']:.3f}, {row['seconds'][config]:.2f} s", flush=True)
    finally:
        renderer.free()
    return row


def markdown(rows, configs, command: str, seconds: float) -> str:
    heads = [f"{c.split(':')[0]} points, {c.split(':')[1]}²" for c in configs]
    text = suite_sweep.markdown(
        "ism_resolution.py", "VSGL visibility at several shadow-map sides and point counts", command, seconds,
        "; visibility on with POINTS points per map and maps of side SIZE (POINTS:SIZE).", rows, "configs",
        list(configs), heads)
    lines = ["", "Frame time (second frame, mean over the seeds) over the first configuration's: "
             + "; ".join(f"{r['scene']} " + ", ".join(f"{r['seconds'][c] / r['seconds'][configs[0]]:.2f}"
                                                      for c in configs[1:]) for r in rows) + "."]
    return text + "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--configs", nargs="+", default=["4096:64", "16384:128"], help="POINTS:SIZE")
    suite_sweep.add_common_arguments(parser, "ism_resolution")
    args = parser.parse_args(argv)
    command = suite_sweep.command_line("ism_resolution.py", "--configs", args.configs, args)
    return suite_sweep.run(
        args, lambda name, path, w, h, seeds: measure(name, path, args.configs, w, h, seeds),
        lambda rows, seconds: markdown(rows, args.configs, command, seconds))


if __name__ == "__main__":
    raise SystemExit(main())
