# SPDX-License-Identifier: GPL-3.0-or-later
"""One pass's time with the GLSL at a git revision against the working tree's, in one process.

    .venv/bin/python benchmarks/pass_ab.py [--pass vpl_culling] [--old REV] [--scenes demo ...]
                                           [--size 128] [--repeats 5] [--vsgl-count 256]

For each scene (demo.blend or benchmarks/scenes/NAME.blend) and each of the pass's variants (VARIANTS:
VSGL shading's visibility off / on x per-lobe / shared positions, without the glossy VPL pass) the
pass's shaders compiled from the old GLSL and from the working tree's alternate frame by frame
(FrameRenderer.render_view), so a change of the shared machine's load falls on both; prints the
median time of the pass's step (wall, GPU finished) and the median process CPU time of the step
(llvmpipe's threads are the process's), new / old, and whether every image of the frame (FrameImages
arrays) is bit-identical (np.array_equal) and finite. Only the shaders a variant's frame compiles are
built from the old GLSL. Only GLSL changes that keep the interface and defines are comparable.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from checkout_ab import extract_commit

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
IMAGES = ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular", "coverage",
          "indirect_glossy_reflectors", "indirect_caustics")
#: Per pass: (label, VSGLSettings overrides) of each variant measured; other passes: one, the defaults.
VARIANTS = {
    "vsgl_shading": [(f"visibility {'on' if visibility else 'off'}, {positions}",
                      {"caustics": False, "visibility": visibility, "positional_distribution": positions})
                     for visibility in (False, True) for positions in ("per-lobe", "shared")],
}
#: Default --vsgl-count per pass (VSGL shading's cost grows with N; 256 elsewhere).
VSGL_COUNT = {"vsgl_shading": 1024}


class _CPUTimings(dict):
    """A frame's timings dict that also stores each step's process CPU time: the renderer sets a
    step's entry right after finishing it, so the CPU time since the previous entry is the step's."""

    def __init__(self):
        super().__init__()
        self.cpu, self._clock = {}, time.process_time()

    def __setitem__(self, key, value):
        now = time.process_time()
        self.cpu[key], self._clock = now - self._clock, now
        super().__setitem__(key, value)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pass", dest="pass_name", default="vpl_culling", help="module in vsgl_addon.passes")
    parser.add_argument("--old", default="HEAD", help="git revision of the old GLSL (default HEAD)")
    parser.add_argument("--scenes", nargs="+", default=["demo", "caustic_panel", "polished_metal_floor"])
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--vsgl-count", type=int, default=None, help="default 1024 for vsgl_shading, else 256")
    arguments = parser.parse_args(argv)

    old_root = extract_commit(arguments.old, Path(tempfile.mkdtemp(prefix="pass_ab_")), "glsl")

    import importlib

    import bpy

    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.renderer import FrameRenderer, SceneLights
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings
    from vsgl_addon.shaders import create_shader

    renderer_name = ensure_gpu_context()
    gpu_pass = importlib.import_module(f"vsgl_addon.passes.{arguments.pass_name}").PASS
    old_cache = {}

    def old_shader(key):
        if key not in old_cache:
            spec = gpu_pass.shaders[key]
            old_cache[key] = create_shader(f"{gpu_pass.name}_old_{key}", spec.interface(), defines=spec.defines(),
                                           code=spec.code(), root=old_root / "glsl", **spec.stages)
        return old_cache[key]

    step = gpu_pass.step.name
    vsgl_count = arguments.vsgl_count or VSGL_COUNT.get(arguments.pass_name, 256)
    variants = VARIANTS.get(arguments.pass_name, [("", {})])
    rows = []
    renderer = FrameRenderer()
    render_view_textures, cpu = renderer.render_view_textures, []

    def timed_view_textures(lights, settings, width, height, view, projection, timings=None, *args, **kwargs):
        recorded = _CPUTimings()
        try:
            return render_view_textures(lights, settings, width, height, view, projection, recorded, *args, **kwargs)
        finally:
            timings.update(recorded)
            cpu.append(recorded.cpu.get(step, 0.0))

    renderer.render_view_textures = timed_view_textures
    new_cache = {}
    try:
        for scene in arguments.scenes:
            path = REPO / "demo.blend" if scene == "demo" else REPO / "benchmarks" / "scenes" / f"{scene}.blend"
            bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
            description = extract_scene(bpy.context.evaluated_depsgraph_get())
            view, projection = description.camera.view_matrix(), description.camera.projection_matrix()
            for label, overrides in variants:
                settings = VSGLSettings(vsgl_count=vsgl_count, **overrides)
                lights = SceneLights.build(description, settings)
                wall, process, images = {True: [], False: []}, {True: [], False: []}, {}
                try:
                    gpu_pass._cache.update(new_cache)
                    renderer.render_view(lights, settings, arguments.size, arguments.size, view, projection)
                    used = [key for key in gpu_pass.shaders if key in gpu_pass._cache]  # this variant's
                    new_cache.update((key, gpu_pass._cache[key]) for key in used)
                    old = {key: old_shader(key) for key in used}
                    for repeat in range(arguments.repeats + 1):  # the first: warm-up
                        for is_old in (True, False):
                            gpu_pass._cache.update(old if is_old else {key: new_cache[key] for key in used})
                            frame = renderer.render_view(lights, settings, arguments.size, arguments.size,
                                                         view, projection)
                            images.setdefault(is_old, [np.asarray(getattr(frame, n)) for n in IMAGES])
                            if repeat:
                                wall[is_old].append(frame.timings[step])
                                process[is_old].append(cpu[-1])
                finally:
                    gpu_pass._cache.update(new_cache)
                    lights.free()
                equal = all(np.array_equal(a, b) for a, b in zip(images[True], images[False]))
                finite = all(np.isfinite(a).all() for a in images[False])
                rows.append((scene, label, *(statistics.median(t[is_old]) for t in (wall, process)
                                             for is_old in (True, False)), equal, finite))
    finally:
        gpu_pass._cache.update(new_cache)
        renderer.free()

    print(f"{step} at {arguments.size}², N {vsgl_count}, {renderer_name}; old = {arguments.old}'s GLSL, "
          f"alternating with the working tree's; median of {arguments.repeats}\n")
    print("| scene | variant | old ms | new ms | new / old | CPU new / old | bit-identical | finite |\n"
          "|---|---|---|---|---|---|---|---|")
    for scene, label, wall_old, wall_new, cpu_old, cpu_new, equal, finite in rows:
        print(f"| {scene} | {label or '-'} | {wall_old * 1e3:.1f} | {wall_new * 1e3:.1f} | {wall_new / wall_old:.3f} | "
              f"{cpu_new / cpu_old if cpu_old else float('nan'):.3f} | {equal} | {finite} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
