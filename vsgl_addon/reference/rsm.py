# SPDX-License-Identifier: GPL-3.0-or-later
"""Float64 twin of the RSM texel quantities (formulas.md §4; 000 §4): what ``glsl/rsm/rsm.frag.glsl``
computes per texel, given the texel's ray, position, normal and material.

Used by the tests of :mod:`vsgl_addon.passes.rsm` and by anything that needs the light model of the
RSM without a GPU. Blender's units throughout (formulas.md §4):

* point light of power P: radiant intensity P / (4π) W/sr in every direction;
* spot light: the same, times Blender's cone attenuation (:func:`spot_attenuation`);
* sun of strength S: irradiance S W/m² on a surface facing it; a texel's flux is S times the
  texel's area on the sun's plane (orthographic view);
* area light of power P: a Lambertian point emitter, I(θ) = (P/π) cos θ about its -Z axis (the
  emitter's size and shape, and the spread, are not modelled: "small area light").

A texel's flux is Φ = I(ω) dω: the intensity towards the texel centre times the texel's solid angle
dω = ∫ cos³ dA over the texel's area on the image plane at distance 1 (:func:`texel_solid_angles`;
the midpoint rule, area × cos³ at the centre, would be off by 1 % in the corner texels of a 16²
cube face, so the GPU integrates it exactly: see ``glsl/rsm/rsm.frag.glsl`` texel_solid_angle).

Reflectances of the Principled BSDF's base layer (:func:`principled_reflectances`):

* Rd = base colour × (1 − metallic);
* Rs = lerp(F0_dielectric, base colour, metallic), the reflectance at normal incidence, with
  F0_dielectric = ((ior − 1)/(ior + 1))² × 2 × specular_ior_level clamped to [0, 1] — Blender's own
  adjustment (Cycles ``kernel/svm/closure.h``, Principled BSDF: ``f0 = F0_from_ior(ior);
  f0 *= 2 * specular_ior_level``; EEVEE's ``gpu_shader_material_principled.glsl`` the same; the
  Specular Tint is taken as white) — and the metallic layer's F0 = base colour (Cycles' F82-tint
  Schlick Fresnel starts at the base colour). Blender's diffuse is further reduced by the
  dielectric layer's albedo and its specular by the GGX directional albedo; neither is modelled
  here. Calibration of Rd and Rs against Cycles' Diffuse/Glossy Color passes comes in a later issue.

The specular lobe of a texel is 000 Eq. 7's spherical warp (``sg.specular_lobe_warp``) for the
incoming direction ω' (towards the light) with GGX α = max(roughness², ALPHA_MIN).
"""

from __future__ import annotations

import math

import numpy as np

from .sg import specular_lobe_warp

#: Smallest GGX α = roughness² (roughness 1e-3): keeps λ_h = 2/α² finite for roughness 0.
ALPHA_MIN = 1e-6


def _f64(x):
    return np.asarray(x, dtype=np.float64)


def smoothstep(x):
    """Cycles' smoothstepf: 0 for x <= 0, 1 for x >= 1, 3x² − 2x³ between."""
    x = np.clip(_f64(x), 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def spot_attenuation(cos_axis, spot_size: float, spot_blend: float):
    """Blender's spot cone (Cycles ``kernel/light/spot.h`` ``spot_light_attenuation``):

    smoothstep((cos θ − cos(spot_size/2)) / ((1 − cos(spot_size/2)) · spot_blend)), θ the angle off
    the spot axis in the light's local frame (object scale divided out); a hard edge for blend 0.
    """
    cos_axis = _f64(cos_axis)
    cos_half = math.cos(0.5 * spot_size)
    if spot_blend <= 0.0:
        return np.where(cos_axis > cos_half, 1.0, 0.0)
    return smoothstep((cos_axis - cos_half) / ((1.0 - cos_half) * spot_blend))


def spot_cone_solid_angle(spot_size: float, spot_blend: float, samples: int = 200_001) -> float:
    """∫ spot_attenuation dω over the sphere (numerically, 2π ∫ atten(c) dc by the trapezoid rule)."""
    cos_half = math.cos(0.5 * spot_size)
    c = np.linspace(cos_half, 1.0, samples)
    values = spot_attenuation(c, spot_size, spot_blend)
    return float(2.0 * math.pi * np.sum(0.5 * (values[1:] + values[:-1]) * np.diff(c)))


def principled_reflectances(base_color, metallic, specular_ior_level, ior):
    """(Rd, Rs) of a Principled BSDF's base layer, RGB (see the module documentation)."""
    base_color = np.maximum(_f64(base_color), 0.0)  # a float image may hold negative values
    metallic = np.clip(_f64(metallic), 0.0, 1.0)[..., None]
    ratio = (_f64(ior) - 1.0) / (_f64(ior) + 1.0)
    f0 = np.clip(ratio * ratio * 2.0 * np.maximum(_f64(specular_ior_level), 0.0), 0.0, 1.0)[..., None]
    diffuse = base_color * (1.0 - metallic)
    specular = f0 * (1.0 - metallic) + base_color * metallic
    return diffuse, specular


def texel_solid_angles(size: int, half_extent) -> np.ndarray:
    """(size, size) exact solid angles of the texels of a perspective view whose image plane at
    distance 1 spans [−hx, hx] × [−hy, hy] (row 0 = bottom, as the GPU's texture rows).

    Closed form per texel: the solid angle of [0, x] × [0, y] at distance 1 is
    atan(xy / √(1 + x² + y²)); a texel is four such corners. (The GPU takes this form up to 8²
    texels and 3×3 Gauss-Legendre on cos³ beyond, within 2e-6 of it.)
    """
    hx, hy = (float(v) for v in half_extent)
    edges = np.linspace(-1.0, 1.0, size + 1)
    x = edges[None, :] * hx
    y = edges[:, None] * hy
    corner = np.arctan(x * y / np.sqrt(1.0 + x * x + y * y))
    return corner[1:, 1:] - corner[1:, :-1] - corner[:-1, 1:] + corner[:-1, :-1]


def texel_rays(size: int, half_extent, view_to_world) -> np.ndarray:
    """(size, size, 3) unit world directions from the light through the texel centres."""
    hx, hy = (float(v) for v in half_extent)
    centres = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    u, v = np.meshgrid(centres * hx, centres * hy)
    local = np.stack([u, v, -np.ones_like(u)], axis=-1)
    local /= np.linalg.norm(local, axis=-1, keepdims=True)
    return local @ _f64(view_to_world)[:3, :3].T


def radiant_intensity(light, directions) -> np.ndarray:
    """Intensity per unit light colour (W/sr) of a point, spot or area light towards ``directions``
    (..., 3, unit, from the light); for a sun the irradiance S (W/m²), whatever the direction."""
    directions = _f64(directions)
    shape = directions.shape[:-1]
    if light.type == "SUN":
        return np.full(shape, float(light.power))
    if light.type == "POINT":
        return np.full(shape, light.power / (4.0 * math.pi))
    if light.type == "SPOT":
        to_local = np.linalg.inv(_f64(light.matrix_world)[:3, :3])
        local = directions @ to_local.T
        local /= np.linalg.norm(local, axis=-1, keepdims=True)
        return light.power / (4.0 * math.pi) * spot_attenuation(-local[..., 2], light.spot_size,
                                                                light.spot_blend)
    if light.type == "AREA":
        axis = _f64(light.direction)
        return light.power / math.pi * np.maximum(directions @ axis, 0.0)
    raise ValueError(f"unknown light type {light.type!r}")


def incoming_directions(light, positions) -> np.ndarray:
    """ω' per texel (..., 3): unit, from the surface towards the light (a sun: −its direction)."""
    positions = _f64(positions)
    if light.type == "SUN":
        return np.broadcast_to(-_f64(light.direction), positions.shape).copy()
    towards = _f64(light.position) - positions
    return towards / np.linalg.norm(towards, axis=-1, keepdims=True)


def specular_lobes(incoming, normal, roughness):
    """(ξs, λs) of the texels: 000 Eq. 7's warp with α = max(roughness², ALPHA_MIN)."""
    alpha = np.maximum(_f64(roughness) ** 2, ALPHA_MIN)
    return specular_lobe_warp(incoming, normal, alpha)
