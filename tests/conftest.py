"""Shared fixtures. Tests marked `gpu` get Blender's gpu module, made usable once per session."""

from __future__ import annotations

import pytest


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
