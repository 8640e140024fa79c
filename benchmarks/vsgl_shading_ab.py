# SPDX-License-Identifier: GPL-3.0-or-later
"""VSGL shading time of the GLSL at a git revision against the working tree's, in one process.

    .venv/bin/python benchmarks/vsgl_shading_ab.py [--old REV] [--size 128] [--n 1024] [--repeats 7]

On demo.blend (without the glossy VPL pass), for visibility off and on and both positional
distributions: the old and the new shaders alternate frame by frame (FrameRenderer.render_view), so
a change of the shared machine's load falls on both; prints the median shading time (wall, GPU
finished) and the median process CPU time of the pass (llvmpipe's threads are the process's) for
each, and new / old. The old GLSL gets the current interface and defines; revisions before the
positional distribution became the VSGL_SHARED_POSITIONS define read it from the `shared_positions`
push constant, declared and set for them too.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--old", default="HEAD~1", help="git revision of the old GLSL (default HEAD~1)")
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--n", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=7)
    arguments = parser.parse_args(argv)

    old_root = Path(tempfile.mkdtemp(prefix="vsgl_shading_ab_"))
    archive = subprocess.run(["git", "-C", str(REPO), "archive", arguments.old, "glsl"], check=True,
                             capture_output=True).stdout
    with tarfile.open(fileobj=__import__("io").BytesIO(archive)) as tar:
        tar.extractall(old_root)

    import bpy

    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.passes import vsgl_shading
    from vsgl_addon.passes.gpu_util import finish
    from vsgl_addon.renderer import FrameRenderer, SceneLights
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings
    from vsgl_addon.shaders import create_shader

    renderer_name = ensure_gpu_context()
    new_shader, new_set_uniform, new_run = vsgl_shading.shader, vsgl_shading.set_uniform, vsgl_shading.VSGLShading.run
    old_shaders, state = {}, {"old": False, "shared": 0, "program": None}

    def old_shader(diffuse_mode="cosine", visibility=False, maps_per_vsgl=1, shared_positions=False):
        key = (diffuse_mode, visibility, maps_per_vsgl, bool(shared_positions))
        if key not in old_shaders:
            interface = vsgl_shading._interface(visibility)
            interface.push_constants.append(("INT", "shared_positions"))
            spec = vsgl_shading._shader_spec(*key)
            old_shaders[key] = create_shader("vsgl_shading_old", interface, defines=spec.defines(),
                                             code=spec.code(), root=old_root / "glsl", **spec.stages)
        state["shared"], state["program"] = int(shared_positions), old_shaders[key]
        return old_shaders[key]

    def set_uniform(setter, name, value):
        new_set_uniform(setter, name, value)
        if name == "vsgl_count" and state["old"]:
            new_set_uniform(state["program"].uniform_int, "shared_positions", state["shared"])

    cpu = []

    def timed_run(self, *args, **kwargs):
        clock = time.process_time()
        textures = new_run(self, *args, **kwargs)
        finish(textures[0])
        cpu.append(time.process_time() - clock)
        return textures

    vsgl_shading.set_uniform, vsgl_shading.VSGLShading.run = set_uniform, timed_run
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"), load_ui=False)
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    view, projection = description.camera.view_matrix(), description.camera.projection_matrix()
    size, count = arguments.size, arguments.n
    renderer = FrameRenderer()
    rows = []
    try:
        for visibility in (False, True):
            for positions in ("per-lobe", "shared"):
                settings = VSGLSettings(vsgl_count=count, caustics=False, visibility=visibility,
                                        positional_distribution=positions)
                lights = SceneLights.build(description, settings)
                wall, process = {True: [], False: []}, {True: [], False: []}
                try:
                    for repeat in range(arguments.repeats + 1):  # the first: warm-up
                        for old in (True, False):
                            state["old"] = old
                            vsgl_shading.shader = old_shader if old else new_shader
                            frame = renderer.render_view(lights, settings, size, size, view, projection)
                            if repeat:
                                wall[old].append(frame.timings["vsgl_shading"])
                                process[old].append(cpu[-1])
                finally:
                    lights.free()
                rows.append((visibility, positions, *(statistics.median(t[old]) for t in (wall, process)
                                                      for old in (True, False))))
    finally:
        vsgl_shading.shader = new_shader
        renderer.free()

    print(f"VSGL shading on demo.blend, {size}², N {count}, {renderer_name}; old = {arguments.old}'s GLSL, "
          f"alternating with the working tree's; median of {arguments.repeats}\n")
    print("| visibility | positions | old ms | new ms | new / old | CPU new / old |\n|---|---|---|---|---|---|")
    for visibility, positions, wall_old, wall_new, cpu_old, cpu_new in rows:
        print(f"| {'on' if visibility else 'off'} | {positions} | {wall_old * 1e3:.0f} | {wall_new * 1e3:.0f} | "
              f"{wall_new / wall_old:.3f} | {cpu_new / cpu_old:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
