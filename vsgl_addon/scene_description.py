# SPDX-License-Identifier: GPL-3.0-or-later
"""The plain scene description the GPU passes consume: numpy arrays and Python scalars, no bpy.

Built from Blender's evaluated depsgraph by :mod:`vsgl_addon.scene_extraction`; the passes (and
their float64 numpy references) only ever see these classes, so they can be tested and run
without Blender. Importing this module must never import ``bpy``.

Units are Blender's (formulas.md sec. 4): lengths in metres of world space, light power in watts
(sun: irradiance in W/m^2), colours in Blender's scene-linear RGB. Geometry is float32 because the
GPU consumes float32 and a 100k-triangle scene stays at a few MB; matrices are float64 because
they are few and the camera tests compare them against Blender's own to 1e-6.

The world (environment) light is ignored for now: only lamps light the RSMs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import views

LIGHT_TYPES = ("POINT", "SPOT", "SUN", "AREA")
AREA_SHAPES = ("SQUARE", "RECTANGLE", "DISK", "ELLIPSE")

#: Channels of :meth:`SceneDescription.light_links` per (light, object): does the object receive
#: the light (light linking), block it (shadow linking and the object's shadow-ray visibility),
#: and is it seen by diffuse and by glossy rays (its bounce reaches receivers' diffuse / glossy lobes).
LINK_RECEIVES, LINK_BLOCKS, LINK_VISIBLE_DIFFUSE, LINK_VISIBLE_GLOSSY = range(4)
#: The receivers' lobes a set of VSGLs lights (which objects' bounce it carries, by ray visibility).
RECEIVER_LOBES = ("all", "diffuse", "glossy")


@dataclass(frozen=True)
class Geometry:
    """All render-visible triangles of the scene, in world space, modifiers and instances applied.

    T triangles, three corners each, in the winding that makes the geometric normal
    ``cross(p1 - p0, p2 - p0)`` point to the side Blender calls front (mirroring transforms are
    undone by swapping corners 1 and 2).
    """

    positions: np.ndarray  # (T, 3, 3) float32, metres, world space
    normals: np.ndarray  # (T, 3, 3) float32, unit, world space: Blender's corner (shading) normals
    uvs: np.ndarray  # (T, 3, 2) float32, the active render UV map; zeros where a mesh has none
    material_index: np.ndarray  # (T,) int32, into SceneDescription.materials
    object_index: np.ndarray  # (T,) int32, into SceneDescription.object_names (one per instance)

    @property
    def triangle_count(self) -> int:
        return int(self.positions.shape[0])

    @staticmethod
    def empty() -> "Geometry":
        return Geometry(
            positions=np.zeros((0, 3, 3), np.float32),
            normals=np.zeros((0, 3, 3), np.float32),
            uvs=np.zeros((0, 3, 2), np.float32),
            material_index=np.zeros(0, np.int32),
            object_index=np.zeros(0, np.int32),
        )


@dataclass(frozen=True)
class Material:
    """What the passes know of a surface: a Principled BSDF's base layer (formulas.md sec. 4).

    ``approximated`` is True when the extraction could not read the material exactly;
    ``approximation`` then says what was replaced by what, for the user's warning line.
    """

    name: str
    base_color: np.ndarray  # (3,) float32, scene-linear RGB; ignored where base_color_image is set
    roughness: float  # Principled "Roughness" (perceptual; GGX alpha = roughness^2)
    metallic: float
    specular_ior_level: float  # Principled "Specular IOR Level", 0.5 = the IOR's own reflectance
    ior: float
    # (H, W, 4) float32 scene-linear RGBA, row 0 at the bottom (Blender's order, v = 0), sampled with
    # the triangle UVs, repeat extension; None when the base colour is a constant.
    base_color_image: np.ndarray | None = None
    base_color_image_name: str = ""
    approximated: bool = False
    approximation: str = ""


# The material of triangles whose object has no material: Blender's own default surface
# (Principled defaults: Base Color 0.8 grey, Roughness 0.5, IOR 1.5).
DEFAULT_MATERIAL = Material(
    name="<default>",
    base_color=np.array([0.8, 0.8, 0.8], np.float32),
    roughness=0.5,
    metallic=0.0,
    specular_ior_level=0.5,
    ior=1.5,
)


@dataclass(frozen=True)
class Light:
    """One lamp that emits light, in Blender's units (formulas.md sec. 4).

    ``power`` already includes the light's exposure (x 2^exposure) and, when Normalize is off, the
    emitter's area (point and spot 4 pi r^2, area lights their world-space area, sun
    pi sin^2(angle / 2)), as Cycles renders them; ``color`` includes the
    temperature tint. So the emitted flux in watts per colour channel is ``power * color`` for
    point, spot and area lights, and a sun's irradiance on a facing surface is ``power * color``.
    """

    name: str
    type: str  # one of LIGHT_TYPES
    matrix_world: np.ndarray  # (4, 4) float64, the instance's world matrix
    position: np.ndarray  # (3,) float64, metres
    direction: np.ndarray  # (3,) float64, unit: where the light points (its local -Z)
    color: np.ndarray  # (3,) float64, scene-linear RGB (color x temperature colour when used)
    power: float  # W (point, spot, area); W/m^2 (sun); > 0 always (others are skipped)
    energy: float  # the light's Power / Strength field as the user typed it
    exposure: float
    normalize: bool
    radius: float  # shadow_soft_size, metres (point and spot: sphere radius; sun: unused)
    spot_size: float  # full cone angle, radians (spot only, else 0)
    spot_blend: float  # smooth edge fraction 0..1 (spot only, else 0)
    sun_angle: float  # angular diameter, radians (sun only, else 0)
    shape: str  # area shape, one of AREA_SHAPES (area only, else "")
    size: np.ndarray  # (2,) float64, area width/height in metres, object scale applied (else 0)
    diffuse_factor: float  # Blender's multipliers of the light for diffuse and glossy reflection
    specular_factor: float
    # Light linking: (O,) bool per object of SceneDescription.object_names, True where the object
    # receives this light; None: every object does. Shadow linking likewise for the objects that
    # block it (before the objects' own shadow-ray visibility).
    receivers: np.ndarray | None = None
    blockers: np.ndarray | None = None

    @property
    def flux(self) -> np.ndarray:
        """Emitted flux per channel, W (sun: irradiance, W/m^2)."""
        return self.power * self.color

    @property
    def radiant_intensity(self) -> np.ndarray:
        """On-axis radiant intensity per channel, W/sr (point, spot: P/4pi; area: P/pi)."""
        if self.type in ("POINT", "SPOT"):
            return self.flux / (4.0 * math.pi)
        if self.type == "AREA":
            return self.flux / math.pi
        raise ValueError("a sun has no radiant intensity, only an irradiance (power)")


@dataclass(frozen=True)
class SkippedLight:
    name: str
    reason: str  # "zero power", "zero colour", "hidden from render", "unsupported type"


@dataclass(frozen=True)
class Camera:
    """The scene camera as Blender renders it, enough to rebuild its view and projection matrices."""

    name: str
    matrix_world: np.ndarray  # (4, 4) float64; camera looks down its local -Z, +Y up
    type: str  # "PERSP" or "ORTHO" (a panoramic camera becomes PERSP, with a warning)
    lens: float  # focal length, mm
    sensor_width: float  # mm
    sensor_height: float  # mm
    sensor_fit: str  # "AUTO", "HORIZONTAL" or "VERTICAL"
    ortho_scale: float  # metres across the fitted side
    shift_x: float  # fractions of the fitted side
    shift_y: float
    clip_start: float  # metres
    clip_end: float
    resolution: tuple[int, int]  # pixels, render resolution x percentage
    pixel_aspect: tuple[float, float]

    @property
    def aspect(self) -> float:
        """Width / height of the rendered image (pixel aspect applied)."""
        return (self.resolution[0] * self.pixel_aspect[0]) / (self.resolution[1] * self.pixel_aspect[1])

    def view_matrix(self) -> np.ndarray:
        """(4, 4) float64 world -> camera space (:func:`vsgl_addon.views.camera_view_matrix`)."""
        return views.camera_view_matrix(self.matrix_world)

    def viewplane(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) of the view plane at clip_start (PERSP) or in metres (ORTHO),
        as Blender computes it (:func:`vsgl_addon.views.camera_viewplane`)."""
        return views.camera_viewplane(self)

    def projection_matrix(self) -> np.ndarray:
        """(4, 4) float64 OpenGL-style projection, as Camera.calc_matrix_camera
        (:func:`vsgl_addon.views.camera_projection_matrix`)."""
        return views.camera_projection_matrix(self)


@dataclass(frozen=True)
class SceneDescription:
    geometry: Geometry
    materials: tuple[Material, ...]  # index 0 is always DEFAULT_MATERIAL
    lights: tuple[Light, ...]  # only lights that emit: power > 0, colour > 0, render-visible
    camera: Camera | None  # None when the scene has no camera
    object_names: tuple[str, ...]  # per object instance (Geometry.object_index)
    skipped_lights: tuple[SkippedLight, ...] = ()
    # One line per kind of problem, for the UI (e.g. "VSGL: approximated materials (...): A, B").
    warnings: tuple[str, ...] = field(default_factory=tuple)
    # Ray visibility per object (O, 3) bool: seen by diffuse rays, by glossy rays, casts shadows
    # (Blender's Object.visible_diffuse / visible_glossy / visible_shadow); None: all True.
    object_visibility: np.ndarray | None = None
    # Per object name, where not "auto": whether its planar regions become rectangle proxies
    # (settings.PROXY_OVERRIDES names; vsgl_addon/proxies.py). None: every object is "auto".
    proxy_overrides: dict | None = None

    def visibility(self) -> np.ndarray:
        """(O, 3) bool: diffuse, glossy, shadow visibility of every object (all True by default)."""
        if self.object_visibility is None:
            return np.ones((len(self.object_names), 3), bool)
        return np.asarray(self.object_visibility, bool).reshape(len(self.object_names), 3)

    @property
    def uses_light_links(self) -> bool:
        """Whether any light or object departs from 'everything receives, blocks and is seen'."""
        return bool(any(light.receivers is not None or light.blockers is not None for light in self.lights)
                    or not self.visibility().all())

    @property
    def receiver_lobe_split(self) -> bool:
        """Whether some object is hidden from diffuse or from glossy rays, so that the receivers'
        diffuse and glossy lobes see different reflectors (two sets of VSGLs, one per lobe)."""
        visibility = self.visibility()
        return bool(not visibility[:, :2].all())

    def light_links(self) -> np.ndarray:
        """(L, O, 4) float32, the LINK_* channels per light and object (1 or 0)."""
        visibility = self.visibility()
        table = np.zeros((len(self.lights), len(self.object_names), 4), np.float32)
        for index, light in enumerate(self.lights):
            receives = np.ones(len(self.object_names), bool) if light.receivers is None else light.receivers
            blocks = np.ones(len(self.object_names), bool) if light.blockers is None else light.blockers
            table[index, :, LINK_RECEIVES] = receives
            table[index, :, LINK_BLOCKS] = blocks & visibility[:, 2]
            table[index, :, LINK_VISIBLE_DIFFUSE] = visibility[:, 0]
            table[index, :, LINK_VISIBLE_GLOSSY] = visibility[:, 1]
        return table

    @property
    def approximated_materials(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.materials if m.approximated)
