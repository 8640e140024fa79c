# SPDX-License-Identifier: GPL-3.0-or-later
"""One pass's time with the GLSL at a git revision against the working tree's, in one process.

    .venv/bin/python benchmarks/pass_ab.py [--pass vpl_culling] [--old REV] [--scenes demo ...]
                                           [--size 128] [--repeats 5] [--vsgl-count 256]

For each scene (demo.blend or benchmarks/scenes/NAME.blend) the pass's shaders compiled from the
old GLSL and from the working tree's alternate frame by frame (FrameRenderer.render_view), so a
change of the shared machine's load falls on both; prints the median time of the pass's step
(wall, GPU finished), new / old, and whether every image of the frame (FrameImages arrays) is
bit-identical (np.array_equal) and finite. Only GLSL changes that keep the interface are comparable.
"""

from __future__ import annotations

import argparse
import io
import statistics
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
IMAGES = ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular", "coverage",
          "indirect_glossy_reflectors", "indirect_caustics")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pass", dest="pass_name", default="vpl_culling", help="module in vsgl_addon.passes")
    parser.add_argument("--old", default="HEAD", help="git revision of the old GLSL (default HEAD)")
    parser.add_argument("--scenes", nargs="+", default=["demo", "caustic_panel", "polished_metal_floor"])
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--vsgl-count", type=int, default=256)
    arguments = parser.parse_args(argv)

    old_root = Path(tempfile.mkdtemp(prefix="pass_ab_"))
    archive = subprocess.run(["git", "-C", str(REPO), "archive", arguments.old, "glsl"], check=True,
                             capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(old_root)

    import importlib

    import bpy

    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.renderer import FrameRenderer, SceneLights
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings
    from vsgl_addon.shaders import create_shader

    renderer_name = ensure_gpu_context()
    gpu_pass = importlib.import_module(f"vsgl_addon.passes.{arguments.pass_name}").PASS
    new_cache, old_cache = {}, {}
    for key, spec in gpu_pass.shaders.items():
        new_cache[key] = gpu_pass.shader(key)
        old_cache[key] = create_shader(f"{gpu_pass.name}_old_{key}", spec.interface(), defines=spec.defines(),
                                       code=spec.code(), root=old_root / "glsl", **spec.stages)
    step = gpu_pass.step.name
    rows = []
    renderer = FrameRenderer()
    try:
        for scene in arguments.scenes:
            path = REPO / "demo.blend" if scene == "demo" else REPO / "benchmarks" / "scenes" / f"{scene}.blend"
            bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
            description = extract_scene(bpy.context.evaluated_depsgraph_get())
            view, projection = description.camera.view_matrix(), description.camera.projection_matrix()
            settings = VSGLSettings(vsgl_count=arguments.vsgl_count)
            lights = SceneLights.build(description, settings)
            times, images = {True: [], False: []}, {}
            try:
                for repeat in range(arguments.repeats + 1):  # the first: warm-up
                    for old in (True, False):
                        gpu_pass._cache.update(old_cache if old else new_cache)
                        frame = renderer.render_view(lights, settings, arguments.size, arguments.size,
                                                     view, projection)
                        images.setdefault(old, [np.asarray(getattr(frame, n)) for n in IMAGES])
                        if repeat:
                            times[old].append(frame.timings[step])
            finally:
                lights.free()
            equal = all(np.array_equal(a, b) for a, b in zip(images[True], images[False]))
            finite = all(np.isfinite(a).all() for a in images[False])
            rows.append((scene, statistics.median(times[True]), statistics.median(times[False]), equal, finite))
    finally:
        gpu_pass._cache.update(new_cache)
        renderer.free()

    print(f"{step} at {arguments.size}², {renderer_name}; old = {arguments.old}'s GLSL, alternating with the "
          f"working tree's; median of {arguments.repeats}\n")
    print("| scene | old ms | new ms | new / old | bit-identical | finite |\n|---|---|---|---|---|---|")
    for scene, old_time, new_time, equal, finite in rows:
        print(f"| {scene} | {old_time * 1e3:.1f} | {new_time * 1e3:.1f} | {new_time / old_time:.3f} | {equal} | "
              f"{finite} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
