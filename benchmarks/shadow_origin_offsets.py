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

import suite_sweep

OFFSETS = (0.5, 0.75, 1.0, 1.5)


def measure(name, path, offsets, width: int, height: int, seeds=None) -> dict:
    from vsgl_addon.passes import ism as ism_pass
    from vsgl_addon.reference import ism

    saved = ism.SHADOW_ORIGIN_SIGMAS
    return suite_sweep.measure_scene(
        name, path, width, height, seeds, offsets, field="offsets", key=lambda s: repr(float(s)),
        label=lambda s: f"S = {s}", apply=ism_pass.set_shadow_origin_sigmas,
        restore=lambda: ism_pass.set_shadow_origin_sigmas(saved))


def markdown(rows, offsets, command: str, seconds: float) -> str:
    return suite_sweep.markdown(
        "shadow_origin_offsets.py", "VSGL visibility at several shadow origin offsets", command, seconds,
        ", visibility on with the maps built and looked up S σ_v off each lobe's mean; off: visibility off.",
        rows, "offsets", [repr(float(s)) for s in offsets], [f"S = {s:g}" for s in offsets])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--offsets", nargs="+", type=float, default=list(OFFSETS), help="shadow origin offsets, σ_v")
    suite_sweep.add_common_arguments(parser, "shadow_origin_offsets")
    args = parser.parse_args(argv)
    command = suite_sweep.command_line("shadow_origin_offsets.py", "--offsets", [f"{s:g}" for s in args.offsets], args)
    return suite_sweep.run(
        args, lambda name, path, width, height, seeds: measure(name, path, args.offsets, width, height, seeds),
        lambda rows, seconds: markdown(rows, args.offsets, command, seconds))


if __name__ == "__main__":
    raise SystemExit(main())
