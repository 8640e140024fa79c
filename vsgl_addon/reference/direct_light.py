# SPDX-License-Identifier: GPL-3.0-or-later
"""Float64 twin of ``glsl/direct_light/lights.glsl`` and of the direct-light pass's shading
(:mod:`vsgl_addon.passes.direct_light`), without shadows (a visibility can be passed in).

Blender's lights are the emission model of :mod:`vsgl_addon.reference.lights` (formulas.md §4,
checked against Cycles 5.0 in tests/test_direct_light.py): point and spot lights radiate
P/(4π) W/sr (spot: times Blender's cone), an area light is a Lambertian point emitter
I(θ) = (P/π) cos θ about its −Z axis, a sun puts S W/m² on a surface facing it. The irradiance of a
surface at distance d is E = I cos θ_surface / d² (sun: S cos θ_surface); the reflected radiance is
f E with the Principled BRDF f of :mod:`vsgl_addon.reference.principled`, split into its diffuse
and specular parts.
"""

from __future__ import annotations

import numpy as np

from . import principled
from .lights import light_params, light_intensity
from .numerics import dot, f64, norm, safe_normalize

MIN_DISTANCE2 = 1e-12


def direct_light_irradiance(light, positions, normals):
    """(E, incoming): irradiance per unit light colour (W/m²) at ``positions`` (..., 3) with unit
    ``normals``, and the unit directions towards the light."""
    p, n = f64(positions), f64(normals)
    axis = f64(light.direction)
    axis = axis / np.linalg.norm(axis)
    _, _, _, scale = light_params(light)
    if light.type == "SUN":
        incoming = np.broadcast_to(-axis, p.shape).copy()
        return scale * np.maximum(dot(n, incoming), 0.0), incoming
    towards = f64(light.position) - p
    distance2 = np.maximum(dot(towards, towards), MIN_DISTANCE2)
    length = norm(towards)
    incoming = safe_normalize(towards, n, length)
    intensity = light_intensity(light, -incoming)
    return intensity * np.maximum(dot(n, incoming), 0.0) / distance2, incoming


def shade(gbuffer: dict, camera_vector, lights, visibility=None):
    """(diffuse, glossy) direct radiance (h, w, 3) from G-buffer arrays (``GBuffer.to_numpy``
    layout) lit by ``lights``; ``visibility``: optional list of (h, w) arrays per light (1 lit)."""
    position = f64(gbuffer["position"])
    covered = position[..., 3] > 0.5
    p = position[..., :3]
    n = f64(gbuffer["normal"])[..., :3]
    rough = f64(gbuffer["normal"])[..., 3]
    base = f64(gbuffer["base_color"])[..., :3]
    metallic = f64(gbuffer["base_color"])[..., 3]
    level = f64(gbuffer["material"])[..., 0]
    ior = np.where(covered, f64(gbuffer["material"])[..., 1], 1.5)
    camera = f64(camera_vector)
    outgoing = camera[:3] - p if camera[3] > 0.5 else np.broadcast_to(camera[:3], p.shape)
    outgoing = outgoing / np.maximum(norm(outgoing)[..., None], 1e-300)
    n_safe = np.where(covered[..., None], n, np.array([0.0, 0.0, 1.0]))
    diffuse = np.zeros(p.shape)
    glossy = np.zeros(p.shape)
    for index, light in enumerate(lights):
        e, incoming = direct_light_irradiance(light, p, n_safe)
        if visibility is not None:
            e = e * visibility[index]
        fd, fs = principled.principled_brdf(incoming, outgoing, n_safe, base, rough, metallic, level, ior)
        color = f64(light.color)
        diffuse += fd * e[..., None] * color * light.diffuse_factor
        glossy += fs * e[..., None] * color * light.specular_factor
    diffuse[~covered] = 0.0
    glossy[~covered] = 0.0
    return diffuse, glossy
