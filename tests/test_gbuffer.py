"""Camera G-buffer pass (vsgl_addon/passes/gbuffer.py): positions reproject to their pixels, normals
face the camera, materials and image textures land where they should, background is zero."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytestmark = pytest.mark.gpu


def _scene(kind="PERSP", image=False):
    import scene_builders as sb
    from vsgl_addon.scene import extract_scene

    sb.reset()
    img = None
    if image:
        img = sb.generated_image("Checker", 2, 2, float_buffer=True, colorspace="Linear Rec.709")
        img.pixels.foreach_set(np.array([1, 0, 0, 1, 0, 1, 0, 1, 0, 0, 1, 1, 1, 1, 0, 1], np.float32))
    floor = sb.principled("Floor", base_color=(0.7, 0.3, 0.1), roughness=0.35, metallic=0.25,
                          specular_ior_level=0.4, ior=1.6, image=img)
    box = sb.principled("Box", base_color=(0.1, 0.2, 0.9), roughness=0.8, metallic=1.0)
    sb.plane(size=4, material=floor)
    sb.box(size=1.0, location=(0.5, 0.3, 0.5), material=box)
    sb.camera(location=(0, -6, 3), look_at_point=(0, 0, 0.3), kind=kind, ortho_scale=6.0,
              resolution=(64, 48))
    return extract_scene(sb.depsgraph())


def _render(scene):
    from vsgl_addon.passes.gbuffer import render_camera_gbuffer
    from vsgl_addon.passes.rsm import SceneGPU

    scene_gpu = SceneGPU(scene)
    gbuffer = render_camera_gbuffer(scene_gpu)
    arrays = gbuffer.to_numpy()
    gbuffer.free()
    scene_gpu.free()
    return arrays


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_positions_reproject_to_their_pixels_and_normals_face_the_camera(kind):
    scene = _scene(kind)
    g = _render(scene)
    camera = scene.camera
    w, h = camera.resolution
    coverage = g["position"][..., 3] > 0.5
    assert 0.2 * w * h < coverage.sum() < w * h  # the floor fills much, not all of the image
    for name in ("position", "normal", "base_color", "material"):
        assert np.all(g[name][~coverage] == 0.0), name
        assert np.all(np.isfinite(g[name]))
    assert np.all(g["depth"][~coverage] == 1.0)
    # Reproject: each covered pixel's world position lands at its pixel centre.
    matrix = camera.projection_matrix() @ camera.view_matrix()
    p = g["position"][coverage][:, :3].astype(np.float64)
    clip = np.c_[p, np.ones(len(p))] @ matrix.T
    ndc = clip[:, :3] / clip[:, 3:4]
    rows, cols = np.nonzero(coverage)
    np.testing.assert_allclose((ndc[:, 0] + 1) * 0.5 * w, cols + 0.5, atol=2e-3)
    np.testing.assert_allclose((ndc[:, 1] + 1) * 0.5 * h, rows + 0.5, atol=2e-3)
    np.testing.assert_allclose(ndc[:, 2] * 0.5 + 0.5, g["depth"][coverage], atol=1e-5)
    # Normals: unit, facing the camera; the floor's is +Z, the box's are axis-aligned.
    n = g["normal"][coverage][:, :3]
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-6)
    from vsgl_addon.views import camera_vector

    cam = camera_vector(camera.view_matrix(), camera.projection_matrix())
    towards = cam[:3] - p if cam[3] > 0.5 else np.broadcast_to(cam[:3], p.shape)
    assert np.all(np.sum(n * towards, axis=-1) > 0.0)
    floor = np.abs(p[:, 2]) < 1e-5
    np.testing.assert_allclose(n[floor], np.tile([0, 0, 1.0], (floor.sum(), 1)), atol=1e-6)
    assert np.all(np.max(np.abs(n[~floor]), axis=-1) > 0.999)
    # Materials.
    floor_px = g["base_color"][coverage][floor]
    np.testing.assert_allclose(floor_px, np.tile([0.7, 0.3, 0.1, 0.25], (len(floor_px), 1)), atol=1e-6)
    np.testing.assert_allclose(g["normal"][coverage][floor][:, 3], 0.35, atol=1e-6)
    np.testing.assert_allclose(g["material"][coverage][floor][:, :2], np.tile([0.4, 1.6], (floor.sum(), 1)),
                               atol=1e-6)
    box_px = g["base_color"][coverage][~floor]
    np.testing.assert_allclose(box_px, np.tile([0.1, 0.2, 0.9, 1.0], (len(box_px), 1)), atol=1e-6)
    names = [m.name for m in scene.materials]
    np.testing.assert_array_equal(g["material"][coverage][floor][:, 2], names.index("Floor"))
    np.testing.assert_array_equal(g["material"][coverage][~floor][:, 2], names.index("Box"))


def test_image_texture_is_sampled_at_the_uv():
    scene = _scene(image=True)
    g = _render(scene)
    coverage = g["position"][..., 3] > 0.5
    p = g["position"][coverage][:, :3].astype(np.float64)
    floor = np.abs(p[:, 2]) < 1e-5
    uv = (p[floor, :2] + 2.0) / 4.0  # the plane's planar UVs: 0..1 over its 4 m
    image = np.array([[[1, 0, 0], [0, 1, 0]], [[0, 0, 1], [1, 1, 0]]], np.float64)  # row 0 = bottom
    x = uv * 2 - 0.5
    i0 = np.floor(x).astype(int)
    f = x - i0

    def texel(ix, iy):
        return image[iy % 2, ix % 2]

    expected = ((1 - f[:, :1]) * (1 - f[:, 1:]) * texel(i0[:, 0], i0[:, 1]) +
                f[:, :1] * (1 - f[:, 1:]) * texel(i0[:, 0] + 1, i0[:, 1]) +
                (1 - f[:, :1]) * f[:, 1:] * texel(i0[:, 0], i0[:, 1] + 1) +
                f[:, :1] * f[:, 1:] * texel(i0[:, 0] + 1, i0[:, 1] + 1))
    np.testing.assert_allclose(g["base_color"][coverage][floor][:, :3], expected, atol=2e-3)


def test_empty_scene_is_all_background():
    import scene_builders as sb
    from vsgl_addon.passes.gbuffer import render_gbuffer
    from vsgl_addon.passes.rsm import SceneGPU
    from vsgl_addon.scene import extract_scene

    sb.reset()
    sb.camera(resolution=(8, 6))
    scene = extract_scene(sb.depsgraph())
    scene_gpu = SceneGPU(scene)
    gbuffer = render_gbuffer(scene_gpu, scene.camera.view_matrix(), scene.camera.projection_matrix(), (8, 6))
    arrays = gbuffer.to_numpy()
    gbuffer.free()
    assert all(np.all(arrays[name] == 0.0) for name in ("position", "normal", "base_color", "material"))
    assert np.all(arrays["depth"] == 1.0)
