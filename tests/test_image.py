"""Image texture sampling (glsl/lib/image.glsl, the base colour of the RSM and G-buffer passes)
against its float64 twin (vsgl_addon/reference/image.py)."""

from __future__ import annotations

import numpy as np
import pytest

from vsgl_addon.reference.image import image_sample_linear_repeat

from glsl_harness import Accuracy, as_gpu_floats, evaluate_glsl


def test_reference_hits_texel_centres_and_wraps():
    image = np.arange(2 * 3 * 4, dtype=np.float64).reshape(2, 3, 4)  # H = 2, W = 3
    # Texel (row 1, column 2) at its centre, and one period further in u and v.
    for uv in ((2.5 / 3, 1.5 / 2), (2.5 / 3 + 1.0, 1.5 / 2 - 2.0)):
        np.testing.assert_allclose(image_sample_linear_repeat(image, np.array([uv])), image[1:2, 2, :3])
    # Halfway between the last and the first column (the edge): their mean.
    between = image_sample_linear_repeat(image, np.array([[1.0, 0.5 / 2]]))
    np.testing.assert_allclose(between, 0.5 * (image[0:1, 2, :3] + image[0:1, 0, :3]))


@pytest.mark.gpu
def test_image_sample_glsl_matches_numpy():
    rng = np.random.default_rng(9)
    image = rng.uniform(-0.5, 2.0, size=(5, 7, 4))  # not a power of two, negative values kept
    uv = rng.uniform(-3.0, 3.0, size=(3000, 2))
    uv[:8] = [[0.0, 0.0], [1.0, 1.0], [0.5 / 7, 0.5 / 5], [-1e-7, 0.5], [0.5, 1.0 - 1e-7],
              [6.5 / 7, 4.5 / 5], [-2.0, 3.0], [1e3 + 0.25, -1e3 + 0.75]]
    uv = as_gpu_floats(uv)
    image = as_gpu_floats(image.reshape(-1, 4)).reshape(image.shape)
    out = evaluate_glsl("image_sample_linear_repeat(base_color_image, uv)", {"uv": uv}, 3,
                        libraries=["lib/image.glsl"], images={"base_color_image": image})
    expected = image_sample_linear_repeat(image, uv)
    # float32 texel coordinates: u W − 0.5 rounds to ~1e-7 of |u| W, which moves the weights
    # (measured: 3.4e-6 relative at |u| up to 1e3).
    accuracy = Accuracy(out, expected, relative=5e-5, absolute=1e-6)
    print(accuracy.summary())
    assert accuracy.ok, accuracy.report({"uv": uv})
