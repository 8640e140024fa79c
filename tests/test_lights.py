"""Blender's light emission model (glsl/lib/light_emission.glsl) against its float64 twin
(vsgl_addon/reference/lights.py), which the RSM and the direct light share."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from vsgl_addon.reference import lights as ref

from glsl_harness import Accuracy, as_gpu_floats, evaluate_glsl


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _light(kind, spot_size=1.2, spot_blend=0.4, scale=(1.0, 1.5, 1.0), power=250.0):
    """A light whose local -Z points along (0.2, 0.1, -1), with a non-uniform object scale."""
    z = -_unit(np.array([0.2, 0.1, -1.0]))
    x = _unit(np.cross([0.3, 1.0, 0.2], z))
    y = np.cross(z, x)
    matrix = np.eye(4)
    matrix[:3, :3] = np.stack([x, y, z], axis=1) * np.asarray(scale, float)
    return SimpleNamespace(type=kind, power=power, spot_size=spot_size, spot_blend=spot_blend,
                           matrix_world=matrix, direction=-z)


def test_params_and_cone_solid_angle():
    assert ref.light_params(_light("POINT", power=4.0 * math.pi)) == (0.0, 0.0, 0.0, 1.0)
    assert ref.light_params(_light("AREA", power=math.pi))[::3] == (3.0, 1.0)
    assert ref.light_params(_light("SUN", power=3.0))[::3] == (2.0, 3.0)
    code, cos_half, smooth, _ = ref.light_params(_light("SPOT", spot_size=1.0, spot_blend=0.0))
    assert (code, cos_half, smooth) == (1.0, pytest.approx(math.cos(0.5)), -1.0)
    # A hard cone: the solid angle of a cap, 2π (1 − cos half angle).
    assert ref.spot_cone_solid_angle(1.0, 0.0) == pytest.approx(2.0 * math.pi * (1.0 - math.cos(0.5)), rel=1e-5)


@pytest.mark.gpu
@pytest.mark.parametrize("kind,spot_blend", [("POINT", 0.4), ("SPOT", 0.4), ("SPOT", 0.0), ("SUN", 0.4),
                                             ("AREA", 0.4)])
def test_light_intensity_glsl_matches_numpy(kind, spot_blend):
    rng = np.random.default_rng(5)
    count = 4000
    light = _light(kind, spot_blend=spot_blend)
    directions = _unit(rng.normal(size=(count, 3)))
    # Half of them near the spot axis, where the cone's edge lies.
    directions[: count // 2] = _unit(light.direction + 0.8 * rng.normal(size=(count // 2, 3)))
    directions = as_gpu_floats(directions)
    to_local = np.linalg.inv(light.matrix_world[:3, :3])
    inputs = {"params": np.tile(ref.light_params(light), (count, 1)), "direction": directions,
              "axis": np.tile(light.direction, (count, 1)), "r0": np.tile(to_local[0], (count, 1)),
              "r1": np.tile(to_local[1], (count, 1)), "r2": np.tile(to_local[2], (count, 1))}
    out = evaluate_glsl("light_intensity(params, direction, axis, transpose(mat3(r0, r1, r2)))",
                        {k: as_gpu_floats(v) for k, v in inputs.items()},
                        libraries=["lib/light_emission.glsl"])
    expected = ref.light_intensity(light, directions)
    # A hard spot edge flips between 0 and 1 where float32 rounding decides: leave out the
    # directions within 1e-5 of it.
    keep = np.ones(count, bool)
    if kind == "SPOT" and spot_blend == 0.0:
        to_local_dirs = _unit(directions @ to_local.T)
        keep = np.abs(-to_local_dirs[:, 2] - math.cos(0.5 * light.spot_size)) > 1e-5
    # On the smooth edge, cos − cos_half cancels in float32 (~1e-7 absolute, ~1e-6 after the
    # 1/((1 − cos) blend) scale): 3x² is then off by ~2e-6/x relative, so values below 1 % of the
    # peak are held to an absolute 1e-6 of it.
    accuracy = Accuracy(out[keep], expected[keep], relative=1e-4, absolute=1e-6, significant=1e-2)
    print(kind, spot_blend, accuracy.summary())
    assert accuracy.ok, accuracy.report()
    if kind == "SPOT":
        assert 0.0 < np.mean(expected > 0.0) < 1.0  # both sides of the cone were tested
