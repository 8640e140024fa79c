# SPDX-License-Identifier: GPL-3.0-or-later
"""Float64 twin of ``glsl/direct_light/light_at_surface.glsl`` and of the direct-light pass's shading
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
from .lights import light_params, radiant_intensity

MIN_DISTANCE2 = 1e-12


def _f64(x):
    return np.asarray(x, dtype=np.float64)


def light_irradiance(light, positions, normals):
    """(E, incoming): irradiance per unit light colour (W/m²) at ``positions`` (..., 3) with unit
    ``normals``, and the unit directions towards the light."""
    p, n = _f64(positions), _f64(normals)
    axis = _f64(light.direction)
    axis = axis / np.linalg.norm(axis)
    _, _, _, scale = light_params(light)
    if light.type == "SUN":
        incoming = np.broadcast_to(-axis, p.shape).copy()
        return scale * np.maximum(np.sum(n * incoming, axis=-1), 0.0), incoming
    towards = _f64(light.position) - p
    distance2 = np.maximum(np.sum(towards * towards, axis=-1), MIN_DISTANCE2)
    length = np.linalg.norm(towards, axis=-1)
    incoming = np.where(length[..., None] > 0.0, towards / np.where(length > 0.0, length, 1.0)[..., None], n)
    intensity = radiant_intensity(light, -incoming)
    return intensity * np.maximum(np.sum(n * incoming, axis=-1), 0.0) / distance2, incoming


def shade(gbuffer: dict, camera_vector, lights, visibility=None):
    """(diffuse, glossy) direct radiance (h, w, 3) from G-buffer arrays (``GBuffer.to_numpy``
    layout) lit by ``lights``; ``visibility``: optional list of (h, w) arrays per light (1 lit)."""
    position = _f64(gbuffer["position"])
    covered = position[..., 3] > 0.5
    p = position[..., :3]
    n = _f64(gbuffer["normal"])[..., :3]
    rough = _f64(gbuffer["normal"])[..., 3]
    base = _f64(gbuffer["base_color"])[..., :3]
    metallic = _f64(gbuffer["base_color"])[..., 3]
    level = _f64(gbuffer["material"])[..., 0]
    ior = np.where(covered, _f64(gbuffer["material"])[..., 1], 1.5)
    camera = _f64(camera_vector)
    outgoing = camera[:3] - p if camera[3] > 0.5 else np.broadcast_to(camera[:3], p.shape)
    outgoing = outgoing / np.maximum(np.linalg.norm(outgoing, axis=-1, keepdims=True), 1e-300)
    n_safe = np.where(covered[..., None], n, np.array([0.0, 0.0, 1.0]))
    diffuse = np.zeros(p.shape)
    glossy = np.zeros(p.shape)
    for index, light in enumerate(lights):
        e, incoming = light_irradiance(light, p, n_safe)
        if visibility is not None:
            e = e * visibility[index]
        fd, fs = principled.principled_brdf(incoming, outgoing, n_safe, base, rough, metallic, level, ior)
        color = _f64(light.color)
        diffuse += fd * e[..., None] * color * light.diffuse_factor
        glossy += fs * e[..., None] * color * light.specular_factor
    diffuse[~covered] = 0.0
    glossy[~covered] = 0.0
    return diffuse, glossy
