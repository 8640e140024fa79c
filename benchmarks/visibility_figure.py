# SPDX-License-Identifier: GPL-3.0-or-later
"""The README's before/after image of VSGL visibility (not a test): the occluder scene's indirect
light without visibility, with it, and Cycles' one-bounce truth, side by side on one exposure.

    .venv/bin/python benchmarks/visibility_figure.py [--out docs/images/visibility-occluder.png]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from build_validation_scenes import RESOLUTION, scene_path  # noqa: E402
from validation_suite import TRUTH_SAMPLES, open_scene  # noqa: E402
from tradeoff.truth import load_reference  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="occluder")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "images" / "visibility-occluder.png")
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    import bpy
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.renderer import FrameRenderer
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    ensure_gpu_context()
    width, height = RESOLUTION
    path = scene_path(args.scene)
    truth = load_reference(open_scene(path), width, height, TRUTH_SAMPLES[args.scene], False, name=args.scene,
                           source=path, dtype=np.float16)
    scene = open_scene(path)
    settings = VSGLSettings.from_properties(scene.vsgl)
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    renderer = FrameRenderer()
    try:
        images = [renderer.render(description, settings.overridden(visibility=on), width, height).indirect
                  for on in (False, True)]
    finally:
        renderer.free()
    images.append(truth["indirect"])
    # One exposure for all three: the truth's 99th percentile maps to 1, then sRGB-like gamma.
    scale = 1.0 / max(float(np.percentile(truth["indirect"], 99.0)), 1e-12)
    titles = ("VSGL, visibility off", "VSGL, visibility on (ISMs)", "Cycles, one bounce")
    figure, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    for axis, image, title in zip(axes, images, titles):
        axis.imshow(np.clip(np.asarray(image, np.float64)[::-1] * scale, 0, 1) ** (1 / 2.2))
        axis.set_title(title)
        axis.axis("off")
    figure.suptitle(f"{args.scene}: indirect light only (the wall stands between the lit floor and the receiver)")
    figure.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(args.out, dpi=80)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
