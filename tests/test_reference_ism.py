# SPDX-License-Identifier: GPL-3.0-or-later
"""The scene point sets (vsgl_addon/scene_points.py) and the float64 imperfect-shadow-map twin
(vsgl_addon/reference/ism.py) against brute force and quadrature."""

from __future__ import annotations

import numpy as np
import pytest

from vsgl_addon import scene_points as sp
from vsgl_addon.reference import ism
from vsgl_addon.scene_description import Geometry


def _geometry(triangles) -> Geometry:
    tris = np.asarray(triangles, np.float32).reshape(-1, 3, 3)
    count = len(tris)
    face = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normals = np.repeat((face / np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-30))[:, None], 3, 1)
    return Geometry(tris, normals.astype(np.float32), np.zeros((count, 3, 2), np.float32),
                    np.zeros(count, np.int32), np.arange(count, dtype=np.int32))


def _quad(x0, y0, x1, y1, z=0.0):
    a, b, c, d = (x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)
    return [(a, b, c), (a, c, d)]


# --- Scene point sets ------------------------------------------------------------------------


def test_point_sets_are_area_weighted_and_stratified_per_set():
    # Three rectangles of areas 1, 4 and 0.25, a zero-area triangle and a collinear one.
    tris = (_quad(0, 0, 1, 1) + _quad(2, 0, 4, 2) + _quad(5, 0, 5.5, 0.5)
            + [((0, 0, 1), (0, 0, 1), (0, 0, 1)), ((0, 0, 2), (1, 0, 2), (2, 0, 2))])
    geometry = _geometry(tris)
    points = sp.scene_point_sets(geometry, 500, 7, seed=3)
    assert points.positions.shape == (7, 500, 3) and points.normals.shape == (7, 500, 3)
    area = sp.triangle_areas(geometry.positions)
    share = area / area.sum()
    for s in range(7):
        counts = np.bincount(points.triangle[s], minlength=len(area))
        # Stratification: each triangle gets its share of every set to within 2 points.
        assert np.all(np.abs(counts - 500 * share) <= 2.0), counts
        assert counts[-2:].sum() == 0  # no point on a triangle without area
    # On their triangles: barycentric coordinates in [0, 1], normal = the face normal.
    tri = np.asarray(geometry.positions, np.float64)[points.triangle]
    p = points.positions.astype(np.float64)
    e1, e2, q = tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :], p - tri[..., 0, :]
    gram = np.stack([np.stack([(e1 * e1).sum(-1), (e1 * e2).sum(-1)], -1),
                     np.stack([(e1 * e2).sum(-1), (e2 * e2).sum(-1)], -1)], -2)
    uv = np.linalg.solve(gram, np.stack([(q * e1).sum(-1), (q * e2).sum(-1)], -1)[..., None])[..., 0]
    assert uv.min() >= -1e-5 and (uv.sum(-1)).max() <= 1 + 1e-5
    np.testing.assert_allclose(points.normals, np.broadcast_to([0, 0, 1], points.normals.shape), atol=1e-6)


def test_point_sets_are_uniform_on_a_triangle_and_fixed_by_the_seed():
    geometry = _geometry(_quad(0, 0, 1, 1))
    points = sp.scene_point_sets(geometry, 4000, 4, seed=0)
    xy = points.positions[..., :2].reshape(-1, 2).astype(np.float64)
    # Uniform on the unit square: every quarter holds a quarter of the points (Monte Carlo, 4σ).
    quarter = ((xy[:, 0] < 0.5) & (xy[:, 1] < 0.5)).mean()
    assert abs(quarter - 0.25) < 4 * np.sqrt(0.25 * 0.75 / len(xy))
    assert abs(xy.mean(axis=0) - 0.5).max() < 4 * np.sqrt(1 / 12 / len(xy))
    again = sp.scene_point_sets(geometry, 4000, 4, seed=0)
    np.testing.assert_array_equal(points.positions, again.positions)  # a static scene does not flicker
    other = sp.scene_point_sets(geometry, 4000, 4, seed=1)
    assert not np.array_equal(points.positions, other.positions)
    assert not np.array_equal(points.positions[0], points.positions[1])  # each set its own points
    assert sp.set_index(9, 4) == 1


@pytest.mark.parametrize("count,sets", [(1, 1), (1, 16384), (1 << 12, 1)])
def test_point_sets_at_the_ends_of_their_ranges_and_empty_scenes(count, sets):
    points = sp.scene_point_sets(_geometry(_quad(0, 0, 1, 1)), count, sets)
    assert points.positions.shape == (sets, count, 3) and np.isfinite(points.positions).all()
    empty = sp.scene_point_sets(Geometry.empty(), count, sets)
    assert np.all(empty.triangle == -1) and np.isfinite(empty.normals).all()
    with pytest.raises(ValueError):
        sp.scene_point_sets(_geometry(_quad(0, 0, 1, 1)), 0, sets)


# --- Octahedral projection --------------------------------------------------------------------


def test_octahedral_round_trip_and_full_sphere_cover():
    rng = np.random.default_rng(5)
    d = rng.normal(size=(20000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = np.concatenate([d, np.eye(3), -np.eye(3), [[1, 1, 0], [0, -1, -1e-12]]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    uv = ism.octahedral_encode(d)
    assert np.abs(uv).max() <= 1.0
    upper = d[:, 2] >= 0.0  # the upper hemisphere is the inner diamond, the lower one folds outside it
    assert np.all(np.abs(uv[upper]).sum(-1) <= 1.0 + 1e-12) and np.all(np.abs(uv[~upper]).sum(-1) >= 1.0 - 1e-12)
    np.testing.assert_allclose(ism.octahedral_decode(uv), d, atol=1e-12)


@pytest.mark.parametrize("size", [8, 64])
def test_octahedral_texel_solid_angles_cover_4pi_with_bounded_distortion(size):
    """Quadrature of dω = |∂ω/∂u × ∂ω/∂v| du dv over each texel (8×8 Gauss-Legendre nodes, the
    Jacobian by central differences): the texels add up to 4π, and the largest is less than 3√3
    times the smallest (the module's claim: the continuous map's density ratio)."""
    order, h = 8, 1e-6
    nodes, weights = np.polynomial.legendre.leggauss(order)
    offsets = (nodes + 1.0) / 2.0  # in [0, 1] of a texel
    grid = (np.arange(size)[:, None] + offsets[None, :]).reshape(-1) / size * 2.0 - 1.0
    w1 = np.tile(weights / 2.0 * (2.0 / size), size)
    u, v = np.meshgrid(grid, grid, indexing="xy")
    uv = np.stack([u, v], -1)
    du = (ism.octahedral_decode(uv + [h, 0]) - ism.octahedral_decode(uv - [h, 0])) / (2 * h)
    dv = (ism.octahedral_decode(uv + [0, h]) - ism.octahedral_decode(uv - [0, h])) / (2 * h)
    jacobian = np.linalg.norm(np.cross(du, dv), axis=-1) * w1[None, :] * w1[:, None]
    solid = jacobian.reshape(size, order, size, order).sum(axis=(1, 3))
    assert solid.sum() == pytest.approx(4 * np.pi, rel=1e-3)
    ratio = solid.max() / solid.min()
    print(f"octahedral {size}²: texel solid angle max/min {ratio:.2f}")
    assert 1.0 < ratio < 3.0 * np.sqrt(3.0)
    # Texel centres decode into their own texel.
    centres = ism.texel_directions(size)
    rows, columns = np.mgrid[0:size, 0:size]
    np.testing.assert_array_equal(ism.ism_texel(centres, size), np.stack([columns, rows], -1))


def test_octahedral_wrap_neighbours_are_adjacent_directions():
    """Across every edge of the square the wrapped neighbour is the texel next to it on the sphere:
    its centre is about one texel's angle away, never across the map."""
    size = 32
    centres = ism.texel_directions(size)
    texel_angle = np.sqrt(4 * np.pi) / size
    edge = np.arange(size)
    for column, row, dc, dr in [(np.zeros(size, int), edge, -1, 0), (np.full(size, size - 1), edge, 1, 0),
                                (edge, np.zeros(size, int), 0, -1), (edge, np.full(size, size - 1), 0, 1)]:
        c, r = ism.octahedral_wrap(column + dc, row + dr, size)
        assert ((0 <= c) & (c < size) & (0 <= r) & (r < size)).all()
        angle = np.arccos(np.clip((centres[row, column] * centres[r, c]).sum(-1), -1, 1))
        assert angle.max() < 2.0 * texel_angle, angle.max() / texel_angle


# --- Splat, pull-push, lookup -----------------------------------------------------------------


def test_splat_keeps_the_nearest_point_per_texel_as_brute_force():
    rng = np.random.default_rng(2)
    points = rng.uniform(-3, 3, size=(3000, 3))
    origin = np.array([0.2, -0.1, 0.3])
    size = 8
    depth = ism.splat(points, origin, size)
    texel = ism.ism_texel(points - origin, size)
    distance = np.linalg.norm(points - origin, axis=1)
    for row in range(size):
        for column in range(size):
            here = (texel[:, 0] == column) & (texel[:, 1] == row)
            assert depth[row, column] == (distance[here].min() if here.any() else ism.EMPTY)
    assert np.all(ism.splat(np.zeros((0, 3)), origin, 4) == ism.EMPTY)
    assert np.all(ism.splat(origin[None], origin, 4) == ism.EMPTY)  # the origin's own point


def test_a_half_space_splats_exactly_the_points_it_keeps():
    """keeps_point against its definition point by point, and a splat with a plane equal to the splat
    of the points it keeps; n = 0, c = 0 keeps every point, c = +inf none."""
    rng = np.random.default_rng(5)
    points = rng.uniform(-3, 3, size=(3000, 3))
    origin = np.array([0.2, -0.1, 0.3])
    normal = np.array([0.3, -0.4, 0.866])
    normal /= np.linalg.norm(normal)
    plane = np.array([*normal, -0.25])
    kept = ism.keeps_point(points - origin, plane)
    assert np.array_equal(kept, [(p - origin) @ normal >= -0.25 for p in points])
    assert 0 < kept.sum() < len(points)
    for size in (1, 8):
        np.testing.assert_array_equal(ism.splat(points, origin, size, plane=plane),
                                      ism.splat(points[kept], origin, size))
    assert ism.keeps_point(points - origin, np.zeros(4)).all()
    assert not ism.keeps_point(points - origin, [0.0, 0.0, 0.0, np.inf]).any()


def test_pull_push_fills_holes_and_keeps_what_was_splatted():
    rng = np.random.default_rng(4)
    truth = 2.0 + rng.random((16, 16))
    holes = rng.random((16, 16)) < 0.6
    depth = np.where(holes, ism.EMPTY, truth)
    filled = ism.pull_push(depth)
    assert np.isfinite(filled).all()
    np.testing.assert_array_equal(filled[~holes], truth[~holes])
    assert filled.min() >= truth[~holes].min() and filled.max() <= truth[~holes].max()  # a mean of neighbours
    one = np.full((8, 8), ism.EMPTY)
    one[3, 5] = 1.5
    assert np.all(ism.pull_push(one) == 1.5)
    assert np.all(ism.pull_push(np.full((1, 1), 2.0)) == 2.0)
    assert np.all(ism.pull_push(np.full((4, 4), ism.EMPTY)) == ism.EMPTY)
    with pytest.raises(ValueError):
        ism.pull_push(np.zeros((6, 6)))


def test_a_wall_shadows_what_lies_behind_it_and_a_floor_does_not_shadow_itself():
    """A VSGL 1.5 m above a floor, a wall at x = 1 between it and receivers beyond; receivers on the
    lit floor before the wall see it (no acne at their slope-scaled bias)."""
    scene = _geometry(_quad(-4, -4, 4, 4) + [((1, -2, 0), (1, 2, 0), (1, 2, 3)), ((1, -2, 0), (1, 2, 3), (1, -2, 3))])
    points = sp.scene_point_sets(scene, 60000, 1, seed=0)
    origin = np.array([0.0, 0.0, 1.5])
    depth = ism.pull_push(ism.splat(points.positions[0], origin, 32))
    up = np.array([0.0, 0.0, 1.0])
    behind = np.stack([np.full(50, 2.5), np.linspace(-1, 1, 50), np.full(50, 0.5)], -1)
    before = np.stack([np.full(50, -2.0), np.linspace(-1, 1, 50), np.zeros(50)], -1)
    assert ism.ism_visibility(depth, origin, behind).max() == 0.0
    assert ism.ism_visibility(depth, origin, before, normals=up).min() == 1.0
    assert ism.ism_pcf(depth, origin, before, radius=1, normals=up).min() == 1.0
    assert ism.ism_pcf(depth, origin, behind, radius=1).max() == 0.0
    # Half in the wall's shadow, half past its end: the filtered test is partial there.
    edge = np.array([[2.5, 2.0 * 2.5, 0.5]])
    value = ism.ism_pcf(depth, origin, edge, radius=3)
    assert 0.0 < value[0] < 1.0


def _box(x0, x1, y0, y1, z1):
    """The faces x = x0, x = x1 and the top z = z1 of a block on the floor."""
    return [((x, y0, 0.0), (x, y1, 0.0), (x, y1, z1)) for x in (x0, x1)] + \
        [((x, y0, 0.0), (x, y1, z1), (x, y0, z1)) for x in (x0, x1)] + _quad(x0, y0, x1, y1, z1)


@pytest.fixture
def lookup_bias():
    """Sets reference.ism's lookup bias (normal offset, depth bias left, back offset) for a test,
    restored after."""
    saved = ism.NORMAL_OFFSET, ism.NORMAL_OFFSET_DEPTH, ism.BACK_OFFSET, ism.SPREAD_BIAS

    def set_bias(offset, depth, back):
        ism.NORMAL_OFFSET, ism.NORMAL_OFFSET_DEPTH, ism.BACK_OFFSET = offset, depth, back

    yield set_bias
    ism.NORMAL_OFFSET, ism.NORMAL_OFFSET_DEPTH, ism.BACK_OFFSET, ism.SPREAD_BIAS = saved


def test_a_thin_wall_stops_a_low_origin_s_light_with_the_normal_offset_lookups(lookup_bias):
    """An origin 0.3 m over a floor, a wall 0.2 m thick and 1 m tall 2 m away (the sun courtyard's
    case, scaled): the floor behind the wall is grazed from the origin, so its slope-scaled depth
    bias (up to nine footprints) reaches through the wall and the floor there is lit; moved along
    its normal instead it is shadowed, and the floor before the wall stays lit. The wall's far
    face, facing away from the origin, is lit through the wall's thickness by the depth bias and
    shadowed when receivers facing away move away (BACK_OFFSET)."""
    scene = _geometry(_quad(-6, -6, 6, 6) + _box(2.0, 2.2, -3, 3, 1.0))
    points = sp.scene_point_sets(scene, 60000, 1, seed=0)
    origin = np.array([0.0, 0.0, 0.3])
    depth = ism.pull_push(ism.close_gaps(ism.splat(points.positions[0], origin, 64)))
    behind = np.stack([np.linspace(2.4, 5.0, 50), np.linspace(-1, 1, 50), np.zeros(50)], -1)
    before = np.stack([np.linspace(-2.5, 1.5, 80), np.linspace(-1, 1, 80), np.zeros(80)], -1)
    before = before[np.linalg.norm(before - origin, axis=-1) > 0.5]
    far_face = np.stack([np.full(50, 2.2), np.linspace(-1, 1, 50), np.linspace(0.05, 0.6, 50)], -1)
    up, away = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])

    def lit(receivers, normal):
        return ism.ism_pcf_bilinear(depth, origin, receivers, normals=np.tile(normal, (len(receivers), 1))).mean()

    lookup_bias(0.0, 0.5, 0.0)
    assert lit(behind, up) > 0.9 and lit(far_face, away) > 0.9 and lit(before, up) == 1.0
    lookup_bias(1.0, 1.0, 0.0)
    assert lit(behind, up) < 0.05 and lit(before, up) > 0.95
    lookup_bias(0.0, 0.5, 1.0)
    assert lit(far_face, away) < 0.05 and lit(before, up) == 1.0


def test_close_gaps_closes_holes_in_a_near_occluder_and_keeps_its_outline():
    """A near square (depth 1) over a far background (depth 5) with holes 1 and 2·reach − 1 texels
    wide and an empty texel: the holes take the square's depth, every background texel outside
    it keeps its own, and a smooth surface (depth 2 + z of the texel's direction, continuous
    across the octahedral folds) is left as it was."""
    size, reach = 32, ism.GAP_REACH
    depth = np.full((size, size), 5.0)
    depth[8:24, 8:24] = 1.0
    depth[12, 12] = 5.0  # a one-texel hole
    depth[18, 10:10 + 2 * reach - 1] = 5.0  # the widest hole that closes
    depth[20, 20] = ism.EMPTY
    closed = ism.close_gaps(depth)
    np.testing.assert_array_equal(closed[8:24, 8:24], 1.0)
    outside = np.ones((size, size), bool)
    outside[8:24, 8:24] = False
    np.testing.assert_array_equal(closed[outside], 5.0)
    smooth = 2.0 + ism.texel_directions(size)[..., 2]
    np.testing.assert_array_equal(ism.close_gaps(smooth), smooth)
    assert np.all(ism.close_gaps(np.full((1, 1), ism.EMPTY)) == ism.EMPTY)


@pytest.mark.parametrize("maps_per_vsgl", [1, 2])
def test_vsgl_map_origins_follow_each_lobe_map_by_map(maps_per_vsgl):
    """Map by map (a loop): lobe m mod maps-per-VSGL of VSGL m div maps-per-VSGL, its mean moved
    half a σ_v along its axis, set (first + m) mod sets, minimum distance sigmas·σ_v (0 for variance
    0 or below)."""
    rng = np.random.default_rng(4)
    count = 9
    vsgls = {}
    for lobe in ("diffuse", "specular"):
        vsgls[f"{lobe}_mean"] = rng.normal(size=(count, 3))
        vsgls[f"{lobe}_variance"] = rng.uniform(-0.1, 1e3, count)
        axis = rng.normal(size=(count, 3))
        vsgls[f"{lobe}_axis"] = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    origins, sets, distance = ism.vsgl_map_origins(vsgls, maps_per_vsgl, 60, 64, 1.5)
    assert len(origins) == len(sets) == len(distance) == count * maps_per_vsgl
    for m in range(count * maps_per_vsgl):
        lobe = "specular" if maps_per_vsgl == 2 and m % 2 else "diffuse"
        i = m // maps_per_vsgl
        sigma = np.sqrt(max(vsgls[f"{lobe}_variance"][i], 0.0))
        np.testing.assert_allclose(origins[m], vsgls[f"{lobe}_mean"][i] + 0.5 * sigma * vsgls[f"{lobe}_axis"][i],
                                   rtol=1e-14, atol=1e-14)
        assert sets[m] == (60 + m) % 64
        assert distance[m] == pytest.approx(1.5 * sigma, rel=1e-14, abs=0.0)


def _plane_depths(directions, point, normal):
    """Ray-cast depth along unit ``directions`` from the origin to the plane through ``point`` with
    ``normal`` (inf where the ray runs away from it)."""
    with np.errstate(divide="ignore"):
        t = (np.asarray(point) @ np.asarray(normal)) / (directions @ np.asarray(normal))
    return np.where(t > 0.0, t, np.inf)


def test_oriented_splats_keep_a_floor_s_depth_as_ray_casting():
    """A floor seen from 0.4 m above it, its points splatted with their normals and area: most texels
    the splats cover hold where the texel centre's ray meets the floor (every point's tangent plane),
    the rest, at grazing angles, at most a point spacing beyond the nearest point's distance; the
    point's own distance over its splat, nearer than the floor by up to the splat's half-width in
    depth, almost never does. tangent_plane_depth against a brute-force ray-plane intersection (the ray's
    point whose offset from the point has no normal component), within its reach and at its ends."""
    scene = _geometry(_quad(-6, -6, 6, 6))
    points = sp.scene_point_sets(scene, 4000, 1, seed=3)
    area = sp.triangle_areas(scene.positions).sum() / 4000
    origin = np.array([0.0, 0.0, 0.4])
    size = 32
    exact = _plane_depths(ism.texel_directions(size), -origin, np.array([0.0, 0.0, 1.0]))
    errors = {}
    for plane in (1.0, 0.0):
        depth = ism.splat(points.positions[0], origin, size, normals=points.normals[0], point_area=area,
                          plane_depth=plane)
        covered = np.isfinite(depth) & np.isfinite(exact)
        assert covered.sum() > 300
        errors[plane] = np.abs(depth[covered] / exact[covered] - 1.0)
    assert np.median(errors[1.0]) < 1e-9 and np.median(errors[0.0]) > 0.05
    assert errors[1.0].mean() < 0.6 * errors[0.0].mean()

    rng = np.random.default_rng(4)
    offsets = rng.normal(size=(500, 3)) * 2.0
    normals = rng.normal(size=(500, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    directions = offsets / np.linalg.norm(offsets, axis=1, keepdims=True) + 0.3 * rng.normal(size=(500, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    spacing = 1.5
    got = ism.tangent_plane_depth(offsets, normals, directions, spacing ** 2, 1.0)
    distance = np.linalg.norm(offsets, axis=1)
    for o, n, u, t, d in zip(offsets, normals, directions, got, distance):
        # Brute force: bisect the ray parameter for the sign change of n · (t u − o) on [0, 100].
        f = lambda x: n @ (x * u - o)  # noqa: E731
        lo, hi = 0.0, 100.0
        if f(lo) * f(hi) > 0.0:
            hit = np.inf
        else:
            for _ in range(200):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if f(lo) * f(mid) > 0.0 else (lo, mid)
            hit = 0.5 * (lo + hi)
        expected = np.clip(hit, d - spacing, d + spacing) if np.isfinite(hit) and hit > 0.0 else d + spacing
        assert t == pytest.approx(expected, rel=1e-9, abs=1e-9)


def test_a_concave_corner_is_no_gap_and_a_hole_in_a_tilted_wall_still_closes():
    """The exact depth map of a room seen from inside (six walls, each depth the ray-cast plane's):
    its corners are farther than the walls on both sides, and gap closing with the
    sides' nearest depths pulls a fifth of the map in; with each side continued as a plane
    (|q| / depth linear on an octahedron face) a fifth of that. A tilted wall with a hole in front of a far
    background: the hole closes either way."""
    size = 32
    directions = ism.texel_directions(size)
    walls = [(np.array(n, np.float64), c) for n, c in (((1, 0, 0), 1.0), ((-1, 0, 0), 2.1), ((0, 1, 0), 0.7),
                                                          ((0, -1, 0), 1.6), ((0, 0, 1), 0.9), ((0, 0, -1), 1.3))]
    corner = np.min([_plane_depths(directions, n * c, n) for n, c in walls], axis=0)  # a box's inside
    assert np.isfinite(corner).all()
    pulled_in = {}
    for continued in (False, True):
        closed = ism.close_gaps(corner, continued)
        assert np.all(closed <= corner)
        pulled_in[continued] = int((closed < corner * (1.0 - 1e-9)).sum())
    # What still closes: sides whose two texels straddle another wall's edge or a face boundary of
    # the octahedron (u = 0, v = 0, |u| + |v| = 1), where |q| / depth is not linear.
    assert pulled_in[False] > 0.15 * size * size and pulled_in[True] < 0.2 * pulled_in[False], pulled_in
    normal = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
    wall = _plane_depths(directions, 0.8 * normal, normal)
    depth = np.where(np.isfinite(wall) & (wall < 3.0), wall, 20.0)
    reach = ism.GAP_REACH + 1
    inside = [(r, c) for r in range(reach, size - reach) for c in range(reach, size - reach)
              if (depth[r - reach:r + reach + 1, c - reach:c + reach + 1] < 3.0).all()]
    assert len(inside) > 20
    holes = inside[::max(len(inside) // 3, 1)][:3]
    holed = depth.copy()
    for row, column in holes:
        holed[row, column] = 20.0
    for continued in (False, True):
        closed = ism.close_gaps(holed, continued)
        for row, column in holes:
            assert closed[row, column] < 3.0
