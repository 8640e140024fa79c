# SPDX-License-Identifier: GPL-3.0-or-later
"""View geometry (vsgl_addon/views.py), pure numpy: the output size rule and band projections.
The camera matrices are checked against Blender's own in tests/test_scene_extraction.py, the RSM
views in tests/test_rsm.py."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from vsgl_addon import views


@pytest.mark.parametrize("x, y, percentage, expected", [
    (100, 77, 29, (29, 22)),  # 100 × 0.29 is 28.999... in float: Blender's integer rule gives 29
    (50, 101, 58, (29, 58)),  # 50 × 0.58 is 28.999... in float
    (101, 75, 33, (33, 24)),
    (99, 73, 37, (36, 27)),
    (101, 77, 50, (50, 38)),
    (97, 71, 67, (64, 47)),
    (101, 63, 100, (101, 63)),
    (4, 4, 1, (1, 1)),  # Blender's smallest settings: at least one pixel
])
def test_render_size_is_blenders_integer_rule(x, y, percentage, expected):
    render = SimpleNamespace(resolution_x=x, resolution_y=y, resolution_percentage=percentage)
    assert views.render_size(render) == expected


def test_band_projection_maps_the_band_to_the_full_viewport():
    projection = np.array([[1.2, 0, 0.1, 0], [0, 1.6, 0.05, 0], [0, 0, -1.002, -0.2], [0, 0, -1, 0]])
    band = views.band_projection(projection, 30, 60, 120)  # rows 30..60 of 120: NDC y in [-0.5, 0]
    point = np.array([0.3, -0.1, -5.0, 1.0])
    full, cropped = projection @ point, band @ point
    y_full, y_band = full[1] / full[3], cropped[1] / cropped[3]
    assert y_band == pytest.approx((y_full + 0.25) / 0.25)
    assert cropped[0] == full[0] and cropped[3] == full[3]


def test_band_projection_of_the_whole_image_is_the_projection():
    projection = np.array([[2.0, 0, 0, -0.1], [0, 1.5, 0, 0.2], [0, 0, -0.1, -1.01], [0, 0, 0, 1.0]])
    np.testing.assert_array_equal(views.band_projection(projection, 0, 48, 48), projection)


def test_camera_vector_perspective_and_orthographic():
    view = np.eye(4)
    view[:3, 3] = (-1.0, -2.0, -3.0)  # a camera at (1, 2, 3) looking down -Z
    perspective = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, -1.0, -0.2], [0, 0, -1.0, 0]])
    orthographic = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, -0.1, -1.0], [0, 0, 0, 1.0]])
    np.testing.assert_allclose(views.camera_vector(view, perspective), (1.0, 2.0, 3.0, 1.0))
    np.testing.assert_allclose(views.camera_vector(view, orthographic), (0.0, 0.0, 1.0, 0.0))


def test_views_imports_neither_bpy_nor_gpu():
    import subprocess
    import sys

    code = ("import sys; import vsgl_addon.views; "
            "print(sorted(m for m in ('bpy', 'gpu') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
