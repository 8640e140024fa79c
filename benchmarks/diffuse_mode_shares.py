# SPDX-License-Identifier: GPL-3.0-or-later
"""Which VSGLs the separable diffuse gives more light than Eq. 12's (not a test), per scene.

    .venv/bin/python benchmarks/diffuse_mode_shares.py [--only NAME ...] [--stride S] [--planarity P]

On every S-th pixel (both ways) of the suite's 240x180 camera G-buffer, the diffuse light of the
scene's VSGL tables (N = the scene's, no visibility) by the float64 reference
(reference/vsgl_shading.shade, per term) in diffuse mode "cosine" (000 Eq. 12's SG, cosine pulled
out, 000 app. C) and "separable" (000 Eqs. 10-11, the default), as ratios to Cycles' indirect light
on those pixels; and the share of each, and of the separable form's gain, that comes from the VSGLs
whose diffuse lobe's mean direction is shorter than P of a flat cluster's (|ξ̄| / |ξ̄|_flat < P,
reference/vsgl_shading FLAT_DIFFUSE_AXIS_LENGTH: clusters that span a corner or a curved surface).
Prints one line per scene.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from validation_suite import sampled_pixels, scene_with_truth, suite  # noqa: E402
from build_validation_scenes import RESOLUTION  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.demo import log  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
MODES = ("cosine", "separable")


def shares(name, path, stride, planarity_limit):
    from vsgl_addon.reference.vsgl_shading import FLAT_DIFFUSE_AXIS_LENGTH, shade

    width, height = RESOLUTION
    settings, truth, description = scene_with_truth(name, path, width, height)
    bench = Bench(description, width, height)
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride)
        cycles = float((truth["indirect"][pick] @ LUMINANCE).sum())
        total = dict.fromkeys(MODES, 0.0)
        bent = dict.fromkeys(MODES, 0.0)
        vsgls, _ = bench.vsgls(settings.overridden(visibility=False))
        try:
            for _, _, generation in vsgls.generations:
                table = {k: np.asarray(v, np.float64) for k, v in generation.read_table().items()}
                sharpness = table["diffuse_sharpness"]
                planarity = sharpness / (1.0 + sharpness) / FLAT_DIFFUSE_AXIS_LENGTH
                selected = planarity < planarity_limit
                for mode in MODES:
                    _, _, terms = shade(table, position, normal, view, rd, f0, alpha, diffuse_mode=mode, per_term=True)
                    light = terms[..., 0, :] @ LUMINANCE  # (P, N, 2): the diffuse of both lobes
                    total[mode] += float(light.sum())
                    bent[mode] += float(light[:, selected].sum())
        finally:
            vsgls.free()
    finally:
        bench.free()
    gain = total["separable"] - total["cosine"]
    gain_share = (bent["separable"] - bent["cosine"]) / gain if gain != 0 else float("nan")
    log(f"{name}: diffuse / Cycles' indirect, Eq. 12 {total['cosine'] / cycles:.3f}, separable "
        f"{total['separable'] / cycles:.3f}; VSGLs with |xi| < {planarity_limit} of a flat cluster's: share of "
        f"the light, Eq. 12 {bent['cosine'] / total['cosine']:.3f}, separable {bent['separable'] / total['separable']:.3f}; "
        f"share of the separable form's gain {gain_share:.3f}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["closed_room", "cornell_box", "many_lights", "sun_courtyard"])
    parser.add_argument("--stride", type=int, default=12)
    parser.add_argument("--planarity", type=float, default=0.9)
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    for name, path, _ in suite():
        if name in args.only:
            shares(name, path, args.stride, args.planarity)
    return 0


if __name__ == "__main__":
    sys.exit(main())
