# SPDX-License-Identifier: GPL-3.0-or-later
"""ensure_gpu_context() in the Blender 5.2 application: `-b` (gpu.init), no OpenGL, and with a window.

The bpy-module (Blender 5.0, no gpu.init) side is in test_gpu_context.py.
"""

from __future__ import annotations

import json
import subprocess
import textwrap

import pytest

from helpers_blender import REAL_BLENDER, REPO, blender_environment, describe, run_blender, scratch_dir

pytestmark = pytest.mark.real_blender

# Runs inside Blender: imports the add-on package from the repository (visible in the chroot at
# its own path) and writes what it saw as JSON.
CHECK = textwrap.dedent("""
    import json, os, sys
    sys.path.insert(0, {repo!r})
    import bpy, gpu
    out = {{"background": bpy.app.background, "has_init": hasattr(gpu, "init")}}
    if {break_egl!r}:
        os.environ["__EGL_VENDOR_LIBRARY_DIRS"] = "/nonexistent"
    init_calls = []
    if hasattr(gpu, "init"):
        real_init = gpu.init
        def counting_init():
            init_calls.append(1)
            real_init()
        gpu.init = counting_init
    from vsgl_addon.gpu_context import GPUContextError, ensure_gpu_context
    from vsgl_addon import shaders
    counts = lambda: [len(c) for c in (bpy.data.scenes, bpy.data.objects, bpy.data.cameras, bpy.data.images)]
    before = counts()
    def check():
        try:
            out["renderer"] = ensure_gpu_context()
            out["renderer_again"] = ensure_gpu_context()
            root = {folder!r}
            interface = shaders.ShaderInterface(vertex_inputs=[("VEC2", "position")], varyings=[("VEC2", "uv")],
                                                fragment_outputs=[("VEC4", "out_color")])
            shaders.create_shader("good", interface, vertex="fullscreen_triangle.vert.glsl",
                                  fragment="good.frag.glsl", root=__import__("pathlib").Path(root))
            try:
                shaders.create_shader("bad", interface, vertex="fullscreen_triangle.vert.glsl",
                                      fragment="bad.frag.glsl", root=__import__("pathlib").Path(root))
            except shaders.ShaderCompileError as error:
                out["compile_error"] = str(error)
        except GPUContextError as error:
            out["error"] = str(error)
        out["init_calls"] = len(init_calls)
        out["data_unchanged"] = counts() == before
        with open({result!r}, "w") as f:
            json.dump(out, f)
        marker = os.environ.get("REAL_BLENDER_SHOT_NOW")
        if marker and not bpy.app.background:
            open(marker, "w").close()
    if bpy.app.background:
        check()
    else:
        bpy.app.timers.register(lambda: check(), first_interval=0.5)
""")


def _script(folder, *, break_egl=False):
    result = folder / "result.json"
    script = folder / "check.py"
    script.write_text(CHECK.format(repo=str(REPO), result=str(result), break_egl=break_egl, folder=str(folder)))
    (folder / "fullscreen_triangle.vert.glsl").write_text((REPO / "glsl" / "fullscreen_triangle.vert.glsl").read_text())
    (folder / "good.frag.glsl").write_text("void main()\n{\n  out_color = vec4(uv, 0.0, 1.0);\n}\n")
    (folder / "bad.frag.glsl").write_text("void main()\n{\n  out_color = vec4(uv, 0.0, 1.0);\n  out_color.x = no_such_name;\n}\n")
    return script, result


def test_background_uses_gpu_init_once_and_leaves_data_alone():
    with scratch_dir("vsgl-gpu-") as folder:
        script, result = _script(folder)
        proc = run_blender("-b", "--factory-startup", "--python-exit-code", "1", "--python", str(script))
        assert proc.returncode == 0, describe(proc)
        seen = json.loads(result.read_text())
    assert seen["background"] and seen["has_init"], seen
    assert "llvmpipe" in seen["renderer"] and seen["renderer_again"] == seen["renderer"], seen
    assert seen["init_calls"] == 1, seen
    assert seen["data_unchanged"], seen
    # Shader loading works on 5.2 too, and a compile error names our file and line.
    assert "bad.frag.glsl:4:" in seen["compile_error"] and "no_such_name" in seen["compile_error"], seen


def test_background_without_opengl_names_what_is_missing():
    with scratch_dir("vsgl-gpu-") as folder:
        script, result = _script(folder, break_egl=True)
        proc = run_blender("-b", "--factory-startup", "--python-exit-code", "1", "--python", str(script))
        assert proc.returncode == 0, describe(proc)  # a clear exception, not an abort
        seen = json.loads(result.read_text())
    message = seen.get("error", "")
    assert "EGL" in message and "OpenGL 4.3" in message and "libegl-mesa0" in message, seen
    assert seen["init_calls"] == 0, seen


def test_with_a_window_it_does_nothing():
    with scratch_dir("vsgl-gpu-") as folder:
        script, result = _script(folder)
        # A profile of its own (not the one kept in real-blender's root); real-blender gui picks a
        # free X display itself. --wait and the timeout only guard against a hang.
        environment = blender_environment({"BLENDER_USER_RESOURCES": str(folder / "user")})
        proc = subprocess.run([str(REAL_BLENDER), "gui", "--wait", "300", "--shot", str(folder / "shot.png"),
                               "--factory-startup", "--python", str(script)],
                              cwd=REPO, env=environment, capture_output=True, text=True, timeout=600)
        assert result.exists(), describe(proc)
        seen = json.loads(result.read_text())
    assert seen["background"] is False, seen
    assert "llvmpipe" in seen["renderer"], seen
    assert seen["init_calls"] == 0, seen
    assert seen["data_unchanged"], seen


def test_every_pass_shader_compiles_in_blender_5_2():
    """5.2 runs its own GLSL preprocessor over Python shader sources (5.0 does not)."""
    with scratch_dir("vsgl-gpu-") as folder:
        script = folder / "compile.py"
        script.write_text(textwrap.dedent(f"""
            import sys
            sys.path.insert(0, {str(REPO)!r})
            from vsgl_addon.gpu_context import ensure_gpu_context
            from vsgl_addon.passes import compile_all_shaders, free_all_shaders
            ensure_gpu_context()
            compile_all_shaders()
            free_all_shaders()
            print("VSGL-SHADERS-COMPILED")
        """))
        proc = run_blender("-b", "--factory-startup", "--python-exit-code", "1", "--python", str(script))
    assert proc.returncode == 0 and "VSGL-SHADERS-COMPILED" in proc.stdout, describe(proc)


def test_the_ism_pass_compiles_and_matches_its_twin_in_blender_5_2():
    """The imperfect-shadow-map pass in 5.2: its compute stages compile, and a
    scene's maps equal the float64 twin's but for texels at rounding edges."""
    with scratch_dir("vsgl-ism-") as folder:
        script = folder / "ism.py"
        script.write_text(textwrap.dedent(f"""
            import sys
            import numpy as np
            sys.path.insert(0, {str(REPO)!r})
            from vsgl_addon.gpu_context import ensure_gpu_context
            from vsgl_addon import scene_points as sp
            from vsgl_addon.passes import ism as ism_pass
            from vsgl_addon.reference import ism
            from vsgl_addon.scene_description import Geometry
            ensure_gpu_context()
            tris = np.array([[(-4, -4, 0), (4, -4, 0), (4, 4, 0)], [(-4, -4, 0), (4, 4, 0), (-4, 4, 0)],
                             [(1, -2, 0), (1, 2, 0), (1, 2, 3)]], np.float32)
            geometry = Geometry(tris, np.zeros_like(tris), np.zeros((3, 3, 2), np.float32),
                                np.zeros(3, np.int32), np.arange(3, dtype=np.int32))
            points = sp.scene_point_sets(geometry, 2048, 2, seed=1)
            origins = np.array([[0.0, 0.0, 1.5], [2.0, 0.0, 1.0], [-1.0, 1.0, 0.5]])
            sets = [0, 1, 0]
            atlas = ism_pass.PASS.run(points, origins, sets, 16)
            got = atlas.read()
            ism_pass.PASS.free(atlas)
            expected = np.stack([ism.pull_push(ism.close_gaps(ism.splat(points.positions[s], o, 16)))
                                 for o, s in zip(origins, sets)])
            close = float(np.isclose(got, expected, rtol=1e-5).mean())
            ism_pass.PASS.free_shaders()
            print("VSGL-ISM", close, bool(np.isfinite(got).all()))
        """))
        proc = run_blender("-b", "--factory-startup", "--python-exit-code", "1", "--python", str(script))
    line = next((line for line in proc.stdout.splitlines() if line.startswith("VSGL-ISM")), None)
    assert proc.returncode == 0 and line is not None, describe(proc)
    _, close, finite = line.split()
    assert float(close) > 0.99 and finite == "True", line
