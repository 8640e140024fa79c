# SPDX-License-Identifier: GPL-3.0-or-later
"""vsgl_addon.reference.vpl_culling (formulas.md section 7, 004 Eqs. 2-17): the ranges are bounded
by the spheroid / sphere, the estimator is unbiased against brute force, tiled culling equals
shading every accepted VPL, and everything stays finite at the extremes."""

from __future__ import annotations

import numpy as np
import pytest

from vsgl_addon.reference import ggx
from vsgl_addon.reference import vpl_culling as vc

RNG_SEED = 20171


def random_unit(rng, shape):
    v = rng.normal(size=shape + (3,))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def hemisphere(rng, normal, count):
    v = random_unit(rng, (count,))
    return np.where((v @ normal < 0.0)[:, None], -v, v)


def near_axis(rng, axis, spread, count):
    """Directions within ~spread radians of ``axis`` (the peak of a sharp lobe)."""
    v = axis + spread * rng.normal(size=(count, 3))
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def random_vpl(rng, roughness, cos_incidence):
    normal = random_unit(rng, ())
    tangent = np.cross(normal, random_unit(rng, ()))
    tangent /= np.linalg.norm(tangent)
    sin_i = np.sqrt(max(1.0 - cos_incidence**2, 0.0))
    incoming = cos_incidence * normal + sin_i * tangent
    return rng.normal(size=3), normal, incoming / np.linalg.norm(incoming)


@pytest.mark.parametrize("roughness", [1e-3, 1e-2, 0.08, 0.3, 1.0])
@pytest.mark.parametrize("cos_incidence", [1.0, 0.7, 0.1, 1e-4])
def test_spheroid_bounds_range_surface(roughness, cos_incidence):
    """Points q + l_max(w_o) w_o (Eq. 5, F <= 1) never fall outside the spheroid (Eqs. 13-15)."""
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(4):
        q, n, wi = random_vpl(rng, roughness, cos_incidence)
        flux, delta, xi = 10.0 ** rng.uniform(-2, 2), 10.0 ** rng.uniform(-6, -1), rng.uniform(1e-6, 1.0)
        wu = vc.mirror_direction(wi, n)
        wo = np.concatenate([hemisphere(rng, n, 4000),
                             near_axis(rng, wu, max(roughness, 1e-3), 4000),
                             near_axis(rng, wu, 3.0 * roughness, 4000)])
        wo = wo[wo @ n > 0.0]
        lmax = vc.light_range(vc.glossy_intensity(wi, wo, n, roughness, flux), delta, xi)
        centre, axes, rotation = vc.ggx_spheroid(q, n, wi, roughness, flux, delta, xi)
        assert np.all(np.isfinite(centre)) and np.all(np.isfinite(axes)) and np.all(np.isfinite(rotation))
        np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
        inside = vc.spheroid_contains(q + lmax[:, None] * wo, centre, axes, rotation, slack=1e-7)  # rounding: r_u - offset cancels at alpha = 1e-3
        assert inside.all(), f"{(~inside).sum()} range points outside the spheroid"
        # The bound is tight along w_u: s(0) = r / alpha is the spheroid's far vertex (Eq. 12-15).
        r = vc.ggx_range_radius(wi @ n, roughness, flux, delta, xi)
        tip = q + vc.ggx_bounding_surface(0.0, r, roughness) * wu
        local = rotation @ (tip - centre) / axes
        assert np.linalg.norm(local) == pytest.approx(1.0, rel=1e-9)


def test_bounding_surface_dominates_ggx():
    """Phi f1 <w_o, n> <= Phi G1(w_i) D(cos(theta/2)) / (4 |w_i.n|) (Eqs. 9-11)."""
    rng = np.random.default_rng(RNG_SEED + 1)
    for roughness in np.logspace(-3, 0, 7):
        for cos_i in (1.0, 0.5, 0.01):
            _, n, wi = random_vpl(rng, roughness, cos_i)
            wu = vc.mirror_direction(wi, n)
            wo = np.concatenate([hemisphere(rng, n, 2000), near_axis(rng, wu, roughness, 2000)])
            wo = wo[wo @ n > 0.0]
            intensity = vc.glossy_intensity(wi, wo, n, roughness, 1.0)
            theta = np.arccos(np.clip(wo @ wu, -1.0, 1.0))
            bound = vc.ggx_bounding_surface(theta, vc.ggx_range_radius(wi @ n, roughness, 1.0, 1.0, 1.0),
                                            roughness) ** 2
            assert np.all(intensity <= bound * (1.0 + 1e-9))


def test_diffuse_sphere_bounds_range():
    rng = np.random.default_rng(RNG_SEED + 2)
    n = random_unit(rng, ())
    q = rng.normal(size=3)
    wo = hemisphere(rng, n, 20000)
    for flux_k, delta, xi in [(1.0, 1e-3, 0.5), (50.0, 1e-6, 1e-4), (1e-3, 0.1, 0.999)]:
        lmax = vc.light_range(flux_k / np.pi * (wo @ n), delta, xi)
        centre, radius = vc.diffuse_sphere(q, n, flux_k, delta, xi)
        d = np.linalg.norm(q + lmax[:, None] * wo - centre, axis=-1)
        assert np.all(d <= radius * (1.0 + 1e-9))
        # Tight: some range point is within 1 % of the sphere.
        assert d.max() > 0.99 * radius


def test_xi_per_vpl_uniform_and_frame_dependent():
    index = np.arange(200000)
    xi = vc.vpl_xi(index, 7, 3)
    assert np.all((xi > 0.0) & (xi < 1.0))
    assert abs(xi.mean() - 0.5) < 4.0 * np.sqrt(1.0 / 12.0 / xi.size)
    hist = np.histogram(xi, bins=20, range=(0, 1))[0]
    assert np.all(np.abs(hist - xi.size / 20) < 5.0 * np.sqrt(xi.size / 20))
    other = vc.vpl_xi(index, 7, 4)
    assert abs(np.corrcoef(xi, other)[0, 1]) < 0.01
    assert np.mean(np.abs(vc.vpl_xi(index, 8, 3) - xi) > 0.0) > 0.99
    np.testing.assert_array_equal(vc.vpl_xi(index, 7, 3), xi)


def small_scene(rng, count=40, roughness=0.08, flux_scale=1.0):
    """Glossy VPLs on a panel near z = 0, receivers on a wall at x = 2 facing -x."""
    vpls = {
        "position": np.column_stack([rng.uniform(-0.2, 0.2, count), rng.uniform(-0.2, 0.2, count),
                                     np.zeros(count)]),
        "normal": np.tile([0.0, 0.0, 1.0], (count, 1)),
        "incoming": np.tile(np.array([-0.8, 0.0, 0.6]), (count, 1)),
        "flux": flux_scale * rng.uniform(0.5, 2.0, (count, 3)),
        "rs": np.tile([0.9, 0.8, 0.7], (count, 1)),
        "roughness": np.full(count, roughness),
    }
    return vpls


def receivers_on_wall(ys, zs):
    y, z = np.meshgrid(ys, zs, indexing="ij")
    points = np.column_stack([np.full(y.size, 2.0), y.ravel(), z.ravel()])
    normals = np.tile([-1.0, 0.0, 0.0], (y.size, 1))
    return points, normals, np.full((y.size, 3), 0.8)


def test_stochastic_estimator_unbiased():
    """The mean over n frames of Eq. 3 converges to brute force as 1/sqrt(n)."""
    rng = np.random.default_rng(RNG_SEED + 3)
    vpls = small_scene(rng, count=30, roughness=0.2, flux_scale=1e-3)
    points, normals, albedo = receivers_on_wall(np.linspace(-0.6, 0.6, 4), np.linspace(0.8, 2.0, 4))
    brute = vc.shade_glossy_vpls(points, normals, albedo, vpls, 0.0, None)
    assert np.all(brute > 0.0)
    delta = 2e-4
    radiance, intensity, l2 = vc.glossy_vpl_radiance(
        points[:, None], normals[:, None], albedo[:, None], vpls["position"][None], vpls["normal"][None],
        vpls["incoming"][None], vpls["roughness"][None], vpls["flux"][None], vpls["rs"][None])
    p = vc.acceptance_probability(intensity, l2, delta)
    assert 0.05 < np.mean(p < 1.0) < 0.95, "the test must exercise rejection"
    frames = 4000
    xi = vc.vpl_xi(np.arange(30)[None, :], 11, np.arange(frames)[:, None])  # (frames, K)
    weight = np.where(p[None] > xi[:, None, :], 1.0 / p[None], 0.0)          # (frames, P, K)
    samples = np.einsum("fpk,pkc->fpc", weight, radiance)
    err = {}
    for n in (250, 4000):
        mean = samples[:n].mean(axis=0)
        sigma = samples[:n].std(axis=0) / np.sqrt(n)
        assert np.all(np.abs(mean - brute) <= 4.5 * sigma + 1e-12 * brute)
        err[n] = np.sqrt(np.mean(((samples[:n].mean(axis=0) - brute) / brute) ** 2))
    # The standard error of the mean scales as 1/sqrt(n): 16x the frames, ~4x less spread.
    spread = [samples[:250].std(axis=0).mean() / np.sqrt(250), samples.std(axis=0).mean() / np.sqrt(4000)]
    assert spread[0] / spread[1] == pytest.approx(4.0, rel=0.15)


def test_all_accepted_equals_brute_force():
    rng = np.random.default_rng(RNG_SEED + 4)
    vpls = small_scene(rng)
    points, normals, albedo = receivers_on_wall(np.linspace(-1, 1, 5), np.linspace(0.5, 2.5, 5))
    xi = vc.vpl_xi(np.arange(40), 1, 0)
    np.testing.assert_allclose(vc.shade_glossy_vpls(points, normals, albedo, vpls, 1e-30, xi),
                               vc.shade_glossy_vpls(points, normals, albedo, vpls, 0.0, None), rtol=1e-12)


def look_at(eye, target):
    forward = target - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, -forward, eye
    return m


def perspective(fov, aspect, near, far):
    f = 1.0 / np.tan(0.5 * fov)
    return np.array([[f / aspect, 0, 0, 0], [0, f, 0, 0],
                     [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)], [0, 0, -1, 0]])


@pytest.mark.parametrize("delta", [1e-3, 1e-2])
def test_tiled_culling_exact_and_spheroids_beat_spheres(delta):
    """Tile lists from the exact ellipsoid-frustum test (Eqs. 16-17's stretch) shade exactly what shading every
    accepted VPL without culling gives; spheroids leave fewer false positives than spheres."""
    rng = np.random.default_rng(RNG_SEED + 5)
    vpls = small_scene(rng, count=60, roughness=0.08, flux_scale=1e-3)
    size, tile = 64, 16
    eye, target = np.array([-1.0, 0.0, 1.5]), np.array([2.0, 0.0, 1.5])
    v2w = look_at(eye, target)
    proj = perspective(np.radians(60.0), 1.0, 0.1, 20.0)
    inv_proj = np.linalg.inv(proj)
    # Receivers: the wall x = 2 seen through each pixel.
    ndc = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    nx, ny = np.meshgrid(ndc, ndc, indexing="xy")
    view = np.einsum("ij,...j->...i", inv_proj, np.stack([nx, ny, np.ones_like(nx), np.ones_like(nx)], -1))
    dirs = view[..., :3] / view[..., 3:]
    dirs_world = dirs @ v2w[:3, :3].T
    t = (2.0 - eye[0]) / dirs_world[..., 0]
    points = eye + t[..., None] * dirs_world
    depth = -(dirs[..., 2] * t)
    normals = np.broadcast_to([-1.0, 0.0, 0.0], points.shape)
    albedo = np.full(points.shape, 0.8)
    xi = vc.vpl_xi(np.arange(60), 3, 0)
    centre, axes, rotation = vc.glossy_bounding_volumes(vpls, delta, xi)
    # The VPL-centred sphere (radius = the spheroid's long semi-axis + centre offset, so it bounds
    # the range surface too) and the spheroid-enclosing sphere, as in 004 Fig. 9.
    long_axis = axes[:, 0]
    offset = np.linalg.norm(centre - vpls["position"], axis=-1)
    vpl_sphere = (vpls["position"], long_axis + offset)
    enclosing = (centre, long_axis)
    tiled = np.zeros(points.shape)
    false_pos = {"spheroid": 0, "spheroid_plane": 0, "vpl_sphere": 0, "enclosing": 0}
    for ty in range(size // tile):
        for tx in range(size // tile):
            sl = (slice(ty * tile, (ty + 1) * tile), slice(tx * tile, (tx + 1) * tile))
            # The pass's frustum: through the tile's outermost pixel centres (every pixel covered).
            lo, hi = vc.tile_receiver_ndc([tx * tile, ty * tile], [(tx + 1) * tile - 1, (ty + 1) * tile - 1],
                                          [size, size])
            planes = vc.tile_frustum_planes(inv_proj, v2w, lo, hi, depth[sl].min(), depth[sl].max())
            corners = vc.tile_frustum_corners(inv_proj, v2w, lo, hi, depth[sl].min(), depth[sl].max())
            # The pass's exact test; the plane test (Eq. 16) lists a superset.
            listed = vc.ellipsoid_frustum_overlap_exact(planes[None], corners[None], centre, axes, rotation)
            p_tile = points[sl].reshape(-1, 3)
            shaded = vc.shade_glossy_vpls(p_tile, normals[sl].reshape(-1, 3), albedo[sl].reshape(-1, 3),
                                          vpls, delta, xi, accepted=listed[None, :].astype(float))
            tiled[sl] = shaded.reshape(tile, tile, 3)
            _, intensity, l2 = vc.glossy_vpl_radiance(
                p_tile[:, None], normals[sl].reshape(-1, 3)[:, None], albedo[sl].reshape(-1, 3)[:, None],
                vpls["position"][None], vpls["normal"][None], vpls["incoming"][None],
                vpls["roughness"][None], vpls["flux"][None], vpls["rs"][None])
            accepted = vc.acceptance_probability(intensity, l2, delta) > xi[None]
            eye_mat = np.broadcast_to(np.eye(3), (60, 3, 3))
            for name, lst in (("spheroid", listed),
                              ("spheroid_plane", vc.ellipsoid_frustum_overlap(planes[None], centre, axes, rotation)),
                              ("vpl_sphere", vc.ellipsoid_frustum_overlap(
                                  planes[None], vpl_sphere[0], np.repeat(vpl_sphere[1][:, None], 3, 1), eye_mat)),
                              ("enclosing", vc.ellipsoid_frustum_overlap(
                                  planes[None], enclosing[0], np.repeat(enclosing[1][:, None], 3, 1), eye_mat))):
                assert np.all(lst[None] | ~accepted), f"{name} culled an accepted VPL"
                false_pos[name] += int(np.sum(lst[None] & ~accepted))
    full = vc.shade_glossy_vpls(points.reshape(-1, 3), normals.reshape(-1, 3), albedo.reshape(-1, 3),
                                vpls, delta, xi).reshape(points.shape)
    np.testing.assert_allclose(tiled, full, rtol=1e-12, atol=0.0)
    assert full.max() > 0.0
    assert false_pos["spheroid"] <= false_pos["enclosing"] <= false_pos["vpl_sphere"]
    assert false_pos["spheroid"] < false_pos["vpl_sphere"]
    assert false_pos["spheroid"] <= false_pos["spheroid_plane"]


def test_extremes_finite():
    n = np.array([0.0, 0.0, 1.0])
    for alpha in (1e-3, 1.0):
        for cos_i in (1.0, 1e-8, 0.0):
            wi = np.array([np.sqrt(1 - cos_i**2), 0.0, cos_i])
            for delta, xi in ((1e-6, 0.0), (1e-6, 1e-12), (0.1, 1.0)):
                centre, axes, rotation = vc.ggx_spheroid(np.zeros(3), n, wi, alpha, 1.0, delta, xi)
                assert np.all(np.isfinite(np.float32(centre))) and np.all(np.isfinite(np.float32(axes)))
                assert np.all(np.isfinite(np.float32(axes ** 2)))
                assert np.all(np.isfinite(rotation))
                c, r = vc.diffuse_sphere(np.zeros(3), n, 1.0, delta, xi)
                assert np.isfinite(np.float32(r)) and np.all(np.isfinite(c))
    assert vc.acceptance_probability(0.0, 0.0, 1e-3) == 0.0
    assert vc.acceptance_probability(1.0, 0.0, 1e-3) == 1.0
    assert vc.stochastic_weight(0.0, 1.0, 1e-3, 0.5) == 0.0
    # Receiver on the VPL, and no VPLs at all.
    rng = np.random.default_rng(0)
    vpls = small_scene(rng, count=1)
    out = vc.shade_glossy_vpls(vpls["position"], vpls["normal"], np.ones((1, 3)), vpls, 1e-3, np.array([0.5]))
    assert np.all(np.isfinite(out))
    empty = {k: v[:0] for k, v in vpls.items()}
    out = vc.shade_glossy_vpls(np.zeros((3, 3)), np.tile(n, (3, 1)), np.ones((3, 3)), empty, 1e-3, np.zeros(0))
    np.testing.assert_array_equal(out, 0.0)


def test_vpls_from_rsm_select_lit_sharp_texels():
    size = 4
    roughness = np.array([0.01, 0.5, 0.08, 0.2] * 4).reshape(size, size)
    flux = np.ones((size, size, 3))
    flux[0, 0] = 0.0
    rs = np.full((size, size, 3), 0.9)
    pos = np.arange(size * size * 3, dtype=float).reshape(size, size, 3)
    normal = np.broadcast_to([0.0, 0.0, 1.0], (size, size, 3))
    vpls = vc.glossy_vpls_from_rsm(pos, normal, normal, flux, rs, roughness, 0.1)
    assert list(vpls["texel"]) == [2, 4, 6, 8, 10, 12, 14]
    np.testing.assert_array_equal(vpls["position"], pos.reshape(-1, 3)[vpls["texel"]])
    one = vc.glossy_vpls_from_rsm(pos[:1, :1], normal[:1, :1], normal[:1, :1], np.ones((1, 1, 3)), rs[:1, :1],
                                  np.array([[0.05]]), 0.1)
    assert one["position"].shape == (1, 3)
    assert ggx.microfacet_brdf(one["incoming"], one["normal"], one["normal"], 0.05, 1.0).shape == (1,)


def test_texel_records_are_the_rsm_vpls():
    """extract_glossy_vpls (the GPU extraction's twin, from the RSM's slots and a light vector) gives
    glossy_vpls_from_rsm's VPLs with reference.rsm's w_i, in texel order: alpha = principled_alpha of
    the slot's roughness, kept below alpha_c and where Phi Rs > 0, floored at VPL_ALPHA_MIN; a sun's
    w_i is its direction; no sharp texel gives none; a light on the texel stays finite."""
    from types import SimpleNamespace

    from vsgl_addon.reference.principled import principled_alpha
    from vsgl_addon.reference.rsm import incoming_directions

    rng = np.random.default_rng(RNG_SEED)
    size = 8
    position = np.concatenate([rng.normal(size=(size, size, 3)), np.zeros((size, size, 1))], -1)
    roughness = rng.uniform(0.0, 1.0, (size, size))
    roughness[0, 0] = 0.0  # a mirror: alpha 1e-6, floored
    normal = np.concatenate([random_unit(rng, (size, size)), roughness[..., None]], -1)
    flux = np.concatenate([rng.uniform(0.0, 2.0, (size, size, 3)), np.ones((size, size, 1))], -1)
    flux[1, :, :3] = 0.0  # unlit
    point = SimpleNamespace(type="POINT", position=np.array([0.5, -1.0, 3.0]), direction=np.array([0.0, 0.0, -1.0]))
    sun = SimpleNamespace(type="SUN", position=np.zeros(3), direction=np.array([0.3, 0.0, -1.0]) / np.hypot(0.3, 1.0))
    for light in (point, sun):
        records, texels = vc.extract_glossy_vpls(position, normal, flux, vc.light_vector(light), 0.1)
        alpha = principled_alpha(roughness)
        vpls = vc.glossy_vpls_from_rsm(position[..., :3], normal[..., :3],
                                       incoming_directions(light, position[..., :3]), flux[..., :3],
                                       np.ones((size, size, 3)), alpha, 0.1)
        assert 0 < len(texels) < size * size
        np.testing.assert_array_equal(texels, vpls["texel"])
        np.testing.assert_array_equal(records[:, 0, :3], vpls["position"])
        np.testing.assert_array_equal(records[:, 0, 3], np.maximum(vpls["roughness"], vc.VPL_ALPHA_MIN))
        np.testing.assert_array_equal(records[:, 1, :3], vpls["normal"])
        np.testing.assert_array_equal(records[:, 1, 3], np.max(vpls["flux"], axis=-1))
        np.testing.assert_allclose(records[:, 2, :3], vpls["incoming"], atol=1e-15)
        np.testing.assert_array_equal(records[:, 3, :3], vpls["flux"])
        assert 0 in texels and not np.isin(texels, np.arange(size, 2 * size)).any()
    none, texels = vc.extract_glossy_vpls(position, np.concatenate([normal[..., :3], np.ones((size, size, 1))], -1),
                                          flux, vc.light_vector(point), 0.1)
    assert none.shape == (0, 4, 4) and texels.shape == (0,)
    _, on_light = vc.glossy_vpl_from_texel(np.append(point.position, 0.0), normal[0, 0], flux[0, 0],
                                           vc.light_vector(point), 0.1)
    assert np.all(np.isfinite(on_light)) and np.isclose(np.linalg.norm(on_light[2, :3]), 1.0)


def orthographic(half, near, far):
    return np.array([[1 / half, 0, 0, 0], [0, 1 / half, 0, 0],
                     [0, 0, -2 / (far - near), -(far + near) / (far - near)], [0, 0, 0, 1]])


@pytest.mark.parametrize("projection", [perspective(np.radians(50.0), 1.5, 0.1, 30.0), orthographic(3.0, 0.1, 30.0)])
def test_tile_frustum_holds_exactly_the_tile(projection):
    """Points whose NDC lies in the tile and whose depth lies in the range are inside every plane;
    points beside the tile or beyond its depth range are outside one."""
    rng = np.random.default_rng(RNG_SEED + 6)
    v2w = look_at(np.array([1.0, -2.0, 1.0]), np.array([0.0, 3.0, 0.5]))
    inv_proj = np.linalg.inv(projection)
    lo, hi, dmin, dmax = np.array([-0.3, 0.1]), np.array([-0.1, 0.35]), 2.0, 5.0
    planes = vc.tile_frustum_planes(inv_proj, v2w, lo, hi, dmin, dmax)

    def world_points(ndc_xy, depth):
        near = np.einsum("ij,nj->ni", inv_proj, np.column_stack([ndc_xy, -np.ones(len(depth)), np.ones(len(depth))]))
        far = np.einsum("ij,nj->ni", inv_proj, np.column_stack([ndc_xy, np.ones(len(depth)), np.ones(len(depth))]))
        near, far = near[:, :3] / near[:, 3:], far[:, :3] / far[:, 3:]
        t = (depth + near[:, 2]) / (near[:, 2] - far[:, 2])
        view = near + t[:, None] * (far - near)
        return view @ v2w[:3, :3].T + v2w[:3, 3]

    n = 2000
    inside = world_points(rng.uniform(lo, hi, (n, 2)), rng.uniform(dmin, dmax, n))
    values = inside @ planes[:, :3].T + planes[:, 3]
    assert np.all(values >= -1e-9 * np.abs(planes[:, :3]).max())
    beside = world_points(rng.uniform(hi + 0.01, hi + 0.3, (n, 2)), rng.uniform(dmin, dmax, n))
    beyond = world_points(rng.uniform(lo, hi, (n, 2)), rng.uniform(dmax * 1.01, dmax * 2, n))
    for outside in (beside, beyond):
        assert np.all(np.any(outside @ planes[:, :3].T + planes[:, 3] < 0.0, axis=1))


def test_tile_receiver_frustum_spans_the_covered_pixel_centres():
    """The tile frustum over a box of covered pixels holds their centre rays' receivers (inside every
    side plane by about PIXEL_MARGIN pixels), however narrow the box, and lies within the frustum
    through the tile's pixel edges; a sphere in the half-pixel strip between the outermost centres
    and the tile's edge is listed by the edge frustum only (it lights no receiver)."""
    width, height = 72, 40
    v2w = look_at(np.array([-1.0, 0.0, 1.5]), np.array([2.0, 0.0, 1.5]))
    proj = perspective(np.radians(60.0), width / height, 0.1, 20.0)
    inv_proj = np.linalg.inv(proj)
    size = np.array([width, height])

    def ray_point(pixel_xy, depth):
        ndc = (np.asarray(pixel_xy, float) + 0.5) / size * 2.0 - 1.0
        view = inv_proj @ np.array([ndc[0], ndc[1], 1.0, 1.0])
        direction = view[:3] / view[3]
        return v2w[:3, :3] @ (direction * depth / -direction[2]) + v2w[:3, 3]

    dmin, dmax = 2.0, 3.0
    for pmin, pmax in (([64, 32], [71, 39]), ([3, 5], [3, 5]), ([16, 0], [31, 0]), ([0, 16], [15, 31])):
        lo, hi = vc.tile_receiver_ndc(pmin, pmax, size)
        planes = vc.tile_frustum_planes(inv_proj, v2w, lo, hi, dmin, dmax)
        corners = vc.tile_frustum_corners(inv_proj, v2w, lo, hi, dmin, dmax)
        xs, ys = np.meshgrid(np.arange(pmin[0], pmax[0] + 1), np.arange(pmin[1], pmax[1] + 1))
        for x, y in zip(xs.ravel(), ys.ravel()):
            for depth in (dmin, 0.5 * (dmin + dmax), dmax):
                point = ray_point([x, y], depth)
                values = planes @ np.append(point, 1.0) / np.linalg.norm(planes[:, :3], axis=1)
                assert np.all(values[4:] >= -1e-9)
                # The outermost centres' distance from their side planes, in pixels (2 d tan(fov/2)
                # / height at depth d): the margin, foreshortened by at most cos(46 deg) at the
                # image's edge.
                pixel = 2.0 * depth * np.tan(np.radians(30.0)) / height
                outermost = np.array([y == pmin[1], x == pmax[0], y == pmax[1], x == pmin[0]])
                assert np.all(values[:4] > 0.0)
                assert np.all(values[:4][outermost] / pixel >= 0.5 * vc.PIXEL_MARGIN)
        # Within the tile's pixel edges' frustum, whose corners hold it.
        tile = np.array(pmin) // 16
        edges_lo = tile * 16 / size * 2.0 - 1.0
        edges_hi = np.minimum(tile * 16 + 16, size) / size * 2.0 - 1.0
        assert np.all(lo >= edges_lo) and np.all(hi <= edges_hi)
        assert np.all(lo > edges_lo) and np.all(hi < edges_hi)
    # A small sphere just beyond the last pixel centre column of a partial tile (x 64..71), inside
    # the tile's edge frustum: the centre frustum rejects it, the edge frustum lists it.
    lo, hi = vc.tile_receiver_ndc([64, 32], [71, 39], size)
    planes = vc.tile_frustum_planes(inv_proj, v2w, lo, hi, dmin, dmax)
    corners = vc.tile_frustum_corners(inv_proj, v2w, lo, hi, dmin, dmax)
    edge_planes = vc.tile_frustum_planes(inv_proj, v2w, [64 / 36 - 1, 32 / 20 - 1], [1.0, 1.0], dmin, dmax)
    edge_corners = vc.tile_frustum_corners(inv_proj, v2w, [64 / 36 - 1, 32 / 20 - 1], [1.0, 1.0], dmin, dmax)
    pixel = 2.0 * 2.5 * np.tan(np.radians(30.0)) / height
    centre = ray_point([71.4, 35.0], 2.5)  # 0.4 px beyond the last centre, 0.1 px inside the edge
    axes, rotation = np.full(3, 0.05 * pixel), np.eye(3)
    assert not vc.ellipsoid_frustum_overlap_exact(planes, corners, centre, axes, rotation)
    assert vc.ellipsoid_frustum_overlap_exact(edge_planes, edge_corners, centre, axes, rotation)


def _random_frustum(rng, flat=False):
    """A tile frustum (planes, corners, sampler) of a random camera: perspective or orthographic, a
    tile of a few pixels' NDC width, a depth range (flat: depth_min = depth_max)."""
    eye = rng.normal(size=3) * 2.0
    v2w = look_at(eye, eye + random_unit(rng, ()) + np.array([0.0, 0.0, 0.1]))
    proj = perspective(np.radians(rng.uniform(20.0, 90.0)), rng.uniform(0.7, 1.8), 0.1, 50.0) \
        if rng.uniform() < 0.7 else orthographic(rng.uniform(1.0, 5.0), 0.1, 50.0)
    inv_proj = np.linalg.inv(proj)
    lo = rng.uniform(-1.0, 0.8, 2)
    hi = lo + rng.uniform(0.02, 0.2, 2)
    dmin = rng.uniform(0.5, 8.0)
    dmax = dmin if flat else dmin + rng.uniform(0.01, 3.0)
    planes = vc.tile_frustum_planes(inv_proj, v2w, lo, hi, dmin, dmax)
    corners = vc.tile_frustum_corners(inv_proj, v2w, lo, hi, dmin, dmax)

    def sample(n):
        # Points of the frustum on an n^3 grid of (NDC x, NDC y, depth): each on its view ray.
        u, v, d = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n),
                              np.linspace(dmin, dmax, n), indexing="ij")
        ones = np.ones(u.size)
        near = np.einsum("ij,nj->ni", inv_proj, np.column_stack([u.ravel(), v.ravel(), -ones, ones]))
        far = np.einsum("ij,nj->ni", inv_proj, np.column_stack([u.ravel(), v.ravel(), ones, ones]))
        near, far = near[:, :3] / near[:, 3:], far[:, :3] / far[:, 3:]
        t = (d.ravel() + near[:, 2]) / (near[:, 2] - far[:, 2])
        return (near + t[:, None] * (far - near)) @ v2w[:3, :3].T + v2w[:3, 3]

    return planes, corners, sample


def _random_ellipsoid(rng, corners):
    """An ellipsoid near the frustum: semi-axes of a GGX spheroid ((1 + a^2)/(2a) r, r, r) for
    alpha 1e-3 ... 1, or a sphere; random orientation; centre within a few of its sizes of the box
    of the corners."""
    alpha = 10.0 ** rng.uniform(-3.0, 0.0)
    extent = np.linalg.norm(corners.max(0) - corners.min(0))
    r = extent * 10.0 ** rng.uniform(-1.5, 0.5)
    axes = np.array([(1.0 + alpha**2) / (2.0 * alpha) * r, r, r]) if rng.uniform() < 0.8 else np.full(3, r)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    reach = rng.uniform(0.0, 1.3) * axes.max() + extent
    centre = corners.mean(0) + random_unit(rng, ()) * reach * rng.uniform(0.3, 1.0)
    return centre, axes, q.T


def test_exact_frustum_test_against_dense_sampling():
    """ellipsoid_frustum_distance equals the smallest stretched norm over dense samples of the frustum
    within the samples' spacing and is never above it (so the exact test is conservative); it
    rejects ellipsoids beyond an edge or corner that the plane test (004 Eq. 16) keeps."""
    rng = np.random.default_rng(RNG_SEED + 9)
    n = 24
    near_misses = overlaps = 0
    for case in range(400):
        planes, corners, sample = _random_frustum(rng, flat=case % 10 == 0)
        centre, axes, rotation = _random_ellipsoid(rng, corners)
        points = sample(n)
        local = (points - centre) @ rotation.T / axes
        sampled = np.min(np.linalg.norm(local, axis=-1))
        exact = vc.ellipsoid_frustum_distance(planes, corners, centre, axes, rotation)
        stretched = (corners - centre) @ rotation.T / axes
        edges = np.linalg.norm(stretched[vc.FRUSTUM_EDGES[:, 1]] - stretched[vc.FRUSTUM_EDGES[:, 0]], axis=-1)
        spacing = (2.0 * edges[:8].max() + edges[8:].max()) / (n - 1)
        assert exact <= sampled + 1e-9 * (1.0 + sampled), f"case {case}: exact {exact} above sampled {sampled}"
        assert exact >= sampled - spacing - 1e-9, f"case {case}: exact {exact} far below sampled {sampled}"
        inside_samples = sampled <= 1.0
        exact_overlap = vc.ellipsoid_frustum_overlap_exact(planes, corners, centre, axes, rotation)
        plane_overlap = vc.ellipsoid_frustum_overlap(planes, centre, axes, rotation)
        if inside_samples:
            assert exact_overlap and plane_overlap
            overlaps += 1
        if plane_overlap and not exact_overlap:
            assert sampled > 1.0
            near_misses += 1
        assert exact_overlap <= plane_overlap  # exact never lists what the plane test culls
    assert overlaps >= 40 and near_misses >= 40, (overlaps, near_misses)


def test_exact_frustum_test_extremes_finite():
    """Finite distances and the right answer for alpha 1e-3 ... 1 at grazing incidence, delta xi -> 0
    (radii up to 1e15), tiny radii and a flat tile (depth_min = depth_max)."""
    rng = np.random.default_rng(RNG_SEED + 10)
    planes, corners, sample = _random_frustum(rng, flat=True)
    inside = sample(3)[13]
    count = 64
    alpha = np.logspace(-3, 0, count)
    normal = np.broadcast_to([0.0, 0.0, 1.0], (count, 3))
    incoming = np.broadcast_to([1.0, 0.0, 1e-7], (count, 3)) / np.sqrt(1.0 + 1e-14)
    for delta_xi, flux in ((1e-30, 1.0), (1e-3, 1e-30), (1e-3, 1.0)):
        centre, axes, rotation = vc.ggx_spheroid(np.broadcast_to(inside, (count, 3)), normal, incoming,
                                                 alpha, flux, delta_xi, 1.0)
        distance = vc.ellipsoid_frustum_distance(planes[None], corners[None], centre, axes, rotation)
        assert np.all(np.isfinite(distance))
        # Each spheroid holds its VPL q (on the frustum's flat face), so it overlaps.
        assert np.all(vc.ellipsoid_frustum_overlap_exact(planes[None], corners[None], centre, axes, rotation))
