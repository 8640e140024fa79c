# SPDX-License-Identifier: GPL-3.0-or-later
"""Cross-bilateral filter guided by position and normal, float64 (004 section 6); twin of
``glsl/lib/bilateral.glsl`` (whose header gives the weights)."""

from __future__ import annotations

import numpy as np

from .numerics import f64


def cross_bilateral(image, position, normal, radius: int, eye, sigma_plane: float, normal_power: float):
    """Filter ``image`` (H, W, >=3) guided by ``position`` (H, W, 4; w = coverage) and ``normal``
    (H, W, >=3); returns (H, W, 3), 0 on uncovered pixels."""
    image = f64(image)[..., :3]
    position = f64(position)
    normal = f64(normal)[..., :3]
    h, w = image.shape[:2]
    covered = position[..., 3] > 0.0
    scale = sigma_plane * np.maximum(np.linalg.norm(position[..., :3] - f64(eye), axis=-1), 1e-30)
    s = 0.5 * max(radius, 1)
    total = np.zeros_like(image)
    weights = np.zeros((h, w))
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            ys = slice(max(0, -dy), min(h, h - dy))
            xs = slice(max(0, -dx), min(w, w - dx))
            yq = slice(max(0, dy), min(h, h + dy))
            xq = slice(max(0, dx), min(w, w + dx))
            n = normal[ys, xs]
            plane = np.sum(n * (position[yq, xq, :3] - position[ys, xs, :3]), axis=-1) / scale[ys, xs]
            facing = np.sum(n * normal[yq, xq], axis=-1)
            weight = np.where(facing > 0.0, np.exp(-(dx * dx + dy * dy) / (2 * s * s) - plane * plane)
                              * np.maximum(facing, 0.0) ** normal_power, 0.0)
            weight = np.where(covered[yq, xq] & covered[ys, xs], weight, 0.0)
            total[ys, xs] += weight[..., None] * image[yq, xq]
            weights[ys, xs] += weight
    out = np.where(weights[..., None] > 0.0, total / np.where(weights > 0.0, weights, 1.0)[..., None], 0.0)
    return np.where(covered[..., None], out, 0.0)
