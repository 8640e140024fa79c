"""Shared fixtures. Tests marked `gpu` get Blender's gpu module, made usable once per session."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

import pytest

# The bpy module (and every Python or Blender this suite starts) reads and writes a Blender user
# profile: by default ~/.config/blender/<version>, i.e. whatever preferences, start-up file or
# add-ons an earlier session or a developer left there. Before anything imports bpy, point it at an
# empty profile of this pytest process, and drop the caller's BLENDER_* variables, so the suite
# sees the same Blender on every machine and every run (helpers_blender gives real-blender calls a
# clean profile of their own).
for _name in [name for name in os.environ if name.startswith("BLENDER_")]:
    del os.environ[_name]
_USER_PROFILE = tempfile.mkdtemp(prefix="vsgl-bpy-user-")
atexit.register(shutil.rmtree, _USER_PROFILE, True)
os.environ["BLENDER_USER_RESOURCES"] = _USER_PROFILE


@pytest.fixture(scope="session")
def gpu_context() -> str:
    """ensure_gpu_context() once per session; the renderer's name (e.g. "llvmpipe (LLVM 15 ...)")."""
    import bpy  # noqa: F401  (the bpy module must be imported before gpu)

    from vsgl_addon.gpu_context import ensure_gpu_context

    return ensure_gpu_context()


@pytest.fixture(autouse=True)
def _gpu_for_marked_tests(request):
    if request.node.get_closest_marker("gpu") is not None:
        request.getfixturevalue("gpu_context")
