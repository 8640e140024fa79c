# SPDX-License-Identifier: GPL-3.0-or-later
"""Small test scenes built in the bpy module: geometry, materials, lights and a camera.

Everything is made through ``bpy.data`` (no operators), so a builder works in any context and
on any scene, not just the context's. Each builder links what it makes into ``scene``'s master
collection (default: the context scene) or into ``collection`` when given, and returns the object.
Angles are radians, lengths metres, light power watts (sun: W/m^2), colours scene-linear.

    reset()
    floor = plane(size=4, material=principled("Floor", base_color=(0.8, 0.2, 0.1), roughness=0.3))
    spot_light(power=1000, location=(0, 0, 3), spot_size=math.radians(45), spot_blend=0.2)
    camera(location=(0, -6, 3), look_at=(0, 0, 0))
    description = extract_scene(depsgraph())
"""

from __future__ import annotations

import math
from typing import Iterable, Sequence

import bpy
import numpy as np
from mathutils import Euler, Matrix, Vector

Vec3 = Sequence[float]


def reset() -> bpy.types.Scene:
    """An empty factory scene (no objects, default render settings); returns it."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def depsgraph(
    scene: bpy.types.Scene | None = None, view_layer: bpy.types.ViewLayer | None = None
) -> bpy.types.Depsgraph:
    """The evaluated depsgraph of ``scene``'s view layer, up to date, without changing the context."""
    scene = scene or bpy.context.scene
    view_layer = view_layer or scene.view_layers[0]
    with bpy.context.temp_override(scene=scene, view_layer=view_layer):
        graph = bpy.context.evaluated_depsgraph_get()
    graph.update()
    return graph


def _link(obj: bpy.types.Object, scene: bpy.types.Scene | None, collection: bpy.types.Collection | None) -> None:
    if collection is None:
        collection = (scene or bpy.context.scene).collection
    collection.objects.link(obj)


def _place(obj: bpy.types.Object, location: Vec3, rotation: Vec3, scale: Vec3 | float) -> None:
    obj.location = location
    obj.rotation_euler = rotation
    obj.scale = (scale, scale, scale) if isinstance(scale, (int, float)) else scale


def look_at(obj: bpy.types.Object, target: Vec3, up: str = "Y") -> None:
    """Rotate ``obj`` so its local -Z (where cameras and lights point) faces ``target``."""
    direction = Vector(target) - obj.location
    obj.rotation_euler = direction.to_track_quat("-Z", up).to_euler()


def mesh_object(
    name: str,
    vertices: Iterable[Vec3],
    faces: Iterable[Sequence[int]],
    *,
    location: Vec3 = (0, 0, 0),
    rotation: Vec3 = (0, 0, 0),
    scale: Vec3 | float = 1.0,
    material: bpy.types.Material | None = None,
    smooth: bool = False,
    uv: bool = True,
    scene: bpy.types.Scene | None = None,
    collection: bpy.types.Collection | None = None,
) -> bpy.types.Object:
    """A mesh object from vertex positions and polygons (flat shaded unless ``smooth``).

    With ``uv``, a UV map "UVMap" holds each corner's vertex x, y rescaled to 0..1 over the mesh's
    bounding box (a planar projection, enough for texture tests).
    """
    vertices = np.asarray(list(vertices), np.float32).reshape(-1, 3)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices.tolist(), [], [tuple(f) for f in faces])
    mesh.update()
    mesh.shade_smooth() if smooth else mesh.shade_flat()
    if uv:
        layer = mesh.uv_layers.new(name="UVMap")
        corner_vertex = np.empty(len(mesh.loops), np.int32)
        mesh.loops.foreach_get("vertex_index", corner_vertex)
        if len(vertices):
            lo, hi = vertices[:, :2].min(axis=0), vertices[:, :2].max(axis=0)
            span = np.where(hi > lo, hi - lo, 1.0)
            layer.uv.foreach_set("vector", ((vertices[corner_vertex, :2] - lo) / span).astype(np.float32).ravel())
    if material is not None:
        mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    _place(obj, location, rotation, scale)
    _link(obj, scene, collection)
    return obj


def plane(
    name: str = "Plane",
    size: float | tuple[float, float] = 2.0,
    *,
    subdivisions: int = 1,
    **kwargs,
) -> bpy.types.Object:
    """A plane in local XY facing +Z, ``size`` across, split into ``subdivisions``^2 quads."""
    sx, sy = (size, size) if isinstance(size, (int, float)) else size
    n = subdivisions
    vertices = [(sx * (i / n - 0.5), sy * (j / n - 0.5), 0.0) for j in range(n + 1) for i in range(n + 1)]
    faces = [
        (j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i)
        for j in range(n)
        for i in range(n)
    ]
    return mesh_object(name, vertices, faces, **kwargs)


def box(name: str = "Box", size: float | Vec3 = 2.0, **kwargs) -> bpy.types.Object:
    """An axis-aligned box centred on its origin, ``size`` along x, y, z, outward-facing quads."""
    sx, sy, sz = (size, size, size) if isinstance(size, (int, float)) else size
    hx, hy, hz = sx / 2, sy / 2, sz / 2
    vertices = [(x, y, z) for z in (-hz, hz) for y in (-hy, hy) for x in (-hx, hx)]
    faces = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return mesh_object(name, vertices, faces, **kwargs)


def _new_node_material(name: str) -> bpy.types.Material:
    mat = bpy.data.materials.new(name)
    # Blender 5.0 gives every new material a node tree and deprecates use_nodes; 4.x needs it.
    if mat.node_tree is None:
        mat.use_nodes = True
    return mat


def principled(
    name: str = "Material",
    *,
    base_color: Vec3 = (0.8, 0.8, 0.8),
    roughness: float = 0.5,
    metallic: float = 0.0,
    specular_ior_level: float = 0.5,
    ior: float = 1.5,
    image: bpy.types.Image | None = None,
) -> bpy.types.Material:
    """A material whose output is one Principled BSDF; ``image`` goes straight into Base Color."""
    mat = _new_node_material(name)
    bsdf = principled_node(mat)
    bsdf.inputs["Base Color"].default_value = (*base_color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Specular IOR Level"].default_value = specular_ior_level
    bsdf.inputs["IOR"].default_value = ior
    if image is not None:
        tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        mat.node_tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def principled_node(material: bpy.types.Material) -> bpy.types.Node:
    """The material's Principled BSDF node (a new material has one, wired to the output)."""
    return next(n for n in material.node_tree.nodes if n.type == "BSDF_PRINCIPLED")


def shader_material(name: str, shader: str, **inputs) -> bpy.types.Material:
    """A material whose Surface is a single shader node of type ``shader`` (e.g. "ShaderNodeEmission")."""
    mat = _new_node_material(name)
    nodes = mat.node_tree.nodes
    for node in [n for n in nodes if n.type != "OUTPUT_MATERIAL"]:
        nodes.remove(node)
    output = next(n for n in nodes if n.type == "OUTPUT_MATERIAL")
    node = nodes.new(shader)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    mat.node_tree.links.new(node.outputs[0], output.inputs["Surface"])
    return mat


def generated_image(
    name: str,
    width: int,
    height: int,
    rgba: Sequence[float] | None = None,
    *,
    float_buffer: bool = False,
    colorspace: str | None = None,
) -> bpy.types.Image:
    """A generated image filled with ``rgba`` (values as stored: sRGB-encoded in an sRGB byte image).

    The colour space is set before the pixels because changing it regenerates (clears) a
    generated image.
    """
    image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=float_buffer)
    if colorspace is not None:
        image.colorspace_settings.name = colorspace
    if rgba is not None:
        image.pixels.foreach_set(np.tile(np.asarray(rgba, np.float32), width * height))
    return image


def light(
    kind: str,
    name: str | None = None,
    *,
    power: float = 1000.0,
    color: Vec3 = (1.0, 1.0, 1.0),
    location: Vec3 = (0, 0, 0),
    rotation: Vec3 = (0, 0, 0),
    look_at_point: Vec3 | None = None,
    scale: Vec3 | float = 1.0,
    scene: bpy.types.Scene | None = None,
    collection: bpy.types.Collection | None = None,
    **settings,
) -> bpy.types.Object:
    """A light of ``kind`` ("POINT", "SPOT", "SUN", "AREA"); ``power`` is Power [W] or, for a sun,
    Strength [W/m^2]; ``settings`` are set on the light data (spot_size, size, shape, ...);
    ``scale`` is the object's (it scales an area light's size and a spot's cone)."""
    data = bpy.data.lights.new(name or kind.title(), kind)
    data.energy = power
    data.color = color
    for key, value in settings.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new(name or kind.title(), data)
    _place(obj, location, rotation, scale)
    if look_at_point is not None:
        look_at(obj, look_at_point)
    _link(obj, scene, collection)
    return obj


def point_light(power: float = 1000.0, radius: float = 0.0, **kwargs) -> bpy.types.Object:
    return light("POINT", power=power, shadow_soft_size=radius, **kwargs)


def spot_light(
    power: float = 1000.0,
    spot_size: float = math.radians(45),
    spot_blend: float = 0.15,
    radius: float = 0.0,
    **kwargs,
) -> bpy.types.Object:
    """Spot light; ``spot_size`` is the full cone angle (radians), ``spot_blend`` its smooth edge."""
    settings = {"spot_size": spot_size, "spot_blend": spot_blend, "shadow_soft_size": radius}
    return light("SPOT", power=power, **settings, **kwargs)


def sun_light(strength: float = 3.0, angle: float = 0.0, **kwargs) -> bpy.types.Object:
    return light("SUN", power=strength, angle=angle, **kwargs)


def area_light(
    power: float = 100.0, size: float = 1.0, size_y: float | None = None, shape: str | None = None, **kwargs
) -> bpy.types.Object:
    """Square (or RECTANGLE when ``size_y`` is given) area light facing its local -Z."""
    shape = shape or ("SQUARE" if size_y is None else "RECTANGLE")
    settings = {"shape": shape, "size": size}
    if size_y is not None:
        settings["size_y"] = size_y
    return light("AREA", power=power, **settings, **kwargs)


def camera(
    name: str = "Camera",
    *,
    location: Vec3 = (0, -6, 3),
    rotation: Vec3 = (0, 0, 0),
    look_at_point: Vec3 | None = (0, 0, 0),
    lens: float = 50.0,
    kind: str = "PERSP",
    ortho_scale: float = 6.0,
    clip_start: float = 0.1,
    clip_end: float = 100.0,
    resolution: tuple[int, int] = (64, 48),
    scene: bpy.types.Scene | None = None,
    make_active: bool = True,
) -> bpy.types.Object:
    """A camera (the scene's active one unless ``make_active`` is False); sets the render resolution."""
    scene = scene or bpy.context.scene
    data = bpy.data.cameras.new(name)
    data.type = kind
    data.lens = lens
    data.ortho_scale = ortho_scale
    data.clip_start = clip_start
    data.clip_end = clip_end
    obj = bpy.data.objects.new(name, data)
    _place(obj, location, rotation, 1.0)
    if look_at_point is not None:
        look_at(obj, look_at_point)
    _link(obj, scene, None)
    if make_active:
        scene.camera = obj
        scene.render.resolution_x, scene.render.resolution_y = resolution
        scene.render.resolution_percentage = 100
    return obj


def world_matrix(obj: bpy.types.Object) -> Matrix:
    """The object's world matrix from its own transform (parentless objects), without a depsgraph."""
    return Matrix.LocRotScale(Vector(obj.location), Euler(obj.rotation_euler).to_quaternion(), Vector(obj.scale))


FRAME_IMAGES = ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular", "coverage",
                "indirect_glossy_reflectors", "indirect_caustics")


def render_frame(scene, settings, width: int, height: int):
    """One frame of the add-on's renderer (FrameRenderer) of ``scene``: a bpy scene (its evaluated
    depsgraph is extracted) or a SceneDescription, from its camera; its GPU resources are freed."""
    from vsgl_addon.renderer import FrameRenderer
    from vsgl_addon.scene import extract_scene

    description = extract_scene(depsgraph(scene)) if isinstance(scene, bpy.types.Scene) else scene
    renderer = FrameRenderer()
    try:
        return renderer.render(description, settings, width, height)
    finally:
        renderer.free()


def assert_finite_frame(images, label: str = "") -> None:
    """Every image of a FrameImages is finite and non-negative (no NaN or Inf reaches a pixel)."""
    for name in FRAME_IMAGES:
        image = getattr(images, name)
        assert np.all(np.isfinite(image)) and image.min() >= 0.0, f"{name} {label}"
