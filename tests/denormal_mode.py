# SPDX-License-Identifier: GPL-3.0-or-later
"""Whether the GPU's fragment shaders flush denormals, as a share of a probe draw's pixels.

llvmpipe (Mesa 22.3) flushes denormals in fragment shaders (its rasterizer threads set FTZ/DAZ when
they start) and keeps them in compute shaders. A draw into a half-float colour target with the
depth test on, whose fragments all fail it in a block, leaves the thread that ran the block with
FTZ/DAZ off for the rest of the process: `generate_unswizzled_blend` (lp_state_fs.c) clears them
for the half-float store and restores them after the mask check, which a block of failed fragments
jumps past. Workbench and EEVEE renders do such draws. Afterwards two draws of the same passes give
other floats wherever a value passes through a denormal, by which thread ran its tile: one thread
or both may leak, so from run to run the suite's bit-for-bit comparisons hold or fail.

So the suite renders with Workbench or EEVEE only in child processes (test_denormal_mode.py shows
the leak there). Probing after every test was tried: a shader kept across tests crashed once an
engine render had made another GPU context current, and one made per probe broke later tests.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

_TESTS = Path(__file__).resolve().parent
_SIDE = 256  # 16 of llvmpipe's 64 x 64 bins: both rasterizer threads take some


def _shader():
    """The probe's shader. Made in each call: in the bpy module an engine render can leave another
    GPU context current, where objects of the last one (shaders, batches, framebuffers) are gone."""
    import gpu

    info = gpu.types.GPUShaderCreateInfo()
    info.push_constant("FLOAT", "value")
    info.vertex_in(0, "VEC2", "position")
    info.fragment_out(0, "VEC4", "out_color")
    info.vertex_source("void main() { gl_Position = vec4(position, 0.5, 1.0); }")
    # value² is denormal (1e-40): 0 where the thread flushes. The fragment coordinate keeps the
    # product from being folded at compile time.
    info.fragment_source("void main() { float v = value * (1.0 + 1e-30 * gl_FragCoord.x); "
                         "out_color = vec4(v * v, 0.0, 0.0, 1.0); }")
    return gpu.shader.create_from_info(info)


def fragment_denormals_kept(draws: int = 3) -> float:
    """The share of the probe's pixels whose fragment shader kept a denormal product, over `draws`
    draws (0 where fragment shaders flush, 1 where none does). Needs the GPU context."""
    import gpu

    from vsgl_addon.passes.gpu_util import fullscreen_triangle_batch

    shader = _shader()
    batch = fullscreen_triangle_batch(shader)
    texture = gpu.types.GPUTexture((_SIDE, _SIDE), format="RGBA32F")
    framebuffer = gpu.types.GPUFrameBuffer(color_slots=[texture])
    kept = 0
    saved = (gpu.state.depth_test_get(), gpu.state.blend_get(), tuple(gpu.state.viewport_get()))
    try:
        for _ in range(draws):
            with framebuffer.bind():
                framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0))
                gpu.state.viewport_set(0, 0, _SIDE, _SIDE)
                gpu.state.depth_test_set("NONE")
                gpu.state.blend_set("NONE")
                shader.bind()
                shader.uniform_float("value", 1e-20)
                batch.draw(shader)
            buffer = texture.read()
            buffer.dimensions = _SIDE * _SIDE * 4
            kept += int(np.count_nonzero(np.array(buffer, dtype=np.float32)[0::4]))
    finally:
        gpu.state.depth_test_set(saved[0])
        gpu.state.blend_set(saved[1])
        gpu.state.viewport_set(*saved[2])
    return kept / (draws * _SIDE * _SIDE)


def run_in_child(source: str, timeout: float = 600.0) -> dict:
    """Run `source` in a fresh Python process with the bpy module and its GPU context (tests/ and the
    repository on its path), where a Workbench or EEVEE render cannot leak into this one; returns the
    JSON object its last line prints."""
    prelude = ("import bpy  # noqa: F401\n"
               "from vsgl_addon.gpu_context import ensure_gpu_context\n"
               "ensure_gpu_context()\n")
    child = subprocess.run([sys.executable, "-c", prelude + source], cwd=_TESTS.parent, capture_output=True,
                           text=True, timeout=timeout,
                           env={**os.environ, "PYTHONPATH": f"{_TESTS}{os.pathsep}{_TESTS.parent}"})
    assert child.returncode == 0, child.stderr[-3000:]
    return json.loads(child.stdout.strip().splitlines()[-1])
