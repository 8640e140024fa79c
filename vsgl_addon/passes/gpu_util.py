# SPDX-License-Identifier: GPL-3.0-or-later
"""Small helpers every GPU pass shares: numpy arrays to and from RGBA32F textures, numpy matrices
to ``mathutils.Matrix`` for ``uniform_float``, and the full-screen triangle of the passes whose
vertex stage is ``glsl/fullscreen_triangle.vert.glsl``. Needs a GPU context, main thread.
"""

from __future__ import annotations

import numpy as np


def matrix(array):
    """A (4, 4) array as a ``mathutils.Matrix`` (what ``GPUShader.uniform_float`` takes for a MAT4)."""
    from mathutils import Matrix

    return Matrix(np.asarray(array, dtype=np.float64).tolist())


def texture_from_array(array: np.ndarray):
    """An RGBA32F texture from an (H, W, 4) array; row 0 of the array is row 0 of the texture (the
    bottom, as ``GPUTexture.read`` returns it)."""
    import gpu

    RoundTrips.uploads += 1
    data = np.ascontiguousarray(array, dtype=np.float32)
    RoundTrips.upload_bytes += data.nbytes
    height, width = data.shape[:2]
    return gpu.types.GPUTexture((width, height), format="RGBA32F",
                                data=gpu.types.Buffer("FLOAT", data.shape, data))


class RoundTrips:
    """CPU round trips of GPU images in this process: ``read_backs`` (whole textures read into numpy,
    by :func:`read_texture`) and ``uploads`` (numpy arrays made into textures, by
    :func:`texture_from_array`). The viewport's GPU-resident path is checked against these."""

    read_backs = 0
    uploads = 0
    read_back_bytes = 0
    upload_bytes = 0
    #: One-texel reads that only wait for the GPU to finish (:func:`finish`), so a step's time is its own.
    syncs = 0


def finish(texture) -> None:
    """Wait for the GPU to finish writing `texture` by reading one texel back (GL calls return
    before the work is done)."""
    import gpu

    RoundTrips.syncs += 1
    framebuffer = gpu.types.GPUFrameBuffer(color_slots=[texture])
    with framebuffer.bind():
        framebuffer.read_color(0, 0, 1, 1, 4, 0, "FLOAT")


def read_texture(texture, width: int, height: int, channels: int = 4) -> np.ndarray:
    """A float texture as a float32 (height, width, channels) array (flattened first: Blender's
    multi-dimensional Buffers report wrong strides to numpy). ``channels`` = 1 for a depth texture."""
    RoundTrips.read_backs += 1
    RoundTrips.read_back_bytes += 4 * width * height * channels
    buffer = texture.read()
    buffer.dimensions = width * height * channels
    return np.array(buffer, dtype=np.float32).reshape(height, width, channels)


#: The one triangle that covers the viewport (``glsl/fullscreen_triangle.vert.glsl``'s ``position``).
FULLSCREEN_TRIANGLE = ((-1.0, -1.0), (3.0, -1.0), (-1.0, 3.0))


def fullscreen_triangle_batch(shader):
    """A batch of :data:`FULLSCREEN_TRIANGLE` for ``shader`` (any shader whose vertex stage is
    ``glsl/fullscreen_triangle.vert.glsl``: they share the vertex format, so one batch serves them
    all). Callers cache it."""
    from gpu_extras.batch import batch_for_shader

    return batch_for_shader(shader, "TRIS", {"position": FULLSCREEN_TRIANGLE})


def set_uniform(setter, name, value) -> None:
    """`setter(name, value)` (e.g. `program.uniform_int`), unless the shader has no such uniform.

    The GLSL compiler drops the uniforms a variant of a shader does not use (one stage serves
    several kernel or diffuse modes), and Blender then raises ValueError for the name.
    """
    try:
        setter(name, value)
    except ValueError:
        pass
