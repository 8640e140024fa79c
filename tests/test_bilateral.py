# SPDX-License-Identifier: GPL-3.0-or-later
"""Cross-bilateral filter (reference/bilateral.py, glsl/lib/bilateral.glsl): its weights are the
documented ones (a brute-force loop), constant images stay constant, light does not cross a depth or
normal edge, the interleaving pattern of N x N sub-images is removed, and the GLSL twin matches the
reference on llvmpipe. The range weight both filters of the library share, at its two settings: the
upsampler's (tangential 1: the whole distance) and the denoiser's (tangential 0: off the plane)."""

from __future__ import annotations

import numpy as np
import pytest

from vsgl_addon.reference.bilateral import bilateral_range_weight, cross_bilateral

EYE = np.array([0.0, 0.0, 5.0])


def two_planes(h=24, w=32):
    """A plane z = 0 (left) and one at z = 1 facing +x (right), a hole of uncovered pixels."""
    y, x = np.mgrid[0:h, 0:w].astype(float)
    position = np.zeros((h, w, 4))
    position[..., 0], position[..., 1] = x * 0.1, y * 0.1
    position[..., 3] = 1.0
    normal = np.zeros((h, w, 4))
    normal[..., 2] = 1.0
    right = x >= w // 2
    position[right, 2] = 1.0
    normal[right] = [1.0, 0.0, 0.0, 0.0]
    position[2:4, 2:4, 3] = 0.0
    return position, normal, right


def test_range_weight_at_both_settings():
    rng = np.random.default_rng(2)
    normal = rng.normal(size=(200, 3))
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    neighbour_normal = normal + 0.5 * rng.normal(size=(200, 3))
    neighbour_normal /= np.linalg.norm(neighbour_normal, axis=-1, keepdims=True)
    position = rng.normal(size=(200, 3))
    neighbour = np.concatenate([position + 0.3 * rng.normal(size=(200, 3)), np.ones((200, 1))], -1)
    neighbour[:10, 3] = 0.0  # background
    scale = rng.uniform(0.1, 2.0, 200)
    d = (neighbour[:, :3] - position) / scale[:, None]
    c = np.sum(normal * neighbour_normal, -1)
    wn = np.where(c > 0.0, np.maximum(c, 0.0) ** 8.0, 0.0) * (neighbour[:, 3] > 0.0)
    whole = bilateral_range_weight(position, normal, neighbour, neighbour_normal, scale, 1.0, 8.0)
    np.testing.assert_allclose(whole, np.exp(-0.5 * np.sum(d * d, -1)) * wn, rtol=1e-12, atol=1e-300)
    plane = bilateral_range_weight(position, normal, neighbour, neighbour_normal, scale, 0.0, 8.0)
    np.testing.assert_allclose(plane, np.exp(-0.5 * np.sum(normal * d, -1) ** 2) * wn, rtol=1e-12, atol=1e-300)
    assert np.all(plane >= whole) and np.all(whole[:10] == 0.0) and np.any(plane > whole)


def test_weights_are_the_documented_ones():
    """A brute-force loop of the weight exp(-|q - p|² / (2 s²)) · exp(-(n_p · (x_q - x_p) /
    (σ_plane |x_p - eye|))²) · max(n_p · n_q, 0)^power, s = radius / 2, for a few pixels."""
    rng = np.random.default_rng(4)
    position, normal, _ = two_planes(12, 16)
    position[..., :3] += 0.02 * rng.normal(size=position[..., :3].shape)
    normal[..., :3] += 0.2 * rng.normal(size=normal[..., :3].shape)
    normal[..., :3] /= np.linalg.norm(normal[..., :3], axis=-1, keepdims=True)
    image = rng.uniform(0.0, 1.0, position.shape[:2] + (3,))
    radius, sigma, power = 3, 0.05, 4.0
    out = cross_bilateral(image, position, normal, radius, EYE, sigma, power)
    for y, x in ((5, 5), (0, 0), (11, 15), (6, 8)):
        n, p = normal[y, x, :3], position[y, x, :3]
        total, weights = np.zeros(3), 0.0
        for qy in range(max(0, y - radius), min(12, y + radius + 1)):
            for qx in range(max(0, x - radius), min(16, x + radius + 1)):
                if position[qy, qx, 3] <= 0.0:
                    continue
                plane = n @ (position[qy, qx, :3] - p) / (sigma * np.linalg.norm(p - EYE))
                facing = n @ normal[qy, qx, :3]
                weight = (np.exp(-((qx - x) ** 2 + (qy - y) ** 2) / (2 * (radius / 2) ** 2) - plane**2)
                          * max(facing, 0.0) ** power if facing > 0.0 else 0.0)
                total += weight * image[qy, qx]
                weights += weight
        np.testing.assert_allclose(out[y, x], total / weights, rtol=1e-12)


def test_constant_preserved_edges_kept_pattern_removed():
    position, normal, right = two_planes()
    image = np.where(right[..., None], 2.0, 0.5) * np.ones((1, 1, 3))
    out = cross_bilateral(image, position, normal, 4, EYE, 0.05, 8.0)
    covered = position[..., 3] > 0
    np.testing.assert_allclose(out[covered], image[covered], rtol=1e-12)
    np.testing.assert_array_equal(out[~covered], 0.0)
    # A 2x2 interleaving pattern (weights 0 / 4x alternate) over a flat value averages out.
    pattern = np.ones(position.shape[:2])
    pattern[::2, ::2] = 4.0
    pattern[1::2, 1::2] = 0.0
    noisy = image * pattern[..., None]
    filtered = cross_bilateral(noisy, position, normal, 4, EYE, 0.05, 8.0)
    inner = covered.copy()
    inner[:, 12:20] = False
    inner[:6, :6] = False
    assert np.std(filtered[inner & ~right] / 0.5) < 0.2 * np.std(noisy[inner & ~right] / 0.5)


@pytest.mark.gpu
def test_glsl_twin_matches_reference():
    from glsl_harness import Accuracy, evaluate_glsl

    rng = np.random.default_rng(3)
    position, normal, _ = two_planes()
    position[..., :3] += 0.01 * rng.normal(size=position[..., :3].shape)
    normal[..., :3] += 0.1 * rng.normal(size=normal[..., :3].shape)
    normal[..., :3] /= np.linalg.norm(normal[..., :3], axis=-1, keepdims=True)
    image = np.concatenate([rng.uniform(0, 2, position.shape[:2] + (3,)), np.zeros(position.shape[:2] + (1,))], -1)
    position, normal, image = (a.astype(np.float32).astype(np.float64) for a in (position, normal, image))
    h, w = position.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w]
    pixel = np.column_stack([xx.ravel(), yy.ravel()]).astype(float)
    for radius, power in ((3, 8.0), (1, 0.0)):
        gpu = evaluate_glsl(f"cross_bilateral(image, guide_position, guide_normal, ivec2(pixel), {radius}, "
                            f"vec3(0.0, 0.0, 5.0), 0.05, {power:.1f})", {"pixel": pixel}, 3,
                            libraries=["lib/bilateral.glsl"],
                            images={"image": image, "guide_position": position, "guide_normal": normal})
        ref = cross_bilateral(image, position, normal, radius, EYE, 0.05, power).reshape(-1, 3)
        acc = Accuracy(gpu, ref, relative=2e-5)
        assert acc.ok, f"worst relative {acc.worst_relative:.3g}"


@pytest.mark.gpu
def test_denoise_pass_reads_images_and_gives_the_sampler_twins_floats():
    """The VPL pass's denoiser (passes/vpl_culling.py denoise: cross_bilateral's image overload, the
    inputs bound as images) gives the sampler overload's floats bit for bit, and the reference's
    within float32 rounding, at the pass's own parameters and a covered and uncovered border."""
    from glsl_harness import Accuracy, evaluate_glsl
    from vsgl_addon.passes import vpl_culling
    from vsgl_addon.passes.gpu_util import read_texture, texture_from_array

    rng = np.random.default_rng(5)
    position, normal, _ = two_planes()
    position[..., :3] += 0.002 * rng.normal(size=position[..., :3].shape)
    image = np.concatenate([rng.uniform(0, 2, position.shape[:2] + (3,)), np.zeros(position.shape[:2] + (1,))], -1)
    position, normal, image = (a.astype(np.float32).astype(np.float64) for a in (position, normal, image))
    h, w = position.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w]
    pixel = np.column_stack([xx.ravel(), yy.ravel()]).astype(float)
    sigma, power = vpl_culling.DENOISE_SIGMA_PLANE, vpl_culling.DENOISE_NORMAL_POWER
    textures = [texture_from_array(a.astype(np.float32)) for a in (image, position, normal)]
    for radius in (1, 4):
        out = read_texture(vpl_culling.denoise(*textures, radius, EYE), w, h)[..., :3].reshape(-1, 3)
        twin = evaluate_glsl(f"cross_bilateral(image, guide_position, guide_normal, ivec2(pixel), {radius}, "
                             f"vec3(0.0, 0.0, 5.0), {sigma!r}, {float(power):.1f})", {"pixel": pixel}, 3,
                             libraries=["lib/bilateral.glsl"],
                             images={"image": image, "guide_position": position, "guide_normal": normal})
        assert np.array_equal(out, twin), radius
        ref = cross_bilateral(image, position, normal, radius, EYE, sigma, power).reshape(-1, 3)
        acc = Accuracy(out, ref, relative=2e-5)
        assert acc.ok, f"worst relative {acc.worst_relative:.3g}"
