# SPDX-License-Identifier: GPL-3.0-or-later
"""Cost of VSGL shading (000 app. C) against the VSGL count N and the image size, on demo.blend.

Every pixel evaluates every VSGL, so the shading time should grow in proportion to pixels × N once
the GPU's threads are all busy (llvmpipe shades 64×64-pixel tiles, one per thread: below 128² an
image leaves threads idle). Prints, as markdown, the median shading time per (size, N), the cost
per pixel × VSGL, and the ratios that test the proportionality: 4× the VSGLs and 4× the pixels
against the 4× they should cost.

    .venv/bin/python benchmarks/vsgl_shading_cost.py [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

CASES = ((64, 64), (64, 1024), (128, 256), (128, 1024), (128, 4096), (256, 1024))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    arguments = parser.parse_args(argv)

    import bpy

    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.renderer import FrameRenderer, SceneLights
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    renderer_name = ensure_gpu_context()
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"))
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    camera = description.camera
    view, projection = camera.view_matrix(), camera.projection_matrix()
    renderer = FrameRenderer()
    seconds = {}
    try:
        for count in sorted({count for _, count in CASES}):
            # VSGL shading alone: without the glossy VPL pass and its extra VSGL set (the demo has a sharp floor).
            settings = VSGLSettings(vsgl_count=count, caustics=False)
            lights = SceneLights.build(description, settings)
            try:
                for size in sorted(size for size, n in CASES if n == count):
                    renderer.render_view(lights, settings, size, size, view, projection)  # warm-up
                    # The renderer times each pass with the GPU finished (renderer.py).
                    seconds[size, count] = statistics.median(
                        renderer.render_view(lights, settings, size, size, view, projection).timings["vsgl_shading"]
                        for _ in range(arguments.repeats))
            finally:
                lights.free()
    finally:
        renderer.free()

    print(f"VSGL shading on demo.blend, {renderer_name}; median of {arguments.repeats}\n")
    print("| image | N | shading (ms) | ns per pixel × VSGL |\n|---|---|---|---|")
    for size, count in CASES:
        t = seconds[size, count]
        print(f"| {size}² | {count} | {t * 1e3:.1f} | {t / (size * size * count) * 1e9:.1f} |")
    print("\nProportionality (each should be about 4):")
    print(f"- 4× the VSGLs (128², N 1024 → 4096): {seconds[128, 4096] / seconds[128, 1024]:.2f}")
    print(f"- 4× the pixels (N 1024, 128² → 256²): {seconds[256, 1024] / seconds[128, 1024]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
