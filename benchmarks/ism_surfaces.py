# SPDX-License-Identifier: GPL-3.0-or-later
"""The validation suite with VSGL visibility from shadow maps that keep their surfaces' depth
(not a test).

    .venv/bin/python benchmarks/ism_surfaces.py [--variants none|TYPES/P:G:O:D ...] [--only NAME ...] [--seeds K ...]

benchmarks/ism_holes.py finds that in the sun courtyard the light leaking through the thin walls
comes from the lookup, not from the maps' holes: with exact depth maps from the same origins the
slope-scaled depth bias still lets it through (the grazed receiver's bias is longer than the wall's
distance in front of it), and the normal-offset lookup stops it; with the point maps the normal
offset's small depth bias shadows the receivers' own surfaces instead (the splats' constant depth,
the gap closing of concave corners). A variant TYPES/P:G:O:D makes the maps of those light types
(pipeline.SURFACE_LIGHT_TYPES; "all" every type) keep their surfaces with
reference.ism.SPLAT_PLANE_DEPTH = P (0: a splat writes its point's distance; > 0: where each
texel's ray meets the point's tangent plane, within P point spacings), GAP_EXTRAPOLATE = G (0/1:
each side's surface continued as a plane before the gap test), SURFACE_NORMAL_OFFSET = O and
SURFACE_NORMAL_OFFSET_DEPTH = D (O = 0 the slope-scaled depth bias; the lookups of the lights of
pipeline.NORMAL_OFFSET_LIGHT_TYPES among them only, the others' the slope-scaled bias), their splats capped at
reference.ism.SURFACE_SPLAT_MAX_RADIUS as it is (TYPES/P:G:O:D:R: at R); "none": no light's. Per scene of benchmarks/validation_suite.py
(suite_sweep: its settings, 240x180, cached Cycles truths), per variant: visibility on, the second of
two frames, mean ours / Cycles, noise-corrected and robust relative RMSE, each the mean over the
seeds with its range, and per material the mean ratio. Writes
``benchmarks/results/ism_surfaces.{md,json}`` and prints the markdown.
"""

from __future__ import annotations

import argparse

import suite_sweep

#: TYPES/P:G:O:D, the first the maps before any kept their surfaces.
VARIANTS = ("none", "SUN/1:1:1:1", "all/1:1:0:0.5", "all/1:1:1:1")


def _parse(variant: str):
    """(light types or None for all, SPLAT_PLANE_DEPTH, GAP_EXTRAPOLATE, SURFACE_NORMAL_OFFSET and
    _DEPTH); "none": no light's maps keep their surfaces."""
    if variant == "none":
        return (), 0.0, False, 0.0, 0.5, None
    types, values = variant.split("/")
    plane, gaps, offset, depth, *cap = (float(p) for p in values.split(":"))
    return ((None if types == "all" else tuple(types.split(","))), plane, bool(gaps), offset, depth,
            int(cap[0]) if cap else None)


#: reference.ism.SURFACE_SPLAT_MAX_RADIUS as the module has it (measure), for the variants without R:
#: one variant's cap does not carry over into the next.
_DEFAULT_CAP = [None]


def _apply(variant: str) -> None:
    from vsgl_addon import pipeline
    from vsgl_addon.reference import ism
    from vsgl_addon.scene_description import LIGHT_TYPES

    types, plane, gaps, offset, depth, cap = _parse(variant)
    pipeline.SURFACE_LIGHT_TYPES = LIGHT_TYPES if types is None else types
    ism.SPLAT_PLANE_DEPTH, ism.GAP_EXTRAPOLATE = plane, gaps
    ism.SURFACE_SPLAT_MAX_RADIUS = _DEFAULT_CAP[0] if cap is None else cap
    ism.SURFACE_NORMAL_OFFSET, ism.SURFACE_NORMAL_OFFSET_DEPTH = offset, depth


def measure(name, path, variants, width: int, height: int, seeds=None) -> dict:
    from vsgl_addon import pipeline
    from vsgl_addon.reference import ism

    saved = (pipeline.SURFACE_LIGHT_TYPES, ism.SPLAT_PLANE_DEPTH, ism.GAP_EXTRAPOLATE, ism.SURFACE_NORMAL_OFFSET,
             ism.SURFACE_NORMAL_OFFSET_DEPTH, ism.SURFACE_SPLAT_MAX_RADIUS)
    _DEFAULT_CAP[0] = ism.SURFACE_SPLAT_MAX_RADIUS

    def restore():
        (pipeline.SURFACE_LIGHT_TYPES, ism.SPLAT_PLANE_DEPTH, ism.GAP_EXTRAPOLATE, ism.SURFACE_NORMAL_OFFSET,
         ism.SURFACE_NORMAL_OFFSET_DEPTH, ism.SURFACE_SPLAT_MAX_RADIUS) = saved

    return suite_sweep.measure_scene(
        name, path, width, height, seeds, variants, field="variants", key=str, label=lambda v: f"variant {v}",
        apply=_apply, restore=restore, regions=True)


def _head(variant: str) -> str:
    if variant == "none":
        return "no maps keep their surfaces (before)"
    types, plane, gaps, offset, depth, cap = _parse(variant)
    return ((("every light" if types is None else "/".join(types)) + "'s maps: ")
            + ("point distance" if plane == 0.0 else f"tangent plane ({plane:g} spacings)")
            + (", gaps continued" if gaps else ", gaps as nearest")
            + (", depth bias" if offset == 0.0 else f", normal offset {offset:g}, depth {depth:g}")
            + ("" if cap is None else f", splats up to {cap} texels"))


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
                        help="none, or TYPES/P:G:O:D: the light types whose maps keep their surfaces (all, or "
                             "e.g. SUN,SPOT), splat plane depth (spacings; 0 the point's distance) : gap sides "
                             "continued (0/1) : normal offset (0 the depth bias) : depth bias left (texels)")
    suite_sweep.add_common_arguments(parser, "ism_surfaces")
    args = parser.parse_args(argv)
    command = suite_sweep.command_line("ism_surfaces.py", "--variants", args.variants, args)
    return suite_sweep.run(
        args, lambda name, path, width, height, seeds: measure(name, path, args.variants, width, height, seeds),
        lambda rows, seconds: markdown(rows, args.variants, command, seconds))


if __name__ == "__main__":
    raise SystemExit(main())
