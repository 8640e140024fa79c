# SPDX-License-Identifier: GPL-3.0-or-later
"""Which techniques a scene needs, by the light-path table (../shared/reference/light-paths.md).
Plain numpy on the scene description, no bpy, no GPU: the renderer and a frame planner ask the same
function, so a pass that owns no cell of a scene's table is never run and costs nothing.

The glossy VPL pass (004) owns "specular lobe of a sharp reflector (GGX α < α_c) -> diffuse
receiver". It is needed when some light can reach such a reflector: a triangle of a material with
α (reference.principled.principled_alpha, as the RSM's split
and the VPLs test it) below ``caustic_roughness`` and a specular lobe (metallic, or a dielectric with a
Specular IOR Level above 0 and an IOR other than 1), whose object is seen by diffuse rays (its bounce
reaches receivers' diffuse lobes) and receives a light with a glossy factor above 0 that can reach
it (inside a spot's cone, in front of an area light). The test ignores shadows: the RSM decides
those, and a reflector in shadow then gives no VPL.
"""

from __future__ import annotations

import math

import numpy as np

from .reference.principled import principled_alpha


def _sharp_materials(scene, caustic_roughness: float) -> np.ndarray:
    """(M,) bool: the materials whose specular lobe is sharp (α < α_c) and reflects anything."""
    sharp = []
    for material in scene.materials:
        reflects = material.metallic > 0.0 or (material.specular_ior_level > 0.0 and material.ior != 1.0)
        sharp.append(bool(principled_alpha(material.roughness) < caustic_roughness) and reflects)
    return np.array(sharp, bool)


def _reaches(light, corners: np.ndarray) -> np.ndarray:
    """(T,) bool: the light can reach the triangles (T, 3, 3) (shadows aside). Conservative: a spot
    reaches a triangle whose bounding sphere meets its cone; an area light one with a corner in front."""
    if light.type == "SUN" or light.type == "POINT":
        return np.ones(len(corners), bool)
    axis = np.asarray(light.direction, np.float64)
    axis = axis / max(np.linalg.norm(axis), 1e-30)
    offsets = corners.astype(np.float64) - np.asarray(light.position, np.float64)
    if light.type == "AREA":
        return (offsets @ axis > 0.0).any(axis=1)
    centre = offsets.mean(axis=1)
    radius = np.linalg.norm(offsets - centre[:, None, :], axis=-1).max(axis=1)
    distance = np.linalg.norm(centre, axis=-1)
    cosine = np.clip((centre @ axis) / np.maximum(distance, 1e-30), -1.0, 1.0)
    spread = np.arcsin(np.clip(radius / np.maximum(distance, 1e-30), 0.0, 1.0))
    inside_sphere = distance <= radius
    return inside_sphere | (np.arccos(cosine) - spread <= 0.5 * light.spot_size)


def needs_glossy_vpls(scene, settings) -> bool:
    """Whether the glossy VPL pass runs for ``scene`` (a SceneDescription) with ``settings``
    (VSGLSettings: ``caustics`` on and its ``caustic_roughness``): some lit sharp specular reflector
    exists (see the module documentation). False hands the cell to the VSGLs (light-paths.md)."""
    if not settings.caustics or not scene.lights or scene.geometry.triangle_count == 0:
        return False
    sharp = _sharp_materials(scene, settings.caustic_roughness)
    geometry = scene.geometry
    candidates = sharp[geometry.material_index]
    candidates &= scene.visibility()[geometry.object_index, 0]
    if not candidates.any():
        return False
    corners = geometry.positions[candidates]
    objects = geometry.object_index[candidates]
    for light in scene.lights:
        if not (light.specular_factor > 0.0 and math.isfinite(light.power) and light.power > 0.0):
            continue
        receives = np.ones(len(objects), bool) if light.receivers is None else np.asarray(light.receivers)[objects]
        if (receives & _reaches(light, corners)).any():
            return True
    return False
