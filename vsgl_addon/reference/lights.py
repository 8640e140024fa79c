# SPDX-License-Identifier: GPL-3.0-or-later
"""Float64 twin of ``glsl/lib/light_emission.glsl``: Blender's light emission model (formulas.md §4), shared
by the RSM (:mod:`.rsm`: the flux of a texel) and the direct light (:mod:`.direct_light`: the
irradiance of a point), in Blender's units:

* point light of power P: radiant intensity P / (4π) W/sr in every direction;
* spot light: the same, times Blender's cone attenuation (:func:`spot_attenuation`);
* area light of power P: a Lambertian point emitter, I(θ) = (P/π) cos θ about its −Z axis (the
  emitter's size and shape, and the spread, are not modelled: "small area light");
* sun of strength S: irradiance S W/m² on a surface facing it (no intensity: :func:`light_intensity`
  returns S).

Checked against Cycles 5.0 through the direct light (tests/test_direct_light.py) and against closed
forms through the RSM's flux (tests/test_rsm.py); the GLSL against this in tests/test_lights.py.
"""

from __future__ import annotations

import math

import numpy as np

from .numerics import f64, norm

#: Light type codes, ``params[0]`` (the numbering of light_emission.glsl's LIGHT_* constants).
LIGHT_TYPE_CODES = {"POINT": 0, "SPOT": 1, "SUN": 2, "AREA": 3}


def light_params(light) -> tuple[float, float, float, float]:
    """(type code, cos half spot angle, 1 / ((1 − cos) spot_blend) or −1 for a hard edge, intensity
    scale): the ``params`` of light_emission.glsl (scale: point/spot P/4π, area P/π, sun S)."""
    code = LIGHT_TYPE_CODES[light.type]
    cos_half, smooth = 0.0, 0.0
    if light.type in ("POINT", "SPOT"):
        scale = light.power / (4.0 * math.pi)
    elif light.type == "AREA":
        scale = light.power / math.pi
    else:
        scale = light.power
    if light.type == "SPOT":
        cos_half = math.cos(0.5 * light.spot_size)
        denominator = (1.0 - cos_half) * light.spot_blend
        smooth = 1.0 / denominator if denominator > 0.0 else -1.0
    return float(code), float(cos_half), float(smooth), float(scale)


def light_smoothstep(x):
    """Cycles' smoothstepf: 0 for x <= 0, 1 for x >= 1, 3x² − 2x³ between."""
    x = np.clip(f64(x), 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def spot_attenuation(cos_axis, spot_size: float, spot_blend: float):
    """Blender's spot cone (Cycles ``kernel/light/spot.h`` ``spot_light_attenuation``):

    light_smoothstep((cos θ − cos(spot_size/2)) / ((1 − cos(spot_size/2)) · spot_blend)), θ the angle off
    the spot axis in the light's local frame (object scale divided out); a hard edge for blend 0.
    """
    cos_axis = f64(cos_axis)
    cos_half = math.cos(0.5 * spot_size)
    if spot_blend <= 0.0:
        return np.where(cos_axis > cos_half, 1.0, 0.0)
    return light_smoothstep((cos_axis - cos_half) / ((1.0 - cos_half) * spot_blend))


def spot_cone_solid_angle(spot_size: float, spot_blend: float, samples: int = 200_001) -> float:
    """∫ spot_attenuation dω over the sphere (numerically, 2π ∫ atten(c) dc by the trapezoid rule)."""
    cos_half = math.cos(0.5 * spot_size)
    c = np.linspace(cos_half, 1.0, samples)
    values = spot_attenuation(c, spot_size, spot_blend)
    return float(2.0 * math.pi * np.sum(0.5 * (values[1:] + values[:-1]) * np.diff(c)))


def light_spot_attenuation(light, directions):
    """The cone of a spot ``light`` for rays leaving it along ``directions`` (..., 3, world): the
    rays in the light's local frame with the object scale divided out (light_emission.glsl's
    light_spot_attenuation)."""
    to_local = np.linalg.inv(f64(light.matrix_world)[:3, :3])
    local = f64(directions) @ to_local.T
    local = local / norm(local)[..., None]
    return spot_attenuation(-local[..., 2], light.spot_size, light.spot_blend)  # lights point down -Z


def light_intensity(light, directions) -> np.ndarray:
    """Intensity per unit light colour (W/sr) of a point, spot or area light towards ``directions``
    (..., 3, unit, leaving the light); for a sun the irradiance S (W/m²), whatever the direction
    (light_emission.glsl's light_intensity)."""
    directions = f64(directions)
    intensity = np.full(directions.shape[:-1], light_params(light)[3])
    if light.type == "SPOT":
        intensity = intensity * light_spot_attenuation(light, directions)
    elif light.type == "AREA":
        axis = f64(light.direction)
        intensity = intensity * np.maximum(directions @ (axis / np.linalg.norm(axis)), 0.0)
    return intensity
