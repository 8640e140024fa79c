# SPDX-License-Identifier: GPL-3.0-or-later
"""GLSL twins of stochastic light culling (glsl/lib/vpl_culling.glsl) against the float64 reference
(vsgl_addon/reference/vpl_culling.py) on llvmpipe: the per-VPL xi bit for bit, ranges, spheroid,
diffuse sphere, the stretched plane distance (004 Eq. 16) and the VPL-to-receiver geometry, over
roughness 1e-3 ... 1, grazing incidence, delta 1e-6 ... 1e-1 and xi down to 0. Inputs are rounded
to float32 first and the reference runs on those values. Criterion: glsl_harness.Accuracy
(relative 1e-4 where significant), the containment decision identical away from the boundary, and
no NaN or Inf."""

from __future__ import annotations

import numpy as np
import pytest

from glsl_harness import Accuracy, as_gpu_floats, evaluate_glsl
from vsgl_addon.reference import vpl_culling as vc

pytestmark = pytest.mark.gpu
LIB = ["lib/vpl_culling.glsl"]


def test_xi_bit_exact():
    index = np.arange(0, 1 << 16, 7, dtype=np.float64)
    seeds = np.array([0.0, 1.0, 12345.0, 65535.0])
    for seed in seeds:
        for frame in (0.0, 1.0, 977.0):
            gpu = evaluate_glsl("vpl_xi(uint(index), uint(seed), uint(frame))",
                                {"index": index, "seed": np.full_like(index, seed),
                                 "frame": np.full_like(index, frame)}, libraries=LIB)
            np.testing.assert_array_equal(gpu, vc.vpl_xi(index.astype(np.uint64), int(seed), int(frame)))


def _grid(rng, count):
    roughness = as_gpu_floats(np.repeat(np.logspace(-3, 0, 8), count // 8))
    n = len(roughness)
    normal = rng.normal(size=(n, 3))
    normal = as_gpu_floats(normal / np.linalg.norm(normal, axis=-1, keepdims=True))
    tangent = np.cross(normal, rng.normal(size=(n, 3)))
    tangent /= np.linalg.norm(tangent, axis=-1, keepdims=True)
    cos_i = np.concatenate([[1.0, 0.0, 1e-6, 1e-3], rng.uniform(0.0, 1.0, n - 4)])
    incoming = cos_i[:, None] * normal + np.sqrt(1 - cos_i**2)[:, None] * tangent
    incoming = as_gpu_floats(incoming / np.linalg.norm(incoming, axis=-1, keepdims=True))
    delta = as_gpu_floats(10.0 ** rng.uniform(-6, -1, n))
    xi = as_gpu_floats(np.concatenate([[0.0, 1e-7], rng.uniform(0.0, 1.0, n - 2)]))
    flux = as_gpu_floats(10.0 ** rng.uniform(-4, 1, n))
    position = as_gpu_floats(rng.normal(size=(n, 3)))
    return dict(roughness=roughness, normal=normal, incoming=incoming, delta=delta, xi=xi, flux=flux,
                position=position)


def test_ranges_and_spheroid():
    rng = np.random.default_rng(4)
    g = _grid(rng, 4096)
    body = """
    vec3 c, a, u, v, w;
    ggx_spheroid(position, normal, incoming, roughness, flux, delta, xi, 1.0, c, a, u, v, w);
    centre = c; axes = a; axis_u = u;
    radius = ggx_range_radius(dot(incoming, normal), roughness, flux, delta, xi, 1.0);
    vec3 dc;
    float dr = diffuse_sphere(position, normal, flux, delta, xi, dc);
    diffuse = vec4(dc, dr);
    """
    out = evaluate_glsl(body, g, {"centre": 3, "axes": 3, "axis_u": 3, "radius": 1, "diffuse": 4}, libraries=LIB)
    centre, axes, rotation = vc.ggx_spheroid(g["position"], g["normal"], g["incoming"], g["roughness"],
                                             g["flux"], g["delta"], g["xi"])
    radius = vc.ggx_range_radius(np.sum(g["incoming"] * g["normal"], -1), g["roughness"], g["flux"],
                                 g["delta"], g["xi"])
    dcentre, dradius = vc.diffuse_sphere(g["position"], g["normal"], g["flux"], g["delta"], g["xi"])
    idx = np.arange(len(radius))
    for name, gpu, ref in (("radius", out["radius"], radius), ("axes", out["axes"], axes),
                           ("axis_u", out["axis_u"], rotation[:, 0]),
                           ("diffuse_radius", out["diffuse"][:, 3], dradius)):
        acc = Accuracy(gpu, ref, idx)
        assert acc.ok, f"{name}: worst relative {acc.worst_relative:.3g}"
    # Centres: q + offset w_u with offset up to 500 r (alpha = 1e-3) -- relative to |c - q| + |q|.
    for gpu, ref in ((out["centre"], centre), (out["diffuse"][:, :3], dcentre)):
        scale = np.linalg.norm(ref - g["position"], axis=-1) + np.linalg.norm(g["position"], axis=-1)
        assert np.all(np.linalg.norm(gpu - ref, axis=-1) <= 3e-6 * scale)
    assert np.all(np.isfinite(out["axes"])) and np.all(np.isfinite(out["centre"]))


def test_plane_distance_and_geometry():
    rng = np.random.default_rng(5)
    g = _grid(rng, 2048)
    n = len(g["xi"])
    g["xi"] = as_gpu_floats(rng.uniform(0.01, 1.0, n))
    g["flux"] = as_gpu_floats(10.0 ** rng.uniform(-4, -2, n))
    plane = rng.normal(size=(n, 3))
    g["plane_normal"] = as_gpu_floats(plane / np.linalg.norm(plane, axis=-1, keepdims=True))
    g["plane_offset"] = as_gpu_floats(rng.normal(size=n) * 3.0)
    receiver = g["position"] + rng.normal(size=(n, 3))
    g["receiver"] = as_gpu_floats(receiver)
    g["receiver_normal"] = as_gpu_floats(-g["normal"][rng.permutation(n)])
    body = """
    vec3 c, a, u, v, w;
    ggx_spheroid(position, normal, incoming, roughness, flux, delta, xi, 1.0, c, a, u, v, w);
    distance = ellipsoid_plane_distance(plane_normal, plane_offset, c, a, u, v, w);
    float intensity_, l2;
    geometry = glossy_vpl_geometry(receiver, receiver_normal, position, normal, incoming, roughness, flux,
                                   intensity_, l2);
    intensity = intensity_;
    """
    out = evaluate_glsl(body, g, {"distance": 1, "geometry": 1, "intensity": 1}, libraries=LIB)
    centre, axes, rotation = vc.ggx_spheroid(g["position"], g["normal"], g["incoming"], g["roughness"],
                                             g["flux"], g["delta"], g["xi"])
    distance = vc.ellipsoid_plane_distance(g["plane_normal"], g["plane_offset"], centre, axes, rotation)
    assert np.all(np.isfinite(out["distance"]))
    # The culling decision (distance >= -1) agrees wherever it is not within float32 rounding of -1.
    clear = np.abs(distance + 1.0) > 1e-4 * (1.0 + np.abs(distance))
    np.testing.assert_array_equal((out["distance"] >= -1.0)[clear], (distance >= -1.0)[clear])
    acc = Accuracy(out["distance"], distance, np.arange(n), relative=2e-4)
    assert acc.ok, f"plane distance: worst relative {acc.worst_relative:.3g}"
    flux_rgb = np.repeat(g["flux"][:, None], 3, 1)
    radiance, intensity, l2 = vc.glossy_vpl_radiance(g["receiver"], g["receiver_normal"], np.full((n, 3), np.pi),
                                                     g["position"], g["normal"], g["incoming"], g["roughness"],
                                                     flux_rgb, np.ones((n, 3)))
    geometry = radiance[:, 0] / g["flux"]
    groups = np.round(np.log10(g["roughness"]), 1)
    for name, gpu, ref in (("geometry", out["geometry"], geometry), ("intensity", out["intensity"], intensity)):
        acc = Accuracy(gpu, ref, groups, relative=1e-3)
        assert acc.ok, f"{name}: worst relative {acc.worst_relative:.3g}"


def _frustum_inputs(cases):
    """The GLSL probe's inputs of (planes, corners, centre, axes, rotation) cases, float32-rounded,
    and the same values for the reference."""
    planes = as_gpu_floats(np.array([c[0] for c in cases]))
    corners = as_gpu_floats(np.array([c[1] for c in cases]))
    centre = as_gpu_floats(np.array([c[2] for c in cases]))
    axes = as_gpu_floats(np.array([c[3] for c in cases]))
    rotation = as_gpu_floats(np.array([c[4] for c in cases]))
    inputs = {f"plane{k}": planes[:, k] for k in range(6)}
    inputs.update({f"corner{k}": corners[:, k] for k in range(8)})
    inputs.update(centre=centre, axes=axes, axis_u=rotation[:, 0], axis_v=rotation[:, 1], axis_w=rotation[:, 2])
    return inputs, (planes, corners, centre, axes, rotation)


EXACT_BODY = """
vec4 planes[6] = vec4[6](plane0, plane1, plane2, plane3, plane4, plane5);
vec3 corners[8] = vec3[8](corner0, corner1, corner2, corner3, corner4, corner5, corner6, corner7);
result = ellipsoid_frustum_overlap_exact(planes, corners, centre, axes, axis_u, axis_v, axis_w, 1e-4) ? 1.0 : 0.0;
"""


def test_exact_frustum_test_matches_reference():
    """The GLSL exact ellipsoid-frustum test against reference ellipsoid_frustum_distance: it lists
    every ellipsoid the reference finds overlapping (conservative), and decides as the reference
    wherever the distance is not within float32 rounding of 1, edge and corner near misses (the plane
    test lists them) included."""
    from test_reference_vpl_culling import _random_ellipsoid, _random_frustum

    rng = np.random.default_rng(11)
    cases = []
    for case in range(3000):
        planes, corners, _ = _random_frustum(rng, flat=case % 10 == 0)
        cases.append((planes, corners) + _random_ellipsoid(rng, corners))
    inputs, (planes, corners, centre, axes, rotation) = _frustum_inputs(cases)
    gpu = evaluate_glsl(EXACT_BODY, inputs, libraries=LIB) > 0.5
    distance = vc.ellipsoid_frustum_distance(planes, corners, centre, axes, rotation)
    plane = vc.ellipsoid_frustum_overlap(planes, centre, axes, rotation)
    assert np.all(gpu[distance <= 1.0]), "the GLSL test culled an overlapping ellipsoid"
    clear = np.abs(distance - 1.0) > 1e-3 * (1.0 + distance)
    np.testing.assert_array_equal(gpu[clear], (distance <= 1.0)[clear])
    near_miss = plane & (distance > 1.0 + 1e-3) & clear
    assert near_miss.sum() >= 200 and not np.any(gpu[near_miss])
    assert (distance <= 1.0).sum() >= 200


def test_exact_frustum_test_extremes():
    """alpha 1e-3 ... 1 spheroids at grazing incidence through a flat tile (depth_min = depth_max), with
    delta xi -> 0 (radii ~1e15, the tile deep inside) and tiny flux (radii ~1e-14): each holds its
    VPL on the tile, so every one is listed; the same moved off the tile by 1 m is culled unless
    huge."""
    from test_reference_vpl_culling import _random_frustum

    rng = np.random.default_rng(12)
    planes, corners, sample = _random_frustum(rng, flat=True)
    on_tile = sample(3)[13]
    count = 64
    alpha = as_gpu_floats(np.logspace(-3, 0, count))
    normal = np.broadcast_to(np.cross(corners[1] - corners[0], corners[3] - corners[0]), (count, 3))
    normal = normal / np.linalg.norm(normal, axis=-1, keepdims=True)
    tangent = (corners[1] - corners[0]) / np.linalg.norm(corners[1] - corners[0])
    incoming = tangent + 1e-6 * normal
    incoming = np.broadcast_to(incoming / np.linalg.norm(incoming), (count, 3))
    off = on_tile + 1.0 * normal[0] + 0.0
    for position, expect in ((on_tile, True), (off, None)):
        for delta_xi, flux in ((1e-30, 1.0), (1e-3, 1e-24), (1e-3, 1.0)):
            centre, axes, rotation = vc.ggx_spheroid(np.broadcast_to(position, (count, 3)), normal, incoming,
                                                     alpha, flux, delta_xi, 1.0)
            cases = [(planes, corners, centre[i], axes[i], rotation[i]) for i in range(count)]
            inputs, args = _frustum_inputs(cases)
            gpu = evaluate_glsl(EXACT_BODY, inputs, libraries=LIB) > 0.5
            distance = vc.ellipsoid_frustum_distance(*args)
            assert np.all(np.isfinite(distance))
            if expect:
                assert np.all(gpu)
            else:
                assert np.all(gpu[distance <= 1.0])
                clear = np.abs(distance - 1.0) > 1e-3 * (1.0 + distance)
                np.testing.assert_array_equal(gpu[clear], (distance <= 1.0)[clear])
                if flux < 1e-20:
                    assert not np.any(gpu)
