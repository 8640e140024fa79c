# SPDX-License-Identifier: GPL-3.0-or-later
"""View geometry (vsgl_addon/views.py), pure numpy: the output size rule, band projections and the
sun's view fit (the reflectors that can bounce light into the camera's view, at the extremes). The
camera matrices are checked against Blender's own in tests/test_scene_extraction.py, the RSM views'
flux on the GPU in tests/test_rsm.py."""

from __future__ import annotations

import math
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


# --- The sun's view: fitted to the reflectors that can bounce light into the camera's view ---------


def _look(direction, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """3x3 rotation whose -Z is ``direction``."""
    d = np.asarray(direction, np.float64) / np.linalg.norm(direction)
    up = np.asarray(up, np.float64) if abs(np.dot(up, d)) < 0.99 else np.array([0.0, 1.0, 0.0])
    x = np.cross(d, up)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(x, d), -d], axis=1)


def _camera(location, target, kind="PERSP", lens=50.0, ortho_scale=6.0, clip_end=100.0):
    from vsgl_addon.scene_description import Camera

    m = np.eye(4)
    m[:3, :3] = _look(np.subtract(target, location), up=(0.0, 0.0, 1.0))
    m[:3, 3] = location
    return Camera("Camera", m, kind, lens, 36.0, 24.0, "AUTO", ortho_scale, 0.0, 0.0, 0.1, clip_end,
                  (240, 180), (1.0, 1.0))


def _sun(direction):
    m = np.eye(4)
    m[:3, :3] = _look(direction)
    return SimpleNamespace(type="SUN", position=np.zeros(3), matrix_world=m,
                           direction=np.asarray(direction, np.float64) / np.linalg.norm(direction))


def _quad(corner, edge_u, edge_v) -> np.ndarray:
    """(2, 3, 3) triangles of the parallelogram corner + [0, 1] edge_u + [0, 1] edge_v."""
    p = np.asarray(corner, np.float64)
    u, v = np.asarray(edge_u, np.float64), np.asarray(edge_v, np.float64)
    return np.array([[p, p + u, p + u + v], [p, p + u + v, p + v]])


def _scene(quads, camera):
    positions = np.concatenate(quads) if quads else np.zeros((0, 3, 3))
    return SimpleNamespace(geometry=SimpleNamespace(positions=positions, triangle_count=len(positions)),
                           camera=camera)


def _covers(spec, points, tolerance=1e-6) -> np.ndarray:
    """(k,) whether each point lies inside the view's image rectangle (clip x, y in [-1, 1])."""
    clip = np.c_[np.asarray(points, np.float64).reshape(-1, 3), np.ones(len(points))] @ spec.view_projection.T
    return np.all(np.abs(clip[:, :2]) <= 1.0 + tolerance, axis=1)


def _ground(half, z=0.0):
    return _quad((-half, -half, z), (2.0 * half, 0.0, 0.0), (0.0, 2.0 * half, 0.0))


SUN_FROM_NORTH = (0.0, -math.cos(math.radians(40)), -math.sin(math.radians(40)))


def _courtyard(camera):
    """benchmarks/scenes/sun_courtyard.blend's layout: a 40 m ground, four 3.5 m walls round an 8 m
    courtyard, the camera inside it looking at the north wall."""
    return _scene([_ground(20.0),
                   _quad((-4.2, 4.1, 0.0), (8.4, 0.0, 0.0), (0.0, 0.0, 3.5)),  # north wall
                   _quad((-4.2, -4.1, 0.0), (8.4, 0.0, 0.0), (0.0, 0.0, 3.5)),  # south wall
                   _quad((4.1, -4.0, 0.0), (0.0, 8.0, 0.0), (0.0, 0.0, 3.5)),  # east wall
                   _quad((-4.1, -4.0, 0.0), (0.0, 8.0, 0.0), (0.0, 0.0, 3.5))], camera)  # west wall


def test_sun_reach_bounds_the_light_a_ground_beyond_it_gives_a_vertical_receiver():
    """Quadrature of the point-to-plane form factor of a vertical receiver at the seen box's height H
    over a lit ground: the ground beyond the reach gives at most SUN_REACH_TOLERANCE of the
    ground's light, and not much less (the reach is not wasted)."""
    seen = np.array([[0.0, 0.0, 0.0], [30.0, 12.0, 2.5]])
    height = 2.5
    reach = views.sun_reach(seen)
    assert reach == pytest.approx(4.0 / math.pi * height / views.SUN_REACH_TOLERANCE)
    # cos θ_x cos θ_y / (π d²) over the half plane in front of the receiver, in polar coordinates
    # (ρ, φ): (h ρ sin φ / (π (ρ² + h²)²)) ρ dρ dφ, φ integrated analytically (2).
    rho = np.geomspace(1e-6, 1e7, 400001)
    integrand = 2.0 * height * rho ** 2 / (math.pi * (rho ** 2 + height ** 2) ** 2)
    cumulative = np.r_[0.0, np.cumsum(0.5 * (integrand[1:] + integrand[:-1]) * np.diff(rho))]
    total = cumulative[-1]
    assert total == pytest.approx(0.5, rel=1e-4)
    beyond = total - np.interp(reach, rho, cumulative)
    assert 0.8 * views.SUN_REACH_TOLERANCE < beyond / total <= views.SUN_REACH_TOLERANCE


def test_sun_reach_of_a_flat_or_empty_view_is_zero():
    assert views.sun_reach(np.zeros((0, 3))) == 0.0
    assert views.sun_reach(np.array([[0.0, 0.0, 1.0], [5.0, 3.0, 1.0]])) == 0.0


def test_sun_view_holds_the_wall_behind_the_camera_that_lights_the_view():
    """The courtyard: the sunlit south wall behind the camera bounces light onto the north wall the
    camera sees; it lies outside the camera's frustum and inside the sun's view."""
    camera = _camera((1.5, -3.6, 1.6), (-0.6, 4.0, 1.6), lens=20.0, clip_end=1000.0)
    scene = _courtyard(camera)
    (spec,) = views.light_view_specs(scene, _sun(SUN_FROM_NORTH))
    south_wall = scene.geometry.positions[4:6].reshape(-1, 3)
    bounds = views._padded_bounds(views.scene_bounds(scene))
    seen = views.convex_hex_intersection(views.camera_frustum_corners(camera), views.box_corners(*bounds))
    assert seen[:, 1].min() > south_wall[:, 1].max(), "the camera must not see the south wall"
    assert np.all(_covers(spec, south_wall))
    # The reach (4/π · 3.5 m / 0.1 ≈ 45 m) spans the whole 40 m ground: every triangle is in the view.
    assert np.all(_covers(spec, scene.geometry.positions.reshape(-1, 3)))


def test_sun_view_over_a_huge_ground_stays_near_the_camera():
    """A 2 m box on a 10 km ground, the camera's far plane at 100 m: the view covers what the camera
    sees and the reach round it, not the 10 km (its texels stay a few decimetres at 1024²)."""
    camera = _camera((0.0, -10.0, 1.7), (0.0, 0.0, 1.0), clip_end=100.0)
    box = [_quad((-1.0, -1.0, 0.0), (2.0, 0.0, 0.0), (0.0, 0.0, 2.0)),
           _quad((-1.0, 1.0, 0.0), (2.0, 0.0, 0.0), (0.0, 0.0, 2.0)),
           _quad((-1.0, -1.0, 2.0), (2.0, 0.0, 0.0), (0.0, 2.0, 0.0))]
    scene = _scene([_ground(5000.0)] + box, camera)
    sun = _sun((0.3, 0.2, -1.0))
    (spec,) = views.light_view_specs(scene, sun)
    bounds = views._padded_bounds(views.scene_bounds(scene))
    seen = views.convex_hex_intersection(views.camera_frustum_corners(camera), views.box_corners(*bounds))
    assert np.all(_covers(spec, seen))
    assert np.all(_covers(spec, np.concatenate(box).reshape(-1, 3)))
    reach = views.sun_reach(seen)
    assert reach == pytest.approx(4.0 / math.pi * 2.0 / views.SUN_REACH_TOLERANCE, rel=2e-3)  # the box pad: 1e-7 of 10 km
    # At most the seen part's box grown by the reach, in any direction the sun looks from.
    assert max(spec.half_extent) <= 0.5 * float(np.linalg.norm(np.ptp(seen, axis=0) + 2.0 * reach)) * (1 + 1e-9)
    assert max(spec.half_extent) < 200.0
    assert np.all(np.isfinite(spec.view_projection))


def test_sun_view_with_the_camera_inside_a_closed_room_covers_the_room():
    half, height = 3.0, 3.0
    room = [_ground(half), _ground(half, z=height)] + [
        _quad((-half, y, 0.0), (2.0 * half, 0.0, 0.0), (0.0, 0.0, height)) for y in (-half, half)] + [
        _quad((x, -half, 0.0), (0.0, 2.0 * half, 0.0), (0.0, 0.0, height)) for x in (-half, half)]
    scene = _scene(room, _camera((0.0, 0.0, 1.5), (0.0, 1.0, 1.5), lens=35.0))
    (spec,) = views.light_view_specs(scene, _sun((0.2, -0.4, -1.0)))
    assert np.all(_covers(spec, scene.geometry.positions.reshape(-1, 3)))
    assert np.all(np.isfinite(spec.view_projection))


def test_sun_view_of_an_orthographic_camera_over_a_lit_plane_alone_is_its_window():
    """A flat lit plane bounces nothing onto itself: no reach, the view is the camera's 2 m x 1.5 m
    window of the 10 m plane (as tests/test_rsm.py's flux test measures on the GPU)."""
    camera = _camera((0.3, -0.2, 5.0), (0.3, -0.2, 0.0), kind="ORTHO", ortho_scale=2.0)
    scene = _scene([_ground(5.0)], camera)
    (spec,) = views.light_view_specs(scene, _sun((0.0, 0.0, -1.0)))
    assert (2.0 * spec.half_extent[0], 2.0 * spec.half_extent[1]) == pytest.approx((2.0, 1.5), rel=1e-3)


def test_sun_view_of_an_orthographic_camera_reaches_past_its_window_to_a_wall():
    """The same window of a 40 m plane with a 1 m wall standing 3 m outside it: the wall is within
    the reach of the part of the scene the camera sees (its box is 1 m high: 12.7 m), so the view
    holds it; the plane's far part is not."""
    camera = _camera((0.3, -0.2, 5.0), (0.3, -0.2, 0.0), kind="ORTHO", ortho_scale=2.0)
    wall = _quad((-1.0, 3.0, 0.0), (2.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    scene = _scene([_ground(20.0), wall], camera)
    sun = _sun((0.0, 0.3, -1.0))
    (spec,) = views.light_view_specs(scene, sun)
    assert np.all(_covers(spec, wall.reshape(-1, 3)))
    # Never wider than the whole scene's view (the fit is cut to the scene's box).
    (whole,) = views.light_view_specs(_scene([_ground(20.0), wall], None), sun)
    assert np.all(np.asarray(spec.half_extent) <= np.asarray(whole.half_extent) * (1.0 + 1e-9))
    assert max(spec.half_extent) < 0.75 * min(whole.half_extent)


@pytest.mark.parametrize("case", ["empty scene", "camera looks away", "no camera"])
def test_sun_view_degenerate_scenes(case):
    sun = _sun((0.0, 0.0, -1.0))
    if case == "empty scene":
        assert views.light_view_specs(_scene([], _camera((0.0, -5.0, 1.0), (0.0, 0.0, 0.0))), sun) == []
    elif case == "camera looks away":
        # Nothing of the scene in view: no receiver, no view (and no draw).
        scene = _scene([_ground(1.0)], _camera((0.0, 0.0, 50.0), (0.0, 0.0, 100.0)))
        assert views.light_view_specs(scene, sun) == []
    else:
        scene = _scene([_ground(4.0), _quad((-1.0, 0.0, 0.0), (2.0, 0.0, 0.0), (0.0, 0.0, 1.0))], None)
        (spec,) = views.light_view_specs(scene, sun)
        assert spec.half_extent == pytest.approx((4.0, 4.0), rel=1e-5)
