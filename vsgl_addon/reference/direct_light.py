# SPDX-License-Identifier: GPL-3.0-or-later
"""Float64 twin of ``glsl/direct_light/light_at_surface.glsl``, of the direct-light pass's shading
(:mod:`vsgl_addon.passes.direct_light`; :func:`shade` takes a visibility, it casts no shadows) and
of the shadow-map lookups of ``glsl/lib/shadow.glsl``.

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


# --- Shadow-map lookups: the twin of glsl/lib/shadow.glsl (same names) -------------------------

#: Largest tan of the incidence angle the slope-scaled bias follows (shadow.glsl's SHADOW_MAX_SLOPE).
SHADOW_MAX_SLOPE = 8.0


def shadow_linear_depth(window_depth, projection):
    """Linear depth along a view's axis from window depth [0, 1]; ``projection`` (..., 4) is
    (perspective 1 / orthographic 0, P00, P22, P23) of the view's OpenGL projection P."""
    ndc = f64(window_depth) * 2.0 - 1.0
    projection = f64(projection)
    with np.errstate(divide="ignore", invalid="ignore"):
        perspective = projection[..., 3] / (ndc + projection[..., 2])  # d = P23 / (ndc + P22)
        orthographic = (projection[..., 3] - ndc) / projection[..., 2]  # d = (P23 - ndc) / P22
    return np.where(projection[..., 0] > 0.5, perspective, orthographic)


def shadow_tan_incidence(normals, incoming):
    """tan of the angle between unit ``normals`` and unit directions ``incoming`` (..., 3)."""
    cos_theta = np.clip(np.sum(f64(normals) * f64(incoming), axis=-1), 0.0, 1.0)
    return np.sqrt(np.maximum(1.0 - cos_theta * cos_theta, 0.0)) / np.maximum(cos_theta, 1e-3)


def shadow_map_lookup(view_projection, projection, size, normal_offset, depth_bias, tan_theta,
                      positions, normals):
    """Where ``positions`` (..., 3) with unit ``normals`` fall in one view of side ``size`` texels:
    (inside, texel, at, receiver, bias). ``inside``: the point lies in the view's frustum; ``texel``
    (..., 2) int (x, y): the texel of the point pushed along its normal by ``normal_offset`` texels
    of the view's footprint; ``at`` (..., 2): that point's continuous coordinate in texels (texel
    centres at integer + 0.5), the input of the bilinear PCF; ``receiver``: its linear depth;
    ``bias``: ``depth_bias`` texels × (1 + tan θ), tan θ capped at SHADOW_MAX_SLOPE. Outside points
    give texel 0 and zeros."""
    matrix = f64(view_projection)
    p, n = f64(positions), f64(normals)
    clip = np.concatenate([p, np.ones(p.shape[:-1] + (1,))], axis=-1) @ matrix.T
    w = clip[..., 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        ndc = clip[..., :3] / w[..., None]
    inside = (w > 0.0) & ~np.any(np.abs(ndc) > 1.0, axis=-1)
    projection = f64(projection)
    texel_world = 2.0 * w / (projection[..., 1] * size)
    offset = p + n * (normal_offset * texel_world)[..., None]
    offset_clip = np.concatenate([offset, np.ones(p.shape[:-1] + (1,))], axis=-1) @ matrix.T
    offset_ndc = offset_clip[..., :3] / np.maximum(offset_clip[..., 3:4], 1e-30)
    at = np.where(inside[..., None], (offset_ndc[..., :2] * 0.5 + 0.5) * size, 0.0)
    cell = np.floor(np.clip(at, -1.0, size))
    texel = np.clip(cell, 0, int(size) - 1).astype(np.int64)
    receiver = shadow_linear_depth(offset_ndc[..., 2] * 0.5 + 0.5, projection)
    bias = depth_bias * texel_world * (1.0 + np.minimum(f64(tan_theta), SHADOW_MAX_SLOPE))
    texel[~inside] = 0
    return inside, texel, at, np.where(inside, receiver, 0.0), np.where(inside, bias, 0.0)


def shadow_map_test(stored, projection, receiver, bias):
    """1 where nothing the view stored (window depth ``stored``, 1 = nothing) lies in front of the
    receiver beyond the bias, 0 in shadow."""
    stored = f64(stored)
    occluder = shadow_linear_depth(stored, projection)
    lit = (stored >= 1.0) | (f64(receiver) <= occluder + f64(bias))
    return lit.astype(np.float64)


def shadow_pcf_first(at):
    """Bilinear percentage-closer filtering (PCF; Reeves, Salesin and Cook 1987): (first, fraction)
    of the 2×2 texels whose centres surround ``at`` (..., 2): ``first`` (..., 2) int the lower-left
    tap (the others +x, +y, +xy; the caller clamps each to the map), ``fraction`` (..., 2) the
    bilinear weights' (x, y)."""
    corner = np.floor(f64(at) - 0.5)
    return corner.astype(np.int64), (f64(at) - 0.5) - corner


def shadow_map_test_bilinear(stored, fraction, projection, receiver, bias):
    """The bilinear PCF of the four taps' stored window depths ``stored`` (..., 4; order first, +x,
    +y, +xy), each tested by :func:`shadow_map_test` against the one receiver depth: 0 or 1 inside a
    shadowed or lit region, a ramp one texel wide across a shadow edge."""
    stored, fraction = f64(stored), f64(fraction)
    lit = [shadow_map_test(stored[..., k], projection, receiver, bias) for k in range(4)]
    fx, fy = fraction[..., 0], fraction[..., 1]
    return ((lit[0] * (1.0 - fx) + lit[1] * fx) * (1.0 - fy)
            + (lit[2] * (1.0 - fx) + lit[3] * fx) * fy)


def shadow_visibility(depth, view_projection, projection, normal_offset, depth_bias, tan_theta,
                      positions, normals):
    """One view's filtered visibility of ``positions`` (direct_light/light_visibility.glsl's
    per-view step): the lookup, the bilinear PCF's four taps of ``depth`` (size, size) window depths
    ([row y, column x]) clamped to the map, and their test; NaN where the point lies outside the
    view."""
    depth = f64(depth)
    size = depth.shape[0]
    inside, _, at, receiver, bias = shadow_map_lookup(view_projection, projection, size, normal_offset,
                                                      depth_bias, tan_theta, positions, normals)
    first, fraction = shadow_pcf_first(at)
    taps = [np.clip(first + np.array(offset), 0, size - 1) for offset in ((0, 0), (1, 0), (0, 1), (1, 1))]
    stored = np.stack([depth[tap[..., 1], tap[..., 0]] for tap in taps], axis=-1)
    lit = shadow_map_test_bilinear(stored, fraction, projection, receiver, bias)
    return np.where(inside, lit, np.nan)


def direct_light_visibility(views, positions, normals, incoming, normal_offset, depth_bias):
    """A light's filtered shadow at ``positions`` (direct_light/light_visibility.glsl): ``views`` a
    list of (depth (size, size) window depths [row y, column x], view_projection (4, 4), projection
    (4,) as :func:`shadow_map_lookup`'s), the first view whose frustum contains the point deciding;
    0 where none does. ``incoming``: unit directions towards the light (the slope-scaled bias's)."""
    positions = f64(positions)
    tan_theta = shadow_tan_incidence(normals, incoming)
    result = np.zeros(positions.shape[:-1])
    decided = np.zeros(positions.shape[:-1], bool)
    for depth, view_projection, projection in views:
        lit = shadow_visibility(depth, view_projection, projection, normal_offset, depth_bias, tan_theta,
                                positions, normals)
        take = ~decided & ~np.isnan(lit)
        result[take] = lit[take]
        decided |= take
    return result
