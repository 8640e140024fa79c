# SPDX-License-Identifier: GPL-3.0-or-later
"""Float64 twin of ``glsl/lib/image.glsl``: an image texture sampled as Blender's Image Texture node
does with Linear interpolation and Repeat extension (bilinear between the four nearest texel centres,
texel centres at (i + 0.5)/W, wrapping at the edges). Used for the base colour of the RSM and
G-buffer passes.
"""

from __future__ import annotations

import numpy as np


def image_sample_linear_repeat(image, uv) -> np.ndarray:
    """RGB (..., 3) of ``image`` (H, W, ≥3; row 0 at v = 0) at texture coordinates ``uv`` (..., 2)."""
    image = np.asarray(image, dtype=np.float64)
    height, width = image.shape[:2]
    x = np.asarray(uv, dtype=np.float64) * np.array([width, height]) - 0.5
    i0 = np.floor(x).astype(np.int64)
    f = x - i0

    def texel(dx, dy):
        return image[(i0[..., 1] + dy) % height, (i0[..., 0] + dx) % width, :3]

    fx, fy = f[..., :1], f[..., 1:]
    bottom = texel(0, 0) * (1.0 - fx) + texel(1, 0) * fx
    top = texel(0, 1) * (1.0 - fx) + texel(1, 1) * fx
    return bottom * (1.0 - fy) + top * fy
