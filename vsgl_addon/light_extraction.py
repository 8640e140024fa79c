# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender side of the scene description, lights: a light object -> :class:`Light` in Blender's
units, with its light and shadow linking (Blender 4.3+) resolved to per-object masks.

Power: the light's Power (Strength for a sun) × 2^exposure; with Normalize off, times the emitter's
area (a sphere's 4πr² for point and spot, the object-scaled shape's area, π sin²(angle / 2) for a
sun), each factor checked against Cycles renders in Blender 5.0.1. Lights that emit nothing (zero
power or colour, hidden) are skipped silently; those the passes cannot model (a spot, area or sun
scaled to zero) are skipped with a warning line (UNMODELLED_LIGHTS).

Linking follows Blender's rule: in a linking collection each object (or child collection) is
included or excluded; with any included entry only included objects receive (or block) the light,
with only excluded ones every other object does.
"""

from __future__ import annotations

import math
from dataclasses import replace

import bpy
import numpy as np

from .scene_description import Light

UNMODELLED_SCALE = "scaled to zero"
# Skipped lights worth a warning: what Cycles would render but the add-on cannot (a hidden light, or
# one of zero power or colour, is skipped because it adds nothing).
UNMODELLED_LIGHTS = ("unsupported type", UNMODELLED_SCALE)


# --- light and shadow linking -------------------------------------------------------------------


def _link_states(collection) -> dict:
    """Original object -> "INCLUDE" / "EXCLUDE" for every object in a linking ``collection``: its
    own entries, and the objects of its child collections with the child's state (Blender's
    CollectionLightLinking), the nearest entry winning."""
    # collection_objects / collection_children run parallel to objects / children.
    states = {}
    for child, entry in zip(collection.children, collection.collection_children):
        for obj in child.all_objects:
            states.setdefault(obj.original, entry.light_linking.link_state)
    for obj, entry in zip(collection.objects, collection.collection_objects):
        states[obj.original] = entry.light_linking.link_state
    return states


def _link_mask(collection, instance_originals) -> np.ndarray | None:
    """Per object instance, whether it is in the linking set (Blender's rule: with any included
    object, only included objects are; with only excluded ones, everything else is); None when
    there is no collection."""
    if collection is None:
        return None
    states = _link_states(collection)
    any_included = "INCLUDE" in states.values()

    def state(originals):
        own, instancer = originals
        return states.get(own, states.get(instancer))

    return np.array([(state(o) == "INCLUDE") if any_included else (state(o) != "EXCLUDE")
                     for o in instance_originals], bool)


def linked(light: Light, original, instance_originals) -> Light:
    linking = getattr(original, "light_linking", None)  # Blender 4.3+
    if linking is None:
        return light
    receivers = _link_mask(linking.receiver_collection, instance_originals)
    blockers = _link_mask(linking.blocker_collection, instance_originals)
    if receivers is None and blockers is None:
        return light
    return replace(light, receivers=receivers, blockers=blockers)


def plain_light_tree(tree) -> bool:
    """A light node tree that changes nothing: Emission (white, strength 1, nothing linked into it)
    into Light Output, as Blender 5.2 gives new lights. Anything else is worth a warning."""
    if tree is None:
        return True
    kinds = sorted(node.type for node in tree.nodes)
    if kinds != ["EMISSION", "OUTPUT_LIGHT"]:
        return False
    emission = next(node for node in tree.nodes if node.type == "EMISSION")
    color, strength = emission.inputs["Color"], emission.inputs["Strength"]
    return (not color.is_linked and not strength.is_linked
            and tuple(color.default_value)[:3] == (1.0, 1.0, 1.0) and strength.default_value == 1.0)


# --- lights -------------------------------------------------------------------------------------


def read_light(obj: bpy.types.Object, matrix: np.ndarray) -> tuple[Light | None, str]:
    light = obj.data
    kind = light.type
    if kind not in ("POINT", "SPOT", "SUN", "AREA"):
        return None, "unsupported type"
    color = np.array(light.color[:3], np.float64)
    if light.use_temperature:
        color *= np.array(light.temperature_color[:3], np.float64)
    radius = float(getattr(light, "shadow_soft_size", 0.0))
    size = np.zeros(2)
    shape = ""
    sun_angle = 0.0
    # Normalize on, the emission is divided by the emitter's area so that Power is the total;
    # off, the light emits that area times more: a sphere's 4 pi r^2 for point and spot, the
    # (object-scaled) shape's area, pi sin^2(angle / 2) for a sun. Each factor was checked
    # against Cycles renders in Blender 5.0.1; with no area (radius or angle 0) nothing changes.
    emitter_area = 0.0
    if kind == "AREA":
        shape = light.shape
        scale = np.linalg.norm(matrix[:3, :2], axis=0)
        size_y = light.size_y if shape in ("RECTANGLE", "ELLIPSE") else light.size
        size = np.array([light.size * scale[0], size_y * scale[1]])
        emitter_area = size[0] * size[1] * (math.pi / 4.0 if shape in ("DISK", "ELLIPSE") else 1.0)
    elif kind == "SUN":
        sun_angle = float(light.angle)
        emitter_area = math.pi * math.sin(sun_angle / 2.0) ** 2
    else:
        emitter_area = 4.0 * math.pi * radius * radius
    power = float(light.energy) * 2.0 ** float(light.exposure)
    if not light.normalize and emitter_area > 0.0:
        power *= emitter_area
    if power <= 0.0:
        return None, "zero power"
    if color.max() <= 0.0:
        return None, "zero colour"
    linear = matrix[:3, :3]
    singular = not abs(np.linalg.det(linear)) > 1e-12 * max(np.abs(linear).max(), 1e-100) ** 3
    if singular and kind != "POINT":
        # A spot's cone, an area's plane and a sun's direction are the object's axes; scaled to
        # zero they do not exist (a point light has none: it stays).
        return None, UNMODELLED_SCALE
    direction = -matrix[:3, 2]
    length = np.linalg.norm(direction)
    direction = direction / length if length > 0.0 else np.array([0.0, 0.0, -1.0])
    if singular:
        matrix = matrix.copy()
        matrix[:3, :3] = np.eye(3)
    return (
        Light(
            name=obj.name,
            type=kind,
            matrix_world=matrix,
            position=matrix[:3, 3].copy(),
            direction=direction,
            color=color,
            power=power,
            energy=float(light.energy),
            exposure=float(light.exposure),
            normalize=bool(light.normalize),
            radius=radius,
            spot_size=float(light.spot_size) if kind == "SPOT" else 0.0,
            spot_blend=float(light.spot_blend) if kind == "SPOT" else 0.0,
            sun_angle=sun_angle,
            shape=shape,
            size=size,
            # Blender's Diffuse / Specular factors of the light, and the light object's diffuse and
            # glossy ray visibility, which is how Cycles (which ignores the factors) drops the same
            # contributions: both scale the light's diffuse and glossy reflection.
            diffuse_factor=float(light.diffuse_factor) * float(bool(getattr(obj, "visible_diffuse", True))),
            specular_factor=float(light.specular_factor) * float(bool(getattr(obj, "visible_glossy", True))),
        ),
        "",
    )
