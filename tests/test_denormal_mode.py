# SPDX-License-Identifier: GPL-3.0-or-later
"""conftest's guard: a GPU test that leaves llvmpipe's fragment shaders keeping denormals fails,
named, instead of a later bit-for-bit comparison failing in some runs (denormal_mode.py)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
_LEAK = "VSGL_TEST_LEAK_DENORMAL_MODE"


@pytest.mark.gpu
@pytest.mark.skipif(not os.environ.get(_LEAK), reason="run by the test below, in a process of its own")
def test_leaks_the_denormal_mode():
    """The draw Workbench and EEVEE make: a half-float target, the depth test on, every fragment
    failing it (lp_state_fs.c's store skips restoring FTZ/DAZ)."""
    import gpu
    from gpu_extras.batch import batch_for_shader

    info = gpu.types.GPUShaderCreateInfo()
    info.vertex_in(0, "VEC2", "position")
    info.fragment_out(0, "VEC4", "out_color")
    info.vertex_source("void main() { gl_Position = vec4(position, 0.5, 1.0); }")
    info.fragment_source("void main() { out_color = vec4(1.0); }")
    shader = gpu.shader.create_from_info(info)
    batch = batch_for_shader(shader, "TRIS", {"position": ((-1, -1), (3, -1), (-1, 3))})
    colour = gpu.types.GPUTexture((256, 256), format="RGBA16F")
    depth = gpu.types.GPUTexture((256, 256), format="DEPTH_COMPONENT32F")
    framebuffer = gpu.types.GPUFrameBuffer(depth_slot=depth, color_slots=[colour])
    with framebuffer.bind():
        framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0), depth=0.0)
        gpu.state.viewport_set(0, 0, 256, 256)
        gpu.state.depth_test_set("LESS")
        gpu.state.depth_mask_set(False)
        shader.bind()
        batch.draw(shader)
        gpu.state.depth_test_set("NONE")
    colour.read()


def test_a_gpu_test_that_changes_the_fragment_denormal_mode_fails_by_name():
    child = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                            f"{Path(__file__).name}::test_leaks_the_denormal_mode"],
                           cwd=REPO / "tests", capture_output=True, text=True, timeout=300,
                           env={**os.environ, _LEAK: "1", "PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1"})
    out = child.stdout + child.stderr
    assert child.returncode != 0, out[-3000:]
    assert "ERROR at teardown of test_leaks_the_denormal_mode" in out or "1 error" in out, out[-3000:]
    # One thread or both may have run the failed blocks: some or all of the probe's pixels.
    changed = re.search(r"changed the GPU's fragment denormal mode \(0\.0% -> ([\d.]+)%", out)
    assert changed is not None and float(changed.group(1)) > 0.0, out[-3000:]
