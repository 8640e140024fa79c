# SPDX-License-Identifier: GPL-3.0-or-later
"""The share of a VSGL diffuse lobe that its own reflector does not hide (reference
vsgl_shading.vsgl_reflector_side, an option of benchmarks/visibility_diagnosis.py; the shader keeps a
flat reflector's own surface in its map instead, pipeline.VSGL_OWN_REFLECTOR_SIGMAS), against brute
force over the texels of spherical caps (flat to a hemisphere).

Brute force: the cluster's texels on a cap of half-angle θc, each a Lambertian emitter; the light
one sends towards a receiver x is ∝ max(⟨n_t, x − y_t⟩, 0)/|x − y_t|. The share the reflector does
not hide is that sum relative to the same sum with the receiver moved onto the lobe's mean plane
(elevation 0, same distance and azimuth) — what the VSGL's own lobe already gives there (its SG
falls off with the angle from its axis; the share only has to take away what lies behind the
reflector). The model must hide all of it behind a flat reflector, and never hide much more than
brute force does behind a curved one (it may hide less: it is a bound on what is certainly hidden).
"""

from __future__ import annotations

import numpy as np
import pytest

from vsgl_addon.reference import vsgl_shading as vs
from vsgl_addon.reference.sg import DIFFUSE_SHARPNESS


def _cap(theta_c, count=20000, seed=0):
    """Texel positions (= their normals) uniformly on the unit sphere's cap about +z of half-angle θc."""
    rng = np.random.default_rng(seed)
    cos_t = 1.0 - rng.random(count) * (1.0 - np.cos(theta_c))
    phi = rng.random(count) * 2.0 * np.pi
    sin_t = np.sqrt(1.0 - cos_t ** 2)
    points = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)
    return points, points


def _lobe(normals):
    """The cluster's diffuse lobe axis and sharpness as VSGL generation makes them (000 app. B.1):
    every texel's λ = 2 lobe contributes λ/(1 + λ) of its normal to the mean direction."""
    mean_direction = DIFFUSE_SHARPNESS / (1.0 + DIFFUSE_SHARPNESS) * normals.mean(axis=0)
    length = np.linalg.norm(mean_direction)
    return mean_direction / length, length / (1.0 - length)


def _emitted(positions, normals, receiver):
    offset = receiver - positions
    distance = np.linalg.norm(offset, axis=-1)
    return float(np.sum(np.maximum((offset * normals).sum(-1), 0.0) / distance ** 2))


@pytest.mark.parametrize("cap_degrees", [1.0, 20.0, 45.0, 90.0])
def test_the_share_follows_brute_force_over_a_cap_of_texels(cap_degrees):
    positions, normals = _cap(np.radians(cap_degrees))
    mean = positions.mean(axis=0)
    axis, sharpness = _lobe(normals)
    side = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    for distance in (1.5, 4.0, 20.0):
        horizon = _emitted(positions, normals, mean + distance * side)
        for elevation in np.radians([-60.0, -30.0, -10.0, -3.0, 0.0, 5.0, 30.0]):
            receiver = mean + distance * (np.cos(elevation) * side + np.sin(elevation) * axis)
            brute = _emitted(positions, normals, receiver) / horizon
            share = float(vs.vsgl_reflector_side(mean, axis, sharpness, receiver))
            assert 0.0 <= share <= 1.0
            if elevation >= 0.0:
                assert share == pytest.approx(1.0, abs=1e-3)  # nothing in front of the plane is hidden
            elif cap_degrees <= 1.0:
                assert share == 0.0, (distance, elevation)  # a flat reflector hides everything behind it
                assert brute < 0.05
            else:
                assert share >= min(brute, 1.0) - 0.1, (cap_degrees, distance, np.degrees(elevation), share, brute)


def test_a_thin_wall_s_sunlit_back_does_not_light_its_shaded_front():
    """The case that motivates it: texels on a wall's back (y = 0.1, normal +y), a receiver on its
    front (y = −0.1, normal −y); the VSGL's mean is on the back, the receiver a few σ away."""
    axis = np.array([0.0, 1.0, 0.0])
    mean = np.array([0.0, 0.1, 1.0])
    for receiver in ([0.3, -0.1, 1.2], [2.0, -0.1, 0.2], [0.0, -0.1, 1.0]):
        assert vs.vsgl_reflector_side(mean, axis, DIFFUSE_SHARPNESS, np.array(receiver)) == 0.0


def test_extremes_stay_finite_and_in_range():
    rng = np.random.default_rng(4)
    axis = rng.normal(size=(200, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    sharpness = np.concatenate([[0.0, 1e-6, 1e-3, 2.0, 1e3, 1e6], rng.uniform(0.0, 3.0, 194)])
    mean = rng.normal(size=(200, 3))
    position = np.where(np.arange(200)[:, None] % 5 == 0, mean, mean + rng.normal(size=(200, 3)) * 10.0 ** rng.uniform(-6, 3, (200, 1)))
    share = vs.vsgl_reflector_side(mean, axis, sharpness, position)
    assert np.all(np.isfinite(share)) and np.all((share >= 0.0) & (share <= 1.0))
    assert np.all(share[np.arange(200) % 5 == 0] == 1.0)  # at the lobe's own position: nothing hidden


def test_the_lookup_is_the_maps_times_the_side():
    """vsgl_visibility's default (the maps alone, as the shader) times the diffuse lobe's side is its
    reflector_side=True lookup (benchmarks/visibility_diagnosis.py); the specular lobe has no side."""
    rng = np.random.default_rng(7)
    count, size = 3, 8
    axis = rng.normal(size=(count, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    vsgls = {"diffuse_mean": rng.normal(size=(count, 3)), "diffuse_variance": rng.uniform(0.01, 0.5, count),
             "diffuse_axis": axis, "diffuse_sharpness": rng.uniform(0.2, 3.0, count), "specular_axis": axis}
    depths = rng.uniform(0.5, 4.0, (count, size, size))
    position = rng.normal(size=(50, 3)) * 2.0
    normal = rng.normal(size=(50, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    full = vs.vsgl_visibility(depths, 1, vsgls, position, normal, 1, reflector_side=True)
    maps = vs.vsgl_visibility(depths, 1, vsgls, position, normal, 1)
    side = vs.vsgl_reflector_side(vsgls["diffuse_mean"][None], axis[None], vsgls["diffuse_sharpness"][None],
                                  position[:, None])
    assert np.allclose(full[..., 0], maps[..., 0] * side)
    assert np.array_equal(full[..., 1], maps[..., 1])
    assert (side < 1.0).any()  # some receivers lie behind a lobe's plane
