# SPDX-License-Identifier: GPL-3.0-or-later
"""VSGL shading with visibility from imperfect shadow maps (glsl/vsgl_shading/, VSGL_VISIBILITY 1)
against its float64 twin (reference/vsgl_shading.py shade(visibility=...) and vsgl_visibility)."""

from __future__ import annotations

import numpy as np
import pytest

from test_reference_ism import _geometry, _quad
from vsgl_addon import scene_points as sp
from vsgl_addon.passes import ism as ism_pass
from vsgl_addon.passes import vsgl_shading as shading_pass
from vsgl_addon.reference import vsgl_shading as vs

pytestmark = pytest.mark.gpu

CAMERA = np.array([-3.0, 0.2, 2.5])
# A floor, and a wall at x = 0.3 (y in [-2, 2], up to z = 1.5) between the VSGLs (x < 0) and a
# receiving wall at x = 1.2 facing them.
SCENE = _geometry(_quad(-2, -2, 2, 2) + [((0.3, -2, 0), (0.3, 2, 0), (0.3, 2, 1.5)),
                                         ((0.3, -2, 0), (0.3, 2, 1.5), (0.3, -2, 1.5))])


def _vsgls(count=6, seed=3):
    """VSGLs on the floor left of the wall, lobes up and sideways, each lobe at its own position."""
    rng = np.random.default_rng(seed)
    mean = np.stack([rng.uniform(-1.5, -0.3, count), rng.uniform(-1, 1, count), np.full(count, 0.02)], -1)
    axis = np.stack([rng.uniform(0.0, 0.6, count), rng.uniform(-0.3, 0.3, count), np.ones(count)], -1)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return {"diffuse_mean": mean, "diffuse_variance": rng.uniform(1e-3, 0.02, count),
            "diffuse_amplitude": rng.uniform(0.5, 2.0, (count, 3)), "diffuse_axis": axis,
            "diffuse_sharpness": rng.uniform(1.0, 3.0, count),
            "specular_mean": mean + [0.05, 0.0, 0.03], "specular_variance": rng.uniform(1e-3, 0.02, count),
            "specular_amplitude": rng.uniform(0.2, 1.0, (count, 3)), "specular_axis": axis,
            "specular_sharpness": rng.uniform(5.0, 40.0, count)}


def _gbuffer(height=12, width=16):
    """Half the pixels on the receiving wall behind the occluder, half on the floor before it."""
    v, u = np.meshgrid(np.linspace(0.1, 1.4, height), np.linspace(-1.5, 1.5, width), indexing="ij")
    wall = np.arange(width)[None, :] >= width // 2
    position = np.where(wall[..., None], np.stack([np.full_like(u, 1.2), u, v], -1),
                        np.stack([-1.8 + 0.1 * v, u, np.zeros_like(u)], -1))
    normal = np.where(wall[..., None], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]) * np.ones_like(position)
    return {"position": position, "coverage": np.ones((height, width)), "normal": normal,
            "roughness": np.full((height, width), 0.3), "diffuse_reflectance": np.full((height, width, 3), 0.7),
            "specular_f0": np.full((height, width, 3), 0.04)}, np.broadcast_to(wall, (height, width))


def _maps(vsgls, size=16):
    points = sp.scene_point_sets(SCENE, 4096, 8, seed=1)
    origins = np.stack([vsgls["diffuse_mean"], vsgls["specular_mean"]], 1).reshape(-1, 3)
    sigma = np.sqrt(np.stack([vsgls["diffuse_variance"], vsgls["specular_variance"]], 1).reshape(-1))
    return ism_pass.PASS.run(points, origins, sp.set_index(np.arange(len(origins)), 8), size,
                             min_distance=2.0 * sigma)


@pytest.fixture
def origin_sigmas(request):
    """The shadow origin offset of the test (passes/ism.py set_shadow_origin_sigmas), restored after."""
    from vsgl_addon.reference import ism

    saved = ism.SHADOW_ORIGIN_SIGMAS
    ism_pass.set_shadow_origin_sigmas(saved if request.param is None else request.param)
    yield ism.SHADOW_ORIGIN_SIGMAS
    ism_pass.set_shadow_origin_sigmas(saved)


# The default offset with both diffuse modes; another offset: the lookups centre each map where
# the reference does.
@pytest.mark.parametrize("diffuse_mode,origin_sigmas", [(vs.diffuse_mode_for_kernel("modified"), None),
                                                        ("cosine", None),
                                                        (vs.diffuse_mode_for_kernel("modified"), 1.0)],
                         indirect=["origin_sigmas"])
def test_shading_with_visibility_matches_the_reference_and_the_wall_shadows(diffuse_mode, origin_sigmas):
    vsgls = _vsgls()
    g, wall = _gbuffer()
    atlas = _maps(vsgls)
    table = shading_pass.upload_vsgl_table(vsgls)
    assert not table.shared_positions
    seen = shading_pass.VSGLTable(table.texture, table.count, False, atlas)
    gbuffer = shading_pass.upload_gbuffer(**g)
    try:
        gpu_d, gpu_s = shading_pass.shade_gpu(gbuffer, CAMERA, [seen], diffuse_mode)
        open_d, _ = shading_pass.shade_gpu(gbuffer, CAMERA, [table], diffuse_mode)
        depths = atlas.read()
    finally:
        ism_pass.PASS.free(atlas)
    position = g["position"].reshape(-1, 3).astype(np.float32).astype(np.float64)
    normal = g["normal"].reshape(-1, 3)
    view = CAMERA - position
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    f32 = {k: np.asarray(v, np.float32).astype(np.float64) for k, v in vsgls.items()}
    visibility = vs.vsgl_visibility(depths, 2, f32, position, normal, shading_pass.ISM_MAX_RADIUS)
    ref_d, ref_s = vs.shade(f32, position, normal, view, g["diffuse_reflectance"].reshape(-1, 3),
                            g["specular_f0"].reshape(-1, 3), g["roughness"].reshape(-1), visibility=visibility,
                            diffuse_mode=diffuse_mode)
    got_d, got_s = gpu_d[..., :3].reshape(-1, 3), gpu_s[..., :3].reshape(-1, 3)
    assert np.isfinite(got_d).all() and np.isfinite(got_s).all()
    # A pixel within float32 rounding of a filter texel's edge or its bias may count one texel
    # more or less; everywhere else the images agree to float32 sums.
    close = np.all(np.abs(got_d - ref_d) <= 1e-4 * np.abs(ref_d) + 1e-6 * np.abs(ref_d).max(), axis=1)
    assert close.mean() > 0.97, close.mean()
    # The occluder: the receiving wall behind it gets (almost) none of the light it gets without
    # visibility, the floor before it all of it.
    behind = wall.reshape(-1) & (position[:, 2] < 1.0)
    unshadowed = open_d[..., :3].reshape(-1, 3)
    assert got_d[behind].sum() <= 0.05 * unshadowed[behind].sum()
    # Before it, the maps hide nothing (the floor's own surface included: its shadow origin sits
    # above it, reference/ism.py shadow_origin).
    before = ~wall.reshape(-1)
    np.testing.assert_allclose(got_d[before], unshadowed[before], rtol=1e-4, atol=1e-6 * np.abs(unshadowed).max())


def test_visibility_off_reproduces_today_s_images_exactly():
    vsgls = _vsgls()
    g, _ = _gbuffer()
    gbuffer = shading_pass.upload_gbuffer(**g)
    table = shading_pass.upload_vsgl_table(vsgls)
    first = shading_pass.shade_gpu(gbuffer, CAMERA, [table])
    atlas = _maps(vsgls)
    try:
        shading_pass.shade_gpu(gbuffer, CAMERA, [shading_pass.VSGLTable(table.texture, table.count, False, atlas)])
    finally:
        ism_pass.PASS.free(atlas)
    again = shading_pass.shade_gpu(gbuffer, CAMERA, [table])
    for a, b in zip(first, again):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("surfaces, normal_offset", [(False, None), (True, None), (True, False)])
def test_a_table_whose_maps_keep_their_surfaces_takes_their_lookup(surfaces, normal_offset):
    """Sized maps that keep their surfaces or not (passes/ism.py ISMAtlas.surfaces), their lookups
    with the normal offset or not (ISMAtlas.normal_offset; None: as ``surfaces``, the sun's maps):
    the shading pass's lookups take the surface normal offset where the atlas says so (reference
    vsgl_visibility ``surfaces``), and the images match the reference's; the two lookups differ on
    this scene."""
    vsgls = _vsgls(count=8, seed=5)
    g, _ = _gbuffer()
    points = sp.scene_point_sets(SCENE, 4096, 8, seed=1)
    area = sp.triangle_areas(SCENE.positions).sum() / 4096
    origins = np.stack([vsgls["diffuse_mean"], vsgls["specular_mean"]], 1).reshape(-1, 3)
    sigma = np.sqrt(np.stack([vsgls["diffuse_variance"], vsgls["specular_variance"]], 1).reshape(-1))
    atlas = ism_pass.PASS.run(points, origins, sp.set_index(np.arange(len(origins)), 8), 16,
                              min_distance=2.0 * sigma, point_area=area, surfaces=surfaces,
                              normal_offset=normal_offset)
    offset = surfaces if normal_offset is None else normal_offset
    assert (atlas.surfaces, atlas.normal_offset) == (surfaces, offset)
    table = shading_pass.upload_vsgl_table(vsgls)
    seen = shading_pass.VSGLTable(table.texture, table.count, False, atlas)
    gbuffer = shading_pass.upload_gbuffer(**g)
    try:
        gpu_d, _ = shading_pass.shade_gpu(gbuffer, CAMERA, [seen], "cosine")
        depths = atlas.read()
    finally:
        ism_pass.PASS.free(atlas)
    position = g["position"].reshape(-1, 3).astype(np.float32).astype(np.float64)
    normal = g["normal"].reshape(-1, 3)
    view = CAMERA - position
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    f32 = {k: np.asarray(v, np.float32).astype(np.float64) for k, v in vsgls.items()}
    lookups = {s: vs.vsgl_visibility(depths, 2, f32, position, normal, shading_pass.ISM_MAX_RADIUS, surfaces=s)
               for s in (False, True)}
    assert not np.allclose(lookups[False], lookups[True])
    ref_d, _ = vs.shade(f32, position, normal, view, g["diffuse_reflectance"].reshape(-1, 3),
                        g["specular_f0"].reshape(-1, 3), g["roughness"].reshape(-1), visibility=lookups[offset],
                        diffuse_mode="cosine")
    got_d = gpu_d[..., :3].reshape(-1, 3)
    assert np.isfinite(got_d).all()
    close = np.all(np.abs(got_d - ref_d) <= 1e-4 * np.abs(ref_d) + 1e-6 * np.abs(ref_d).max(), axis=1)
    assert close.mean() > 0.97, close.mean()
