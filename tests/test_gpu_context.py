"""vsgl_addon.gpu_context: a GPU context for Blender's gpu module in background mode."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parent.parent


def _run_python(code: str, **environment: str) -> subprocess.CompletedProcess:
    """`code` in a fresh Python of this venv (a process of its own: the context lives per process)."""
    env = {**os.environ, "PYTHONPATH": str(REPOSITORY), **environment}
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], cwd=REPOSITORY, env=env,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.gpu
def test_returns_the_renderer_name(gpu_context):
    import gpu

    assert isinstance(gpu_context, str) and gpu_context
    assert gpu_context == gpu.platform.renderer_get()
    if not Path("/dev/dri").exists():  # no GPU on this machine: Mesa's software renderer
        assert "llvmpipe" in gpu_context


@pytest.mark.gpu
def test_is_idempotent(gpu_context, monkeypatch):
    import bpy

    from vsgl_addon.gpu_context import ensure_gpu_context

    from vsgl_addon import gpu_context as module

    scenes = len(bpy.data.scenes)
    rendered, probed = [], []
    monkeypatch.setattr(module, "_create_context_by_rendering", lambda *a: rendered.append(a))
    monkeypatch.setattr(module, "probe_opengl", lambda: probed.append(True))
    assert ensure_gpu_context() == gpu_context
    assert ensure_gpu_context() == gpu_context
    assert rendered == [] and probed == []  # nothing is rendered or probed again
    assert len(bpy.data.scenes) == scenes


def test_leaves_the_blend_data_as_it_was():
    """Blender 5.0 renders once to get the context: the scene, camera and render result it needs go."""
    result = _run_python("""
        import json
        import bpy
        from vsgl_addon.gpu_context import ensure_gpu_context

        def counts():
            data = bpy.data
            return {name: len(getattr(data, name))
                    for name in ("scenes", "objects", "cameras", "images", "meshes", "collections")}

        before = counts()
        renderer = ensure_gpu_context()
        import gpu
        gpu.platform.backend_type_get()  # raises SystemError when there is no context
        print(json.dumps({"before": before, "after": counts(), "renderer": renderer,
                          "engine_left": hasattr(bpy.types, "VSGL_GPU_CONTEXT"),
                          "scene_engine": bpy.context.scene.render.engine}))
    """)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["after"] == report["before"]
    assert report["renderer"]
    assert not report["engine_left"]
    assert report["scene_engine"] != "VSGL_GPU_CONTEXT"


def test_without_opengl_raises_an_actionable_error_and_exits_cleanly():
    """No EGL vendor library: GPUContextError naming EGL/OpenGL and the Debian packages, no abort."""
    result = _run_python("""
        import sys
        import bpy
        from vsgl_addon.gpu_context import GPUContextError, ensure_gpu_context

        try:
            ensure_gpu_context()
        except GPUContextError as error:
            print("GPUContextError:", error)
            sys.exit(0)
        print("no error")
        sys.exit(3)
    """, __EGL_VENDOR_LIBRARY_DIRS="/nonexistent")
    assert result.returncode == 0, (result.returncode, result.stdout, result.stderr)
    message = result.stdout
    assert "GPUContextError:" in message
    assert "EGL" in message and "OpenGL" in message
    for package in ("libegl1", "libegl-mesa0", "libgl1-mesa-dri"):
        assert package in message
    assert "Aborted" not in result.stderr
