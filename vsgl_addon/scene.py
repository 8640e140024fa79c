# SPDX-License-Identifier: GPL-3.0-or-later
"""The scene as the passes see it: :func:`extract_scene` (needs bpy) and the plain classes (do not).

Data flows one way: Blender's evaluated depsgraph -> :class:`SceneDescription` (numpy arrays,
no bpy objects) -> GPU passes. Importing this module does not import ``bpy``; only calling
:func:`extract_scene` does, so the passes and their numpy references stay Blender-free.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .scene_description import (
    AREA_SHAPES,
    DEFAULT_MATERIAL,
    LIGHT_TYPES,
    Camera,
    Geometry,
    Light,
    Material,
    SceneDescription,
    SkippedLight,
)

if TYPE_CHECKING:
    import bpy

__all__ = [
    "AREA_SHAPES",
    "DEFAULT_MATERIAL",
    "LIGHT_TYPES",
    "Camera",
    "Geometry",
    "Light",
    "Material",
    "SceneDescription",
    "SkippedLight",
    "extract_scene",
]


def extract_scene(depsgraph: "bpy.types.Depsgraph") -> SceneDescription:
    """The plain description of what ``depsgraph`` renders (see :mod:`vsgl_addon.scene_extraction`)."""
    from .scene_extraction import extract_scene as _extract

    return _extract(depsgraph)
