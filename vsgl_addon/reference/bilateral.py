# SPDX-License-Identifier: GPL-3.0-or-later
"""Bilateral filters guided by world positions and normals, float64 twin of ``glsl/lib/bilateral.glsl``
(same names; its header gives the weights), one range weight for both:

* joint (cross) bilateral upsampling (Kopf, Cohen, Lischinski, Uyttendaele, "Joint bilateral
  upsampling", SIGGRAPH 2007, eq. 2), the viewport's: the value at a full-resolution pixel p is the
  normalised sum over the low-resolution texels q of f(q) · w_spatial(p, q) · w_range(G(p), G↓(q)),
  with the guide G the full-resolution G-buffer and G↓ the one the low-resolution image was rendered
  with. w_spatial is the bilinear weight of the four nearest texels, w_range
  :func:`bilateral_range_weight` with positions in units of σ_x low-resolution texel footprints and
  both the off-plane and the tangential distance. When the four weights sum below JBU_MIN_WEIGHT,
  the best-matching geometry texel of the 4×4 neighbourhood is taken (four times wider σ_x, ties
  towards the nearest texel), else zero. The weights depend on the guides alone: :func:`jbu_weights`
  once per pixel, :func:`jbu_apply` per image of the render;
* the cross-bilateral filter at equal resolution (004 section 6), the VPL pass's interleave
  denoising: a Gaussian window of the pixel distance times the range weight of the distance off the
  pixel's tangent plane alone, relative to its depth.

Images are (h, w, c) arrays, row 0 at the bottom (texture row 0); guides (h, w, 4): position.rgb +
coverage in .a, normal.rgb.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .numerics import dot, f64

JBU_MIN_WEIGHT = 1e-3


def bilateral_range_weight(position, normal, neighbour_position, neighbour_normal, scale, tangential, normal_power):
    """exp(-(d_n² + tangential |d_t|²) / 2) · max(n · n_q, 0)^power, d = (x_q - x_p) / scale split into
    d_n = n · d and the rest d_t; 0 where the neighbour is background (neighbour_position[..., 3] <= 0).
    Trailing axes: 3, and 4 for neighbour_position."""
    position, normal = f64(position), f64(normal)
    neighbour_position, neighbour_normal = f64(neighbour_position), f64(neighbour_normal)
    d = (neighbour_position[..., :3] - position) / np.maximum(f64(scale), 1e-30)[..., None]
    off_plane = dot(normal, d)
    along = np.maximum(dot(d, d) - off_plane * off_plane, 0.0)
    c = dot(normal, neighbour_normal[..., :3])
    wn = np.where(c > 0.0, np.power(np.maximum(c, 0.0), normal_power), 0.0)
    w = np.exp(-0.5 * np.minimum(off_plane * off_plane + f64(tangential) * along, 1e4)) * wn
    return np.where(neighbour_position[..., 3] > 0.0, w, 0.0)


# --- Joint bilateral upsampling ----------------------------------------------------------------


def jbu_range_weight(position, normal, low_position, low_normal, footprint, sigma_position, normal_power):
    """The upsampler's range weight of a low-resolution texel: :func:`bilateral_range_weight` in units
    of σ_x footprints, off-plane and tangential distances alike."""
    return bilateral_range_weight(position, normal, low_position, low_normal,
                                  f64(footprint) * f64(sigma_position), 1.0, normal_power)


def jbu_footprint(camera, position, projection_11, low_height):
    """World size of one low-resolution texel at `position` (see the GLSL)."""
    camera, position = f64(camera), f64(position)
    extent = 2.0 / (max(abs(float(projection_11)), 1e-30) * max(float(low_height), 1.0))
    if camera[3] > 0.5:
        return np.linalg.norm(position - camera[:3], axis=-1) * extent
    return np.full(position.shape[:-1], extent)


@dataclass
class JBUWeights:
    """The upsampler's weights at n pixels (see the GLSL): `kind` 0 the four nearest texels from
    `base` (n, 2) with raw `weights` (n, 4) summing to `weight_sum`; 1 the one texel `pick` (n, 2);
    2 zero. They depend on the guides alone, so every image of one render shares them."""

    base: np.ndarray
    pick: np.ndarray
    weights: np.ndarray
    weight_sum: np.ndarray
    kind: np.ndarray


def jbu_weights(low_position, low_normal, uv, position, normal, footprint, sigma_position=1.0,
                normal_power=8.0) -> JBUWeights:
    """The weights of :func:`joint_bilateral_upsample` at texture coordinates `uv` (n, 2) of pixels with
    guides `position` (n, 3), `normal` (n, 3) and `footprint` (n,), for images of `low_position`'s size."""
    low_position, low_normal = f64(low_position), f64(low_normal)
    uv, position, normal, footprint = f64(uv), f64(position), f64(normal), f64(footprint)
    h, w = low_position.shape[:2]
    size = np.array([w, h], np.float64)
    q = uv * size - 0.5
    base_f = np.floor(q)
    f = q - base_f
    base = base_f.astype(np.int64)
    hi = np.array([w - 1, h - 1])
    n = len(uv)
    weights = np.zeros((n, 4))
    for k in range(4):
        o = np.array([k & 1, k >> 1])
        t = np.clip(base + o, 0, hi)
        ws = (1.0 - f[:, 0] if o[0] == 0 else f[:, 0]) * (1.0 - f[:, 1] if o[1] == 0 else f[:, 1])
        wr = jbu_range_weight(position, normal, low_position[t[:, 1], t[:, 0]], low_normal[t[:, 1], t[:, 0]],
                              footprint, sigma_position, normal_power)
        weights[:, k] = ws * wr
    weight_sum = weights.sum(axis=1)
    best = np.zeros(n)
    pick = np.zeros((n, 2), np.int64)
    found = np.zeros(n, bool)
    for j in range(-1, 3):
        for i in range(-1, 3):
            t = np.clip(base + np.array([i, j]), 0, hi)
            p = low_position[t[:, 1], t[:, 0]]
            dt = t - q
            wt = jbu_range_weight(position, normal, p, low_normal[t[:, 1], t[:, 0]], footprint,
                                  4.0 * sigma_position, normal_power) + 1e-6 / (1.0 + dot(dt, dt))
            better = (p[:, 3] > 0.0) & (wt > best)
            best = np.where(better, wt, best)
            pick = np.where(better[:, None], t, pick)
            found |= better
    kind = np.where(weight_sum > JBU_MIN_WEIGHT, 0, np.where(found, 1, 2))
    return JBUWeights(base, pick, weights, weight_sum, kind)


def jbu_apply(jw: JBUWeights, low) -> np.ndarray:
    """`low` (h, w, c) resampled with the weights `jw` (a 1×1 image: its one texel): (n, c) float64."""
    low = f64(low)
    hi = np.array([low.shape[1] - 1, low.shape[0] - 1])
    total = np.zeros((len(jw.kind), low.shape[-1]))
    for k in range(4):
        t = np.clip(jw.base + np.array([k & 1, k >> 1]), 0, hi)
        total += jw.weights[:, k, None] * low[t[:, 1], t[:, 0]]
    ok = jw.kind == 0
    out = total / np.where(ok, jw.weight_sum, 1.0)[:, None]
    pick = np.minimum(jw.pick, hi)
    picked = np.where((jw.kind == 1)[:, None], low[pick[:, 1], pick[:, 0]], 0.0)
    return np.where(ok[:, None], out, picked)


def joint_bilateral_upsample(low, low_position, low_normal, uv, position, normal, footprint,
                             sigma_position=1.0, normal_power=8.0):
    """The upsampled values of `low` (h, w, c, of `low_position`'s size) at texture coordinates `uv`
    (n, 2) of pixels with guides `position` (n, 3), `normal` (n, 3) and `footprint` (n,): (n, c) float64."""
    return jbu_apply(jbu_weights(low_position, low_normal, uv, position, normal, footprint, sigma_position,
                                 normal_power), low)


# --- Cross-bilateral filter at equal resolution ------------------------------------------------


def cross_bilateral(image, position, normal, radius: int, eye, sigma_plane: float, normal_power: float):
    """Filter ``image`` (H, W, >=3) guided by ``position`` (H, W, 4; w = coverage) and ``normal``
    (H, W, >=3): exp(-|q - p|² / (2 s²)), s = radius / 2 pixels, times :func:`bilateral_range_weight`
    with tangential 0 and scale σ_plane |x_p - eye| / √2; returns (H, W, 3), 0 on uncovered pixels."""
    image = f64(image)[..., :3]
    position = f64(position)
    normal = f64(normal)[..., :3]
    h, w = image.shape[:2]
    covered = position[..., 3] > 0.0
    scale = sigma_plane * np.maximum(np.linalg.norm(position[..., :3] - f64(eye), axis=-1), 1e-30) / np.sqrt(2.0)
    s = 0.5 * max(radius, 1)
    total = np.zeros_like(image)
    weights = np.zeros((h, w))
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            ys = slice(max(0, -dy), min(h, h - dy))
            xs = slice(max(0, -dx), min(w, w - dx))
            yq = slice(max(0, dy), min(h, h + dy))
            xq = slice(max(0, dx), min(w, w + dx))
            weight = np.exp(-(dx * dx + dy * dy) / (2 * s * s)) * bilateral_range_weight(
                position[ys, xs, :3], normal[ys, xs], position[yq, xq], normal[yq, xq], scale[ys, xs], 0.0,
                normal_power)
            weight = np.where(covered[ys, xs], weight, 0.0)
            total[ys, xs] += weight[..., None] * image[yq, xq]
            weights[ys, xs] += weight
    out = np.where(weights[..., None] > 0.0, total / np.where(weights > 0.0, weights, 1.0)[..., None], 0.0)
    return np.where(covered[..., None], out, 0.0)
