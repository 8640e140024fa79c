# SPDX-License-Identifier: GPL-3.0-or-later
"""Mipmaps, trilinear lookups, the Fibonacci lattice and hierarchical sample warping, float64.

The sampling half of filtered importance sampling on a reflective shadow map (RSM)
(000 = Tokuyoshi, "Modified filtered importance sampling for virtual spherical Gaussian lights",
CVM 2016, §3-4 and app. D). ``vsgl.py`` builds the VSGLs on top of it.

Conventions (shared with the GPU version, which must do the same):

* Images are arrays of shape (H, W) or (H, W, C) with H = W = 2^n, n >= 0 (1x1 works).
* Image coordinates x = (u, v) in [0, 1]^2: u runs along W (columns), v along H (rows); texel
  (row i, column j) covers [j/W, (j+1)/W) x [i/H, (i+1)/H). With row 0 uploaded first this is
  OpenGL's texture coordinate (s, t) = (u, v).
* Mip level 0 is the image (M = H W texels), level l has (H/2^l) x (W/2^l) texels, each the
  *mean* of its 2x2 children (a box filter, what glGenerateMipmap / GenerateMips compute for
  power-of-two sizes); the top level L = log2(H) is 1x1. A level-l texel covers the area 4^l / M of
  [0, 1]^2 (000 §3.1: a_i = 4^l_i / M).
* p̄(x, l) at a fractional level (000 Eq. 3, Algorithm 1): GL_LINEAR_MIPMAP_LINEAR filtering with
  CLAMP_TO_EDGE, i.e. bilinear filtering (texel centres at (j + 0.5)/W) inside the levels floor(l)
  and floor(l) + 1, then linear interpolation in l. Why this filter:
  - it is what ``textureLod`` returns on any GPU, so the GPU version needs no custom filter;
  - it is continuous in x and in l, so a kernel centre or a kernel level that moves a little
    between frames changes the filtered value a little (000's point is temporal coherence);
  - bilinear filtering with clamp-to-edge preserves the integral over [0, 1]^2 of each level (the
    tent weights of interior texels integrate to one texel area, and the clamped half-tents at the
    border add up to the same), so a fixed-level lookup averaged over uniform x returns the image
    mean exactly; the unbiasedness of Eqs. 4-5 rests on that.
  The weights are exact float64 here; GPU hardware rounds the bilinear and level fractions to ~8
  bits, so a GPU comparison needs a tolerance of that order (or filters in the shader).
"""

from __future__ import annotations

import numpy as np

from .numerics import f64

#: Golden-ratio conjugate (sqrt(5) - 1) / 2 = 1/phi: the irrational stand-in for the ratio
#: F_(k-1)/F_k of consecutive Fibonacci numbers, which makes the Fibonacci lattice work for any
#: point count N (000 §5, "Fibonacci lattice point set using a golden ratio approximation").
GOLDEN_RATIO_CONJUGATE = (np.sqrt(5.0) - 1.0) / 2.0

#: Largest float64 below 1: samples live in [0, 1) and rescaled samples are clamped to it.
_BELOW_ONE = float(np.nextafter(1.0, 0.0))


def mip_level_count(size: int) -> int:
    """Number of levels of a size x size image (size a power of two): log2(size) + 1."""
    return int(size).bit_length()


def check_square_power_of_two(shape) -> int:
    """Validate an image shape (H, W, ...) with H = W = 2^n >= 1; return H."""
    if len(shape) < 2:
        raise ValueError(f"an image needs at least 2 dimensions, got shape {tuple(shape)}")
    height, width = int(shape[0]), int(shape[1])
    if height != width or height < 1 or (height & (height - 1)) != 0:
        raise ValueError(f"image must be square with a power-of-two side, got {height}x{width}")
    return height


def build_mip_chain(image) -> list[np.ndarray]:
    """Box-filtered mip chain [level 0 = image, ..., top level 1x1], each texel the mean of 2x2.

    Means rather than sums: a level-l mean times 4^l is the sum of the texels it covers, and a mean
    is what a GPU mipmap holds (000 §4.1, Fig. 4).
    """
    image = f64(image)
    size = check_square_power_of_two(image.shape)
    chain = [image]
    while size > 1:
        size //= 2
        prev = chain[-1]
        chain.append(
            0.25 * (prev[0::2, 0::2] + prev[0::2, 1::2] + prev[1::2, 0::2] + prev[1::2, 1::2])
        )
    return chain


def bilinear(level_image, uv) -> np.ndarray:
    """Bilinear lookup of one mip level at uv (N, 2), CLAMP_TO_EDGE; returns (N, ...)."""
    level_image = f64(level_image)
    uv = f64(uv)
    height, width = level_image.shape[:2]
    s = uv[:, 0] * width - 0.5
    t = uv[:, 1] * height - 0.5
    j0 = np.floor(s)
    i0 = np.floor(t)
    fx = s - j0
    fy = t - i0
    j0 = j0.astype(np.int64)
    i0 = i0.astype(np.int64)
    ja = np.clip(j0, 0, width - 1)
    jb = np.clip(j0 + 1, 0, width - 1)
    ia = np.clip(i0, 0, height - 1)
    ib = np.clip(i0 + 1, 0, height - 1)
    extra = (slice(None),) + (None,) * (level_image.ndim - 2)
    fx = fx[extra]
    fy = fy[extra]
    top = (1.0 - fx) * level_image[ia, ja] + fx * level_image[ia, jb]
    bottom = (1.0 - fx) * level_image[ib, ja] + fx * level_image[ib, jb]
    return (1.0 - fy) * top + fy * bottom


def sample_all_levels(chain, uv) -> np.ndarray:
    """Bilinear lookups of every level at uv: array (levels, N, ...).

    Used where the same kernel centres are looked up at many fractional levels (the bisection of
    000 Algorithm 1), so each level is filtered once.
    """
    return np.stack([bilinear(level, uv) for level in chain])


def interpolate_levels(per_level, level) -> np.ndarray:
    """Linear interpolation in l between integer-level lookups (levels, N, ...) at level (N,).

    ``level`` is clamped to [0, top]; at an integer level the result is that level's lookup.
    """
    per_level = f64(per_level)
    top = per_level.shape[0] - 1
    level = np.clip(f64(level), 0.0, float(top))
    lower = np.minimum(np.floor(level).astype(np.int64), top)
    upper = np.minimum(lower + 1, top)
    frac = level - lower
    index = np.arange(per_level.shape[1])
    a = per_level[lower, index]
    b = per_level[upper, index]
    frac = frac[(slice(None),) + (None,) * (a.ndim - 1)]
    return (1.0 - frac) * a + frac * b


def trilinear(chain, uv, level) -> np.ndarray:
    """p̄(x, l): bilinear in levels floor(l) and floor(l)+1, linear in between (000 Eq. 3)."""
    return interpolate_levels(sample_all_levels(chain, uv), level)


def fibonacci_lattice(count: int, rotation=(0.0, 0.0)) -> np.ndarray:
    """Stratified points in [0, 1)^2: the Fibonacci lattice with the golden-ratio approximation.

    x_i = ((i + 0.5)/N, frac(i / phi)) + rotation (mod 1), i = 0..N-1 (000 §5 and app. D; the
    golden-ratio conjugate replaces F_(k-1)/F_k so any N works). ``rotation`` is a
    Cranley-Patterson shift: with a uniform random rotation every point is uniform on [0, 1)^2
    while the set keeps its stratification, which makes the kernel estimators unbiased in
    expectation over rotations.
    """
    count = int(count)
    if count < 1:
        raise ValueError(f"need at least one lattice point, got {count}")
    rotation = f64(rotation).reshape(2)
    i = np.arange(count, dtype=np.float64)
    points = np.stack([(i + 0.5) / count, i * GOLDEN_RATIO_CONJUGATE], axis=-1) + rotation
    points -= np.floor(points)
    # x - floor(x) can round up to exactly 1.0 for x just below an integer.
    return np.minimum(points, _BELOW_ONE)


def _warp_split(u, first, total):
    """One binary choice of the warp: (u < P, u rescaled to [0, 1) inside the chosen side) with
    P = first / total (1/2 for a block of zero mass)."""
    p_first = np.divide(first, total, out=np.full_like(first, 0.5), where=total > 0.0)
    go_first = u < p_first
    u = np.where(
        go_first,
        u / np.where(go_first, p_first, 1.0),
        (u - p_first) / np.where(go_first, 1.0, 1.0 - p_first),
    )
    return go_first, np.clip(u, 0.0, _BELOW_ONE)


def warp_hierarchical(pdf_chain, samples) -> tuple[np.ndarray, np.ndarray]:
    """Hierarchical sample warping through a PDF mipmap (000 §2.2, §3.2, [12]: Clarberg et al.).

    Top-down from the 1x1 level: inside the current texel pick the left or right column of its 2x2
    children with probability proportional to the column's mass and rescale u to [0, 1); then pick
    the upper or lower child of that column in proportion to their masses and rescale v. At level 0
    the remaining (u, v) places the point uniformly inside the chosen texel. Children of equal area
    have masses proportional to their means, so the mipmap of means suffices.

    The warp is a bijection from [0, 1)^2 to the texels of non-zero mass, piecewise affine, and the
    density of the output is the level-0 image normalized to mean 1 (tested), so warped stratified
    points stay stratified. Texels of zero mass are never chosen: u < 0 is never true and
    (u - 0)/(1 - 0) passes u through.

    Returns ``(uv, texel)``: positions (N, 2) in [0, 1)^2 and the level-0 texel (N, 2) as
    (row, column) each point landed in.
    """
    samples = f64(samples)
    u = samples[:, 0].copy()
    v = samples[:, 1].copy()
    row = np.zeros(u.shape, dtype=np.int64)
    col = np.zeros(u.shape, dtype=np.int64)
    for level in range(len(pdf_chain) - 2, -1, -1):
        img = f64(pdf_chain[level])
        r0 = 2 * row
        c0 = 2 * col
        m00 = img[r0, c0]
        m01 = img[r0, c0 + 1]
        m10 = img[r0 + 1, c0]
        m11 = img[r0 + 1, c0 + 1]
        left = m00 + m10
        go_left, u = _warp_split(u, left, left + m01 + m11)
        col = np.where(go_left, c0, c0 + 1)
        go_upper, v = _warp_split(v, np.where(go_left, m00, m01), np.where(go_left, left, m01 + m11))
        row = np.where(go_upper, r0, r0 + 1)
    size = f64(pdf_chain[0]).shape[0]
    uv = np.stack([(col + u) / size, (row + v) / size], axis=-1)
    return np.minimum(uv, _BELOW_ONE), np.stack([row, col], axis=-1)
