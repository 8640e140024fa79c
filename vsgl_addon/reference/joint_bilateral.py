# SPDX-License-Identifier: GPL-3.0-or-later
"""Joint (cross) bilateral upsampling, float64 twin of ``glsl/lib/joint_bilateral.glsl`` (same names).

Kopf, Cohen, Lischinski, Uyttendaele, "Joint bilateral upsampling" (SIGGRAPH 2007), eq. 2: the value
at a full-resolution pixel p is the normalised sum over the low-resolution texels q of
f(q) · w_spatial(p, q) · w_range(G(p), G↓(q)), with the guide G the full-resolution G-buffer and G↓
the one the low-resolution image was rendered with. Here w_spatial is the bilinear weight of the four
nearest texels, and w_range = exp(-|x_p - x_q|² / (2 (σ_x · footprint)²)) · max(n_p · n_q, 0)^power,
zero for background texels (coverage 0). When the four weights sum below JBU_MIN_WEIGHT, the
best-matching geometry texel of the 4×4 neighbourhood is taken (four times wider σ_x, ties towards
the nearest texel), else zero.

Images are (h, w, c) arrays, row 0 at the bottom (texture row 0); guides (h, w, 4): position.rgb +
coverage in .a, normal.rgb.
"""

from __future__ import annotations

import numpy as np

from .numerics import dot, f64

JBU_MIN_WEIGHT = 1e-3


def jbu_range_weight(position, normal, low_position, low_normal, footprint, sigma_position, normal_power):
    """The range weight of a low-resolution texel (trailing axes: 3 for position and normal, 4 for
    low_position whose [..., 3] is coverage)."""
    position, normal, low_position, low_normal = (f64(x) for x in (position, normal, low_position, low_normal))
    scale = np.maximum(f64(footprint) * f64(sigma_position), 1e-30)[..., None]
    d = (position - low_position[..., :3]) / scale
    c = dot(normal, low_normal[..., :3])
    wn = np.where(c > 0.0, np.power(np.maximum(c, 0.0), normal_power), 0.0)
    w = np.exp(-0.5 * np.minimum(dot(d, d), 1e4)) * wn
    return np.where(low_position[..., 3] > 0.0, w, 0.0)


def jbu_footprint(camera, position, projection_11, low_height):
    """World size of one low-resolution texel at `position` (see the GLSL)."""
    camera, position = f64(camera), f64(position)
    extent = 2.0 / (max(abs(float(projection_11)), 1e-30) * max(float(low_height), 1.0))
    if camera[3] > 0.5:
        return np.linalg.norm(position - camera[:3], axis=-1) * extent
    return np.full(position.shape[:-1], extent)


def joint_bilateral_upsample(low, low_position, low_normal, uv, position, normal, footprint,
                             sigma_position=1.0, normal_power=8.0):
    """The upsampled values of `low` (h, w, c) at texture coordinates `uv` (n, 2) of pixels with
    guides `position` (n, 3), `normal` (n, 3) and `footprint` (n,): (n, c) float64."""
    low, low_position, low_normal = f64(low), f64(low_position), f64(low_normal)
    uv, position, normal, footprint = f64(uv), f64(position), f64(normal), f64(footprint)
    h, w = low.shape[:2]
    size = np.array([w, h], np.float64)
    q = uv * size - 0.5
    base_f = np.floor(q)
    f = q - base_f
    base = base_f.astype(np.int64)
    hi = np.array([w - 1, h - 1])
    n = len(uv)
    total = np.zeros((n, low.shape[-1]))
    weight_sum = np.zeros(n)
    for k in range(4):
        o = np.array([k & 1, k >> 1])
        t = np.clip(base + o, 0, hi)
        ws = (1.0 - f[:, 0] if o[0] == 0 else f[:, 0]) * (1.0 - f[:, 1] if o[1] == 0 else f[:, 1])
        wr = jbu_range_weight(position, normal, low_position[t[:, 1], t[:, 0]], low_normal[t[:, 1], t[:, 0]],
                              footprint, sigma_position, normal_power)
        wk = ws * wr
        total += wk[:, None] * low[t[:, 1], t[:, 0]]
        weight_sum += wk
    ok = weight_sum > JBU_MIN_WEIGHT
    out = np.where(ok[:, None], total / np.where(ok, weight_sum, 1.0)[:, None], 0.0)
    best = np.zeros(n)
    pick = np.zeros((n, low.shape[-1]))
    for j in range(-1, 3):
        for i in range(-1, 3):
            t = np.clip(base + np.array([i, j]), 0, hi)
            p = low_position[t[:, 1], t[:, 0]]
            dt = t - q
            wt = jbu_range_weight(position, normal, p, low_normal[t[:, 1], t[:, 0]], footprint,
                                  4.0 * sigma_position, normal_power) + 1e-6 / (1.0 + dot(dt, dt))
            better = (p[:, 3] > 0.0) & (wt > best)
            best = np.where(better, wt, best)
            pick = np.where(better[:, None], low[t[:, 1], t[:, 0]], pick)
    return np.where(ok[:, None], out, pick)
