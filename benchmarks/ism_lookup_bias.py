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

import suite_sweep

#: O:D:B:S (missing trailing values: D 0.5, B 0, S 0), the first the slope-scaled depth bias alone.
BIASES = ("0:0.5:0:0", "1:1:0:0", "2:1:0:0", "0:0.5:1:0", "0:1:0:2")


def _parse(bias: str) -> tuple[float, float, float, float]:
    parts = [float(p) for p in bias.split(":")]
    return tuple(parts + [0.5, 0.0, 0.0][len(parts) - 1:])[:4]


def measure(name, path, biases, width: int, height: int, seeds=None) -> dict:
    from vsgl_addon.passes import ism as ism_pass
    from vsgl_addon.reference import ism

    saved = ism.NORMAL_OFFSET, ism.NORMAL_OFFSET_DEPTH, ism.BACK_OFFSET, ism.SPREAD_BIAS
    return suite_sweep.measure_scene(
        name, path, width, height, seeds, biases, field="biases", key=str, label=lambda b: f"O:D:B:S = {b}",
        apply=lambda b: ism_pass.set_lookup_bias(*_parse(b)), restore=lambda: ism_pass.set_lookup_bias(*saved),
        regions=True)


def _head(bias: str) -> str:
    offset, depth, back, spread = _parse(bias)
    head = "depth bias" if offset == 0.0 else f"normal offset {offset:g}, depth {depth:g}"
    return (head + (f", back {back:g}" if back > 0.0 else "")
            + (f", at most {spread:g} spread + {depth:g} texels" if spread > 0.0 else ""))


def markdown(rows, biases, command: str, seconds: float) -> str:
    return suite_sweep.markdown(
        "ism_lookup_bias.py", "VSGL visibility at several shadow-map lookup biases", command, seconds,
        "; off: visibility off; depth bias: the slope-scaled depth bias of the filter's footprint; normal "
        "offset O, depth D: the receiver moved O filter footprints along its normal (times the sine of its "
        "incidence), D texel footprints of depth bias left; back B: receivers facing away from the origin "
        "moved B filter footprints away from it.",
        rows, "biases", list(biases), [_head(b) for b in biases])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--biases", nargs="+", default=list(BIASES),
                        help="O:D:B:S, normal offset (filter footprints; 0 the depth bias) : depth bias left "
                             "(texels) : back offset (filter footprints; 0 none) : spread cap (0 none)")
    suite_sweep.add_common_arguments(parser, "ism_lookup_bias")
    args = parser.parse_args(argv)
    command = suite_sweep.command_line("ism_lookup_bias.py", "--biases", args.biases, args)
    return suite_sweep.run(
        args, lambda name, path, width, height, seeds: measure(name, path, args.biases, width, height, seeds),
        lambda rows, seconds: markdown(rows, args.biases, command, seconds))


if __name__ == "__main__":
    raise SystemExit(main())
