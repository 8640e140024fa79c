# SPDX-License-Identifier: GPL-3.0-or-later
"""The validation suite with VSGL visibility from shadow maps that keep their surfaces' depth
(not a test).

    .venv/bin/python benchmarks/ism_surfaces.py [--variants P:G:O:D ...] [--only NAME ...] [--seeds K ...]

benchmarks/ism_holes.py finds that in the sun courtyard the light leaking through the thin walls
comes from the lookup, not from the maps' holes: with exact depth maps from the same origins the
slope-scaled depth bias still lets it through (the grazed receiver's bias is longer than the wall's
distance in front of it), and the normal-offset lookup stops it; with the point maps the normal
offset's small depth bias shadows the receivers' own surfaces instead (the splats' constant depth,
the gap closing of concave corners). A variant P:G:O:D sets reference.ism.SPLAT_PLANE_DEPTH = P
(0: a splat writes its point's distance; > 0: where each texel's ray meets the point's tangent
plane, within P point spacings), GAP_EXTRAPOLATE = G (0/1: each side's surface continued as a plane
before the gap test), NORMAL_OFFSET = O and NORMAL_OFFSET_DEPTH = D (passes/ism.py
set_lookup_bias; O = 0 the slope-scaled depth bias). Per scene of benchmarks/validation_suite.py
(suite_sweep: its settings, 240x180, cached Cycles truths), per variant: visibility on, the second of
two frames, mean ours / Cycles, noise-corrected and robust relative RMSE, each the mean over the
seeds with its range, and per material the mean ratio. Writes
``benchmarks/results/ism_surfaces.{md,json}`` and prints the markdown.
"""

from __future__ import annotations

import argparse

import suite_sweep

#: P:G:O:D, the first the maps and lookup before oriented splats.
VARIANTS = ("0:0:0:0.5", "1:1:0:0.5", "1:1:1:1", "1:1:1:0.5")


def _parse(variant: str) -> tuple[float, bool, float, float]:
    plane, gaps, offset, depth = (float(p) for p in variant.split(":"))
    return plane, bool(gaps), offset, depth


def _apply(variant: str) -> None:
    from vsgl_addon.passes import ism as ism_pass
    from vsgl_addon.reference import ism

    plane, gaps, offset, depth = _parse(variant)
    ism.SPLAT_PLANE_DEPTH, ism.GAP_EXTRAPOLATE = plane, gaps
    ism_pass.set_lookup_bias(offset, depth)


def measure(name, path, variants, width: int, height: int, seeds=None) -> dict:
    from vsgl_addon.passes import ism as ism_pass
    from vsgl_addon.reference import ism

    saved = ism.SPLAT_PLANE_DEPTH, ism.GAP_EXTRAPOLATE, ism.NORMAL_OFFSET, ism.NORMAL_OFFSET_DEPTH

    def restore():
        ism.SPLAT_PLANE_DEPTH, ism.GAP_EXTRAPOLATE = saved[:2]
        ism_pass.set_lookup_bias(*saved[2:])

    return suite_sweep.measure_scene(
        name, path, width, height, seeds, variants, field="variants", key=str, label=lambda v: f"P:G:O:D = {v}",
        apply=_apply, restore=restore, regions=True)


def _head(variant: str) -> str:
    plane, gaps, offset, depth = _parse(variant)
    return (("point distance" if plane == 0.0 else f"tangent plane ({plane:g} spacings)")
            + (", gaps continued" if gaps else ", gaps as nearest")
            + (", depth bias" if offset == 0.0 else f", normal offset {offset:g}, depth {depth:g}"))


def markdown(rows, variants, command: str, seconds: float) -> str:
    return suite_sweep.markdown(
        "ism_surfaces.py", "VSGL visibility from maps that keep their surfaces' depth", command, seconds,
        "; off: visibility off; per variant the splat's depth (the point's distance or its tangent plane), "
        "the gap test's sides (their nearest depth, or their surface continued as a plane) and the lookup "
        "(the slope-scaled depth bias, or the normal offset O with D texels of depth bias).",
        rows, "variants", list(variants), [_head(v) for v in variants])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS),
                        help="P:G:O:D, splat plane depth (spacings; 0 the point's distance) : gap sides "
                             "continued (0/1) : normal offset (0 the depth bias) : depth bias left (texels)")
    suite_sweep.add_common_arguments(parser, "ism_surfaces")
    args = parser.parse_args(argv)
    command = suite_sweep.command_line("ism_surfaces.py", "--variants", args.variants, args)
    return suite_sweep.run(
        args, lambda name, path, width, height, seeds: measure(name, path, args.variants, width, height, seeds),
        lambda rows, seconds: markdown(rows, args.variants, command, seconds))


if __name__ == "__main__":
    raise SystemExit(main())
