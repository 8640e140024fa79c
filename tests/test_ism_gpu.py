# SPDX-License-Identifier: GPL-3.0-or-later
"""The imperfect-shadow-map pass on the GPU (vsgl_addon/passes/ism.py, glsl/ism/, glsl/lib/ism.glsl)
against its float64 twin (vsgl_addon/reference/ism.py)."""

from __future__ import annotations

import numpy as np
import pytest

from glsl_harness import as_gpu_floats, evaluate_glsl
from test_reference_ism import _geometry, _quad
from vsgl_addon import scene_points as sp
from vsgl_addon.passes import ism as ism_pass
from vsgl_addon.reference import ism

pytestmark = pytest.mark.gpu


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_glsl_octahedral_projection_matches_the_reference():
    rng = np.random.default_rng(1)
    d = as_gpu_floats(np.concatenate([_unit(rng.normal(size=(4000, 3))), np.eye(3), -np.eye(3)]))
    got = evaluate_glsl("octahedral_encode(d)", {"d": d}, 2, libraries=["lib/ism.glsl"])
    np.testing.assert_allclose(got, ism.octahedral_encode(d), atol=3e-7)
    back = evaluate_glsl("octahedral_decode(uv)", {"uv": as_gpu_floats(got)}, 3, libraries=["lib/ism.glsl"])
    np.testing.assert_allclose(back, d, atol=2e-6)
    for size in (1, 8, 64):
        texel = evaluate_glsl(f"vec2(ism_texel(d, {size}))", {"d": d}, 2, libraries=["lib/ism.glsl"])
        expected = ism.ism_texel(d, size)
        # float32 may put a direction within rounding of a texel edge into the neighbour.
        uv = (ism.octahedral_encode(d) * 0.5 + 0.5) * size
        near_edge = np.any(np.abs(uv - np.round(uv)) < 1e-5, axis=-1)
        assert np.array_equal(texel[~near_edge], expected[~near_edge]), size


def _atlas(points, origins, set_index, size, **kwargs):
    atlas = ism_pass.PASS.run(points, origins, set_index, size, **kwargs)
    try:
        return atlas.read()
    finally:
        ism_pass.PASS.free(atlas)


def _reference(points, origins, set_index, size, min_distance=0.0, planes=None):
    planes = [None] * len(set_index) if planes is None else planes
    return np.stack([ism.pull_push(ism.close_gaps(ism.splat(points.positions[s], o, size, min_distance, plane=h)))
                     for o, s, h in zip(np.asarray(origins, np.float64), set_index, planes)])


def test_splat_and_pull_push_match_the_reference_on_texel_centres():
    """Points on the directions of texel centres (no rounding can move them to a neighbour), at
    random distances, two sets, five maps in a 3 × 2 atlas: the same depths as the float64 twin."""
    size, rng = 16, np.random.default_rng(7)
    directions = ism.texel_directions(size).reshape(-1, 3)
    origins = rng.uniform(-1, 1, size=(5, 3))
    sets = []
    for s in range(2):
        chosen = directions[rng.choice(len(directions), 120, replace=False)]
        sets.append(chosen * rng.uniform(0.5, 4.0, size=(120, 1)))
    positions = np.stack(sets)  # relative to origin 0 for set 0; other maps see them off-centre
    points = sp.ScenePoints((positions + origins[0]).astype(np.float32), np.zeros_like(positions, np.float32),
                            np.zeros(positions.shape[:2], np.int64))
    set_index = np.array([0, 1, 0, 1, 0])
    got = _atlas(points, origins[:1].repeat(5, 0), set_index, size)
    expected = _reference(points, origins[:1].repeat(5, 0), set_index, size)
    np.testing.assert_allclose(got, expected, rtol=2e-6)
    assert np.isfinite(got).all()


def test_half_spaces_leave_out_the_same_points_as_the_reference():
    """Points on texel-centre directions, maps with the half-space of a floor seen from just above it,
    a tilted one, one that keeps every point (n = 0, c = 0) and one that keeps none: the GPU's maps
    equal the float64 twin's (no point within rounding of a plane)."""
    size, rng = 16, np.random.default_rng(3)
    directions = ism.texel_directions(size).reshape(-1, 3)
    chosen = directions[rng.choice(len(directions), 200, replace=False)] * rng.uniform(0.5, 4.0, size=(200, 1))
    tilted = _unit(np.array([1.0, -2.0, 3.0]))
    planes = np.array([[0.0, 0.0, 1.0, -0.01], [*tilted, 0.3], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1e30]])
    heights = chosen @ planes[:2, :3].T - planes[:2, 3]
    chosen = chosen[np.all(np.abs(heights) > 1e-3, axis=-1)]
    points = sp.ScenePoints(chosen[None].astype(np.float32), np.zeros((1, len(chosen), 3), np.float32),
                            np.zeros((1, len(chosen)), np.int64))
    origins = np.zeros((4, 3))
    got = _atlas(points, origins, [0, 0, 0, 0], size, planes=planes)
    expected = _reference(points, origins, [0, 0, 0, 0], size, planes=planes)
    np.testing.assert_allclose(got, expected, rtol=2e-6)
    np.testing.assert_allclose(got[2], _reference(points, origins[:1], [0], size)[0], rtol=2e-6)
    assert np.all(got[3] == ism.EMPTY) and not np.array_equal(got[0], got[2])
    assert np.isfinite(got[:3]).all()


def test_a_scene_s_maps_match_the_reference_but_for_texels_at_rounding_edges():
    scene = _geometry(_quad(-4, -4, 4, 4) + [((1, -2, 0), (1, 2, 0), (1, 2, 3)), ((1, -2, 0), (1, 2, 3), (1, -2, 3))])
    points = sp.scene_point_sets(scene, 4096, 3, seed=2)
    origins = np.array([[0.0, 0.0, 1.5], [-1.0, 0.5, 0.2], [2.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    set_index = sp.set_index(np.arange(len(origins)), points.set_count)
    got = _atlas(points, origins, set_index, 32)
    expected = _reference(points, origins, set_index, 32)
    close = np.isclose(got, expected, rtol=1e-5)
    assert close.mean() > 0.995, close.mean()
    assert np.isfinite(got).all()


@pytest.mark.parametrize("size,per_set", [(1, 1), (8, 1), (8, 3), (64, 16384)])
def test_extremes_one_texel_maps_one_point_and_a_map_no_point_reaches(size, per_set):
    points = sp.scene_point_sets(_geometry(_quad(-1, -1, 1, 1)), per_set, 2, seed=0)
    origins = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    got = _atlas(points, origins, [0, 1], size)
    expected = _reference(points, origins, [0, 1], size)
    np.testing.assert_allclose(got, expected, rtol=2e-6)
    # A map whose origin is its only point holds nothing: the point is not its own occluder.
    lone = sp.ScenePoints(np.zeros((1, 1, 3), np.float32), np.zeros((1, 1, 3), np.float32), np.zeros((1, 1), np.int64))
    assert np.all(_atlas(lone, np.zeros((1, 3)), [0], size) == ism.EMPTY)


def test_the_pass_declares_its_contract():
    assert set(ism_pass.PASS.shaders) == {"origins", "splat", "close", "pull", "push", "push_final"}
    ism_pass.PASS.compile_shaders()
    ism_pass.PASS.free_shaders()
    with pytest.raises(ValueError):
        ism_pass.PASS.run(sp.scene_point_sets(_geometry(_quad(0, 0, 1, 1)), 4, 1), np.zeros((1, 3)), [0], 12)


@pytest.fixture
def lookup_bias(request):
    """The lookup's bias of the test (passes/ism.py set_lookup_bias: receiver offset along the
    normal in footprints, depth bias left in texels; None the default), restored after."""
    saved = ism.NORMAL_OFFSET, ism.NORMAL_OFFSET_DEPTH, ism.BACK_OFFSET, ism.SPREAD_BIAS
    if request.param is not None:
        ism_pass.set_lookup_bias(*request.param)
    yield ism.NORMAL_OFFSET, ism.NORMAL_OFFSET_DEPTH, ism.BACK_OFFSET, ism.SPREAD_BIAS
    ism_pass.set_lookup_bias(*saved)


# (normal offset, depth bias left, back offset, spread cap): the slope-scaled depth bias; receivers
# moved along their normal; the depth bias with receivers facing away moved away; both moved; the
# depth bias capped by the map's spread.
LOOKUP_BIASES = [(0.0, 0.5, 0.0, 0.0), (1.0, 0.5, 0.0, 0.0), (0.0, 0.5, 1.0, 0.0), (1.5, 1.0, 0.5, 0.0),
                 (0.0, 0.5, 0.0, 1.5)]


@pytest.mark.parametrize("lookup_bias", LOOKUP_BIASES, indirect=True)
def test_glsl_filtered_lookup_matches_the_reference(lookup_bias):
    """ism_pcf on a scene's filled map, for receivers all around the origin (every fold of the
    octahedral map) at radii 0, 1 and 3, with their normals (slope-scaled bias, or the receiver
    moved along its normal)."""
    scene = _geometry(_quad(-4, -4, 4, 4) + [((1, -2, 0), (1, 2, 0), (1, 2, 3)), ((1, -2, 0), (1, 2, 3), (1, -2, 3))])
    points = sp.scene_point_sets(scene, 20000, 1, seed=4)
    origin = np.array([0.0, 0.0, 1.5])
    size = 16
    depth = ism.pull_push(ism.splat(points.positions[0], origin, size))
    rng = np.random.default_rng(9)
    receivers = as_gpu_floats(rng.uniform([-4, -4, -1], [4, 4, 3], size=(3000, 3)))
    normals = as_gpu_floats(_unit(rng.normal(size=(3000, 3))))
    # The atlas as the pass leaves it: one tile at (16, 0) of a 2 × 1 atlas, r = depth (UNKNOWN_DEPTH
    # where nothing landed).
    atlas = np.zeros((size, 2 * size, 4))
    atlas[:, size:, 0] = np.where(np.isfinite(depth), depth, ism_pass.UNKNOWN_DEPTH)
    for radius in (0, 1, 3):
        got = evaluate_glsl(f"ism_pcf(ism_atlas, ivec2({size}, 0), {size}, origin, receiver, normal, {radius})",
                            {"origin": np.tile(origin, (3000, 1)), "receiver": receivers, "normal": normals}, 1,
                            libraries=["lib/ism.glsl"], images={"ism_atlas": atlas})
        expected = ism.ism_pcf(depth, origin, receivers, radius, normals=normals)
        # A receiver within float32 rounding of a texel edge or of its bias may count one texel more or less.
        assert np.mean(np.abs(got - expected) < 1e-6) > 0.99, radius
        assert np.abs(got - expected).max() <= 1.0 / (2 * radius + 1) ** 2 + 1e-6


def test_sized_splats_match_the_reference():
    """Splats sized by the solid angle of each point's share of the surface (point_area > 0)."""
    scene = _geometry(_quad(-4, -4, 4, 4) + [((1, -2, 0), (1, 2, 0), (1, 2, 3)), ((1, -2, 0), (1, 2, 3), (1, -2, 3))])
    points = sp.scene_point_sets(scene, 1024, 2, seed=5)
    area = sp.triangle_areas(scene.positions).sum() / 1024
    origins = np.array([[0.0, 0.0, 0.5], [0.7, 0.3, 0.2]])
    atlas = ism_pass.PASS.run(points, origins, [0, 1], 32, point_area=area)
    try:
        got = atlas.read()
    finally:
        ism_pass.PASS.free(atlas)
    expected = np.stack([ism.pull_push(ism.close_gaps(ism.splat(points.positions[s], o, 32, normals=points.normals[s],
                                                                point_area=area))) for o, s in zip(origins, [0, 1])])
    assert np.isclose(got, expected, rtol=1e-5).mean() > 0.99
    radius = ism.splat_radius(points.positions[0] - origins[0], 1.0, area, 32)
    assert radius.max() >= 2  # near points cover several texels, far ones one
    assert radius.min() == 0


def test_maps_that_would_not_fit_one_atlas_get_a_smaller_side(monkeypatch):
    monkeypatch.setattr(ism_pass, "MAX_ATLAS_SIDE", 256)
    assert ism_pass.fitting_size(8, 128) == 64 and ism_pass.fitting_size(4, 128) == 128
    assert ism_pass.fitting_size(10 ** 6, 64) == 1
    with pytest.raises(ValueError):
        ism_pass.atlas_layout(8, 128)


@pytest.mark.parametrize("lookup_bias", LOOKUP_BIASES, indirect=True)
def test_glsl_bilinear_and_nearest_lookups_match_the_reference(lookup_bias):
    """ism_pcf_bilinear (receivers all around the origin: blocks at the square's edges are kept
    inside it) and ism_visible_nearest (ism_pcf at radius 0) against the float64 twin, with either
    bias."""
    scene = _geometry(_quad(-4, -4, 4, 4) + [((1, -2, 0), (1, 2, 0), (1, 2, 3)), ((1, -2, 0), (1, 2, 3), (1, -2, 3))])
    points = sp.scene_point_sets(scene, 20000, 1, seed=4)
    origin = np.array([0.0, 0.0, 1.5])
    size = 16
    depth = ism.pull_push(ism.close_gaps(ism.splat(points.positions[0], origin, size)))
    rng = np.random.default_rng(11)
    receivers = as_gpu_floats(rng.uniform([-4, -4, -1], [4, 4, 3], size=(3000, 3)))
    normals = as_gpu_floats(_unit(rng.normal(size=(3000, 3))))
    atlas = np.zeros((size, 2 * size, 4))
    atlas[:, size:, 0] = np.where(np.isfinite(depth), depth, ism_pass.UNKNOWN_DEPTH)
    inputs = {"origin": np.tile(origin, (3000, 1)), "receiver": receivers, "normal": normals}
    got = evaluate_glsl(f"ism_pcf_bilinear(ism_atlas, ivec2({size}, 0), {size}, origin, receiver, normal)", inputs, 1,
                        libraries=["lib/ism.glsl"], images={"ism_atlas": atlas})
    expected = ism.ism_pcf_bilinear(depth, origin, receivers, normals=normals)
    # A receiver within float32 rounding of its bias may count one texel (its weight) more or less.
    assert np.mean(np.abs(got - expected) < 1e-5) > 0.99
    assert np.abs(got - expected).max() <= 1.0 + 1e-6
    assert np.mean((expected > 0.01) & (expected < 0.99)) > 0.005  # the filter is soft somewhere
    got = evaluate_glsl(f"ism_visible_nearest(ism_atlas, ivec2({size}, 0), {size}, origin, receiver, normal)", inputs, 1,
                        libraries=["lib/ism.glsl"], images={"ism_atlas": atlas})
    expected = ism.ism_pcf(depth, origin, receivers, 0, normals=normals)
    assert np.mean(got == expected) > 0.99


def _vsgl_table(count, seed=5):
    """A VSGL dict with each lobe at its own position; variances from 0 (and a negative one, clamped)
    to a wide spread, axes of every direction."""
    rng = np.random.default_rng(seed)
    table = {}
    for lobe in ("diffuse", "specular"):
        table[f"{lobe}_mean"] = rng.uniform(-5.0, 5.0, (count, 3))
        table[f"{lobe}_variance"] = np.exp(rng.uniform(np.log(1e-8), np.log(4.0), count))
        table[f"{lobe}_axis"] = _unit(rng.normal(size=(count, 3)))
        table[f"{lobe}_amplitude"] = np.ones((count, 3))
        table[f"{lobe}_sharpness"] = np.ones(count)
    table["diffuse_variance"][0] = 0.0
    if count > 1:
        table["specular_variance"][1] = -1e-3
    return table


@pytest.mark.parametrize("count,maps_per_vsgl,first_map,point_sets,sigmas",
                         [(1, 1, 0, 1, 0.0), (37, 1, 5, 8, 1.0), (37, 2, 61, 64, 2.5), (300, 2, 0, 64, 1e-6)])
def test_glsl_vsgl_map_origins_match_the_reference(count, maps_per_vsgl, first_map, point_sets, sigmas):
    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.passes.vsgl_shading import upload_vsgl_table

    vsgls = _vsgl_table(count)
    table = upload_vsgl_table(vsgls)
    origins = ism_pass.vsgl_map_origins(table.texture, count, maps_per_vsgl, first_map, point_sets, sigmas)
    assert origins.count == count * maps_per_vsgl
    got = read_texture(origins.texture, origins.count, 3).astype(np.float64)
    # The reference reads the float32 table the texture holds.
    stored = {name: np.asarray(value, np.float32) for name, value in vsgls.items()}
    want_origins, want_sets, want_distance = ism.vsgl_map_origins(stored, maps_per_vsgl, first_map, point_sets, sigmas)
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(got[0, :, :3], want_origins, rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(got[0, :, 3], want_sets)
    np.testing.assert_allclose(got[1, :, 0], want_distance, rtol=1e-6, atol=1e-12)
    # Row 2, the half-space of the VPL clusters' maps: none for VSGLs (every point kept).
    np.testing.assert_array_equal(got[2], 0.0)


@pytest.mark.parametrize("origin_sigmas", [0.0, 1.0, 1.5])
def test_maps_built_at_another_shadow_origin_offset_follow_the_reference(origin_sigmas):
    """The offset is compiled into the shaders (glsl/lib/ism.glsl ISM_ORIGIN_SIGMAS): set
    after a first build, the next build compiles again and centres the maps where the float64 twin
    does, origin_sigmas σ_v off the mean."""
    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.passes.vsgl_shading import upload_vsgl_table

    vsgls = _vsgl_table(37)
    stored = {name: np.asarray(value, np.float32) for name, value in vsgls.items()}
    table = upload_vsgl_table(vsgls)
    saved = ism.SHADOW_ORIGIN_SIGMAS
    at_default = read_texture(ism_pass.vsgl_map_origins(table.texture, 37, 2, 0, 8, 0.3).texture, 74, 3)
    try:
        ism_pass.set_shadow_origin_sigmas(origin_sigmas)
        got = read_texture(ism_pass.vsgl_map_origins(table.texture, 37, 2, 0, 8, 0.3).texture, 74, 3)
        want, _, _ = ism.vsgl_map_origins(stored, 2, 0, 8, 0.3)
    finally:
        ism_pass.set_shadow_origin_sigmas(saved)
    np.testing.assert_allclose(got[0, :, :3], want, rtol=1e-6, atol=1e-6)
    variance = np.stack([stored["diffuse_variance"], stored["specular_variance"]], 1).reshape(-1)
    axis = np.stack([stored["diffuse_axis"], stored["specular_axis"]], 1).reshape(-1, 3)
    np.testing.assert_allclose(got[0, :, :3] - at_default[0, :, :3],
                               (origin_sigmas - saved) * np.sqrt(np.maximum(variance, 0.0))[:, None] * axis,
                               rtol=1e-4, atol=1e-5)
    with pytest.raises(ValueError):
        ism_pass.set_shadow_origin_sigmas(-1.0)


def test_vsgl_map_origins_refuse_other_map_counts():
    with pytest.raises(ValueError):
        ism.vsgl_map_origins(_vsgl_table(2), 3, 0, 8, 1.0)
    with pytest.raises(ValueError):
        ism_pass.vsgl_map_origins(None, 2, 3, 0, 8, 1.0)


@pytest.mark.parametrize("maps_per_vsgl", [1, 2])
def test_maps_of_a_table_texture_equal_those_of_the_same_origins_from_numpy(maps_per_vsgl):
    """The splat's table made on the GPU gives the atlas the numpy origins give, reading nothing back."""
    from vsgl_addon.passes.gpu_util import RoundTrips
    from vsgl_addon.passes.vsgl_shading import upload_vsgl_table

    geometry = _geometry(_quad(-2, -2, 2, 2) + _quad(-1, -1, 1, 1, z=1.0))
    points = sp.scene_point_sets(geometry, 2048, 8, seed=2)
    vsgls = _vsgl_table(12, seed=7)
    for lobe in ("diffuse", "specular"):
        vsgls[f"{lobe}_mean"][:, 2] = np.abs(vsgls[f"{lobe}_mean"][:, 2]) * 0.1 + 0.3
        vsgls[f"{lobe}_variance"] = np.minimum(np.maximum(vsgls[f"{lobe}_variance"], 0.0), 0.05)
    stored = {name: np.asarray(value, np.float32) for name, value in vsgls.items()}
    origins, sets, distance = ism.vsgl_map_origins(stored, maps_per_vsgl, 3, 8, 1.0)
    table = upload_vsgl_table(vsgls)
    read_backs = RoundTrips.read_backs
    on_gpu = ism_pass.PASS.run(points, ism_pass.vsgl_map_origins(table.texture, 12, maps_per_vsgl, 3, 8, 1.0),
                               None, 16, point_area=0.01)
    assert RoundTrips.read_backs == read_backs
    from_numpy = ism_pass.PASS.run(points, origins, sets, 16, min_distance=distance, point_area=0.01)
    a, b = on_gpu.read(), from_numpy.read()
    assert on_gpu.count == from_numpy.count == 12 * maps_per_vsgl
    # Float32 origins one rounding apart: a point at a texel's edge may land beside it.
    finite = np.isfinite(a) & np.isfinite(b)
    assert np.array_equal(np.isfinite(a), np.isfinite(b))
    assert np.mean(np.abs(a[finite] - b[finite]) <= 1e-4 * np.maximum(b[finite], 1.0)) > 0.999


@pytest.mark.parametrize("plane,continued", [(1.0, True), (0.5, True), (1.0, False)])
def test_maps_that_keep_their_surfaces_match_the_reference(monkeypatch, plane, continued):
    """An atlas that keeps its surfaces (ISMAtlas.surfaces): sized splats at their tangent plane's
    depth (reference splat ``plane_depth`` = SPLAT_PLANE_DEPTH, radius up to SURFACE_SPLAT_MAX_RADIUS) and gap sides continued as planes
    or as their nearest depth (close_gaps ``continued`` = GAP_EXTRAPOLATE), a floor grazed from
    0.3 m and a wall: the GPU's maps against the float64 twin's, and unlike the maps that do not
    keep their surfaces (the variant reached the shaders)."""
    monkeypatch.setattr(ism, "SPLAT_PLANE_DEPTH", plane)
    monkeypatch.setattr(ism, "GAP_EXTRAPOLATE", continued)
    scene = _geometry(_quad(-4, -4, 4, 4) + [((1, -2, 0), (1, 2, 0), (1, 2, 3)), ((1, -2, 0), (1, 2, 3), (1, -2, 3))])
    points = sp.scene_point_sets(scene, 512, 2, seed=6)  # sparse: the near floor's splats are wide
    area = sp.triangle_areas(scene.positions).sum() / 512
    origins = np.array([[0.0, 0.0, 0.3], [-0.6, 0.4, 1.2]])

    def maps(surfaces):
        atlas = ism_pass.PASS.run(points, origins, [0, 1], 64, point_area=area, surfaces=surfaces)
        try:
            assert atlas.surfaces == surfaces
            return atlas.read()
        finally:
            ism_pass.PASS.free(atlas)

    got, plain = maps(True), maps(False)
    expected = np.stack([ism.pull_push(ism.close_gaps(ism.splat(points.positions[s], o, 64, normals=points.normals[s],
                                                                point_area=area, plane_depth=plane,
                                                                max_radius=ism.SURFACE_SPLAT_MAX_RADIUS),
                                                      continued))
                         for o, s in zip(origins, [0, 1])])
    assert np.isfinite(got).all()
    assert np.isclose(got, expected, rtol=1e-5).mean() > 0.99
    assert not np.isclose(got, plain, rtol=1e-5).all()
    offsets = points.positions[0] - origins[0]
    cos_theta = (points.normals[0] * offsets).sum(axis=1) / np.linalg.norm(offsets, axis=1)
    radius = ism.splat_radius(offsets, cos_theta, area, 64, ism.SURFACE_SPLAT_MAX_RADIUS)
    assert radius.max() > ism.SPLAT_MAX_RADIUS  # the near floor's splats reach past the others' cap


def test_a_splat_and_gap_closing_in_chunks_with_other_maps_built_between_them_give_the_atlas_of_one_dispatch(
        monkeypatch):
    """build_ism_atlas_stages splats SPLATS_PER_STAGE (point, map) pairs and closes the gaps of
    CLOSED_TEXELS_PER_STAGE atlas texels per stage, so the viewport can spread one set's maps over
    steps: here 3 maps per splat stage over 7 maps and bands of 16 atlas rows, with another atlas
    built between the stages (it binds the same shaders and image units to other textures). The
    atlas equals the one of single dispatches, bit for bit."""
    scene = _geometry(_quad(-4, -4, 4, 4) + [((1, -2, 0), (1, 2, 0), (1, 2, 3)), ((1, -2, 0), (1, 2, 3), (1, -2, 3))])
    points = sp.scene_point_sets(scene, 512, 3, seed=2)
    area = sp.triangle_areas(scene.positions).sum() / 512
    rng = np.random.default_rng(4)
    origins = rng.uniform([-3, -3, 0.2], [3, 3, 2.5], (7, 3))
    sets = np.arange(7) % 3

    def build(stages, between=None):
        count = 0
        while True:
            try:
                next(stages)
            except StopIteration as done:
                return done.value, count
            count += 1
            if between is not None:
                between()

    def other():
        ism_pass.PASS.free(ism_pass.PASS.run(points, origins[::-1] + 0.1, sets[::-1], 16, point_area=area))

    whole, whole_stages = build(ism_pass.build_ism_atlas_stages(points, origins, sets, 32, point_area=area,
                                                                surfaces=True))
    columns, rows = ism_pass.atlas_layout(7, 32)
    monkeypatch.setattr(ism_pass, "SPLATS_PER_STAGE", 3 * 512)
    monkeypatch.setattr(ism_pass, "CLOSED_TEXELS_PER_STAGE", 16 * columns * 32)
    chunked, chunked_stages = build(ism_pass.build_ism_atlas_stages(points, origins, sets, 32, point_area=area,
                                                                    surfaces=True), other)
    try:
        # Splats of maps 0-2, 3-5 and 6; the closing in bands of 16 of the atlas's rows.
        assert rows * 32 > 16 and chunked_stages == whole_stages + 2 + (rows * 32 // 16 - 1)
        expected, got = whole.read(), chunked.read()
        assert np.isfinite(expected).all() and (expected < np.inf).any()
        np.testing.assert_array_equal(got, expected)
    finally:
        ism_pass.PASS.free(whole)
        ism_pass.PASS.free(chunked)
