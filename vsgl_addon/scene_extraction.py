# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender side of the scene description: evaluated depsgraph -> :class:`SceneDescription`.

Reads only what it is given (a depsgraph, never ``bpy.context``) and writes nothing: meshes come
from ``Object.to_mesh()`` on evaluated objects and are released with ``to_mesh_clear()``, so the
user's data and ``bpy.data`` are the same before and after. Bulk data goes through
``foreach_get`` into numpy; Python loops run per object instance, material and light, never per
vertex or triangle.

What is approximated (each listed in ``SceneDescription.warnings`` by material name, one line):

* a material whose Material Output surface is not a Principled BSDF (another shader, a mix, a
  node group, nothing) takes the material's Viewport Display colour, metallic and roughness, the
  values Blender's Solid view shows, with Specular IOR Level 0.5 and IOR 1.5;
* a Principled BSDF input that is linked to anything other than an Image Texture's Color output
  straight into Base Color takes the socket's own value (what Blender uses once unlinked); an
  image texture whose Vector input is linked is read as if it used the active render UV map;
* a byte image in a colour space other than sRGB, Non-Color or linear Rec.709 is decoded with
  the sRGB curve, or used as it is when the space is linear (no primaries conversion); a tiled
  (UDIM) or movie image gives its first tile or frame.

Visibility: the depsgraph decides what exists (a render depsgraph already drops objects hidden
from render; a viewport one drops those hidden in the viewport). On top of that, objects with
Disable in Renders, and objects reached only through collections disabled in renders or excluded,
are left out, so a viewport depsgraph yields what a render would show, except where the
depsgraph itself differs: a viewport depsgraph never evaluates objects hidden in the viewport,
and evaluates modifiers with their viewport settings (Subdivision levels, Show in Viewport).
"""

from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np

from .scene_description import (
    DEFAULT_MATERIAL,
    Camera,
    Geometry,
    Light,
    Material,
    SceneDescription,
    SkippedLight,
)
from .light_extraction import UNMODELLED_LIGHTS, linked, plain_light_tree, read_light
from .views import render_size
from .settings import PROXY_OVERRIDES

# Only instances whose evaluated data is a mesh carry triangles. Curve, surface, text and
# metaball objects appear twice in object_instances since Blender 3: as themselves (curve data)
# and as an instance of their evaluated mesh, parented to themselves; like Cycles, read only the
# mesh. Hair curves, point clouds, volumes and grease pencil have no surface for an RSM.
_MESH_TYPE = "MESH"
# Byte-image colour spaces whose values are used as they are: Blender's scene-linear space is
# linear Rec.709 (the names of 4.x and 5.x configurations) and data needs no decoding.
_EXACT_LINEAR_COLORSPACES = {"Linear Rec.709", "scene_linear", "Linear", "Non-Color", "Raw"}
# Other linear spaces (other primaries: Rec.2020, ACEScg, XYZ, ...) are used as they are too, an
# approximation: there is no Python API for OpenColorIO's primaries conversion.
_OTHER_LINEAR_PREFIXES = ("Linear", "ACEScg", "ACES2065")

# The fallback for unreadable shaders takes the material's Viewport Display colour, metallic and
# roughness; these two have no Viewport Display counterpart and take the Principled defaults.
_FALLBACK_SPECULAR_IOR_LEVEL = 0.5
_FALLBACK_IOR = 1.5


def extract_scene(depsgraph: bpy.types.Depsgraph) -> SceneDescription:
    """The plain description of what ``depsgraph`` renders: geometry, materials, lights, camera."""
    visible = _render_visible_object_uids(depsgraph.view_layer)
    materials = _MaterialTable()
    meshes: dict[int, _MeshArrays | None] = {}
    placements: dict[tuple, list[tuple[np.ndarray, int]]] = {}
    object_names: list[str] = []
    proxy_overrides: dict[str, str] = {}  # object name -> settings.PROXY_OVERRIDES name, where not Auto
    lights: list[Light] = []
    light_objects: list[bpy.types.Object] = []
    skipped: list[SkippedLight] = []
    light_node_trees: list[str] = []
    # Per object instance: (the instanced object, its instancer) originals, and its ray visibility.
    instance_originals: list[tuple] = []
    visibility: list[tuple[bool, bool, bool]] = []

    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type != _MESH_TYPE and obj.type != "LIGHT":
            continue
        top = inst.parent if inst.is_instance else obj
        shown = (
            top.original.session_uid in visible
            and not top.original.hide_render
            and not obj.original.hide_render
        )
        if obj.type == "LIGHT":
            if not shown:
                skipped.append(SkippedLight(obj.name, "hidden from render"))
                continue
            light, reason = read_light(obj, np.array(inst.matrix_world, np.float64))
            if light is None:
                skipped.append(SkippedLight(obj.name, reason))
            else:
                lights.append(light)
                light_objects.append(obj.original)
                if obj.data.use_nodes and not plain_light_tree(obj.data.node_tree):
                    light_node_trees.append(obj.name)
            continue
        if not shown:
            continue
        # Evaluated mesh data is shared by every instance of the same geometry (collection and
        # geometry-nodes instances), so each distinct mesh is read once and placed many times.
        key = obj.data.as_pointer()
        if key not in meshes:
            meshes[key] = _read_mesh(obj)
        arrays = meshes[key]
        if arrays is None:
            continue
        # Objects sharing one mesh may still differ in materials (object-linked slots); geometry
        # nodes instances have no slots of their own, only their mesh's materials.
        slot_materials = [s.material for s in obj.material_slots] or arrays.mesh_materials
        table = _slot_table(slot_materials, arrays.used_slots, materials)
        placement = np.array(inst.matrix_world, np.float64), len(object_names)
        placements.setdefault((key, table), []).append(placement)
        object_names.append(_instance_name(inst, obj))
        instance_originals.append((obj.original, top.original))
        visibility.append(tuple(bool(getattr(obj.original, name, True))
                                for name in ("visible_diffuse", "visible_glossy", "visible_shadow")))
        override = getattr(obj.original, "vsgl_proxy", "AUTO")
        if override != "AUTO":
            proxy_overrides[object_names[-1]] = PROXY_OVERRIDES.identified(override).name

    geometry = _place(meshes, placements)
    lights = [linked(light, original, instance_originals) for light, original in zip(lights, light_objects)]
    camera, camera_warning = _read_camera(depsgraph)

    warnings = []
    approx = [m.name for m in materials.list if m.approximated]
    if approx:
        warnings.append("VSGL: approximated materials (not a plain Principled BSDF): " + ", ".join(approx))
    if light_node_trees:
        warnings.append(
            "VSGL: light node trees ignored (plain colour and power used): " + ", ".join(light_node_trees)
        )
    unmodelled = [f"{light.name} ({light.reason})" for light in skipped if light.reason in UNMODELLED_LIGHTS]
    if unmodelled:
        warnings.append("VSGL: lights skipped: " + ", ".join(unmodelled))
    if camera_warning:
        warnings.append(camera_warning)

    return SceneDescription(
        geometry=geometry,
        materials=tuple(materials.list),
        lights=tuple(lights),
        camera=camera,
        object_names=tuple(object_names),
        skipped_lights=tuple(skipped),
        warnings=tuple(warnings),
        object_visibility=None if all(all(v) for v in visibility) else np.array(visibility, bool).reshape(-1, 3),
        proxy_overrides=proxy_overrides or None,
    )


def _instance_name(inst: bpy.types.DepsgraphObjectInstance, obj: bpy.types.Object) -> str:
    if not inst.is_instance or inst.parent.original == obj.original:
        return obj.original.name
    return f"{inst.parent.original.name}/{obj.name}"


# --- visibility ---------------------------------------------------------------------------------


def _render_visible_object_uids(view_layer: bpy.types.ViewLayer) -> set[int]:
    """session_uid of every original object reachable through collections that render."""
    uids: set[int] = set()
    stack = [view_layer.layer_collection]
    while stack:
        layer_collection = stack.pop()
        if layer_collection.exclude or layer_collection.collection.hide_render:
            continue
        uids.update(o.original.session_uid for o in layer_collection.collection.objects)
        stack.extend(layer_collection.children)
    return uids


# --- geometry -----------------------------------------------------------------------------------


@dataclass
class _MeshArrays:
    corners: np.ndarray  # (T, 3, 3) float32, object space
    normals: np.ndarray  # (T, 3, 3) float32, object space
    uvs: np.ndarray  # (T, 3, 2) float32
    slot: np.ndarray  # (T,) int32, the triangles' material slot
    used_slots: tuple[int, ...]  # distinct values of slot
    mesh_materials: list  # the evaluated mesh's own materials (evaluated datablocks or None)


def _read_mesh(obj: bpy.types.Object) -> _MeshArrays | None:
    mesh = obj.to_mesh()
    try:
        if mesh is None:
            return None
        tris = mesh.loop_triangles
        n_tris = len(tris)
        if n_tris == 0:
            return None
        n_verts, n_loops = len(mesh.vertices), len(mesh.loops)
        co = np.empty(n_verts * 3, np.float32)
        mesh.vertices.foreach_get("co", co)
        tri_verts = np.empty(n_tris * 3, np.int32)
        tris.foreach_get("vertices", tri_verts)
        tri_loops = np.empty(n_tris * 3, np.int32)
        tris.foreach_get("loops", tri_loops)
        slot = np.empty(n_tris, np.int32)
        tris.foreach_get("material_index", slot)
        corner_normals = np.empty(n_loops * 3, np.float32)
        mesh.corner_normals.foreach_get("vector", corner_normals)

        uv_layer = next((layer for layer in mesh.uv_layers if layer.active_render), None)
        if uv_layer is not None:
            uv = np.empty(n_loops * 2, np.float32)
            uv_layer.uv.foreach_get("vector", uv)
            uvs = uv.reshape(-1, 2)[tri_loops].reshape(n_tris, 3, 2)
        else:
            uvs = np.zeros((n_tris, 3, 2), np.float32)

        return _MeshArrays(
            corners=co.reshape(-1, 3)[tri_verts].reshape(n_tris, 3, 3),
            normals=corner_normals.reshape(-1, 3)[tri_loops].reshape(n_tris, 3, 3),
            uvs=uvs,
            slot=slot,
            used_slots=tuple(np.unique(slot).tolist()),
            # Evaluated materials belong to the depsgraph, not to the temporary mesh.
            mesh_materials=list(mesh.materials),
        )
    finally:
        obj.to_mesh_clear()


def _slot_table(slot_materials: list, used_slots: tuple[int, ...], materials: "_MaterialTable") -> tuple[int, ...]:
    """Material table index per slot; only slots some triangle uses are read (and warned about)."""
    count = len(slot_materials)
    if count == 0:
        return (0,)
    # Blender draws an out-of-range material index with the last slot.
    used = {min(s, count - 1) for s in used_slots}
    return tuple(materials.index(m) if i in used else 0 for i, m in enumerate(slot_materials))


def _normal_matrices(rot: np.ndarray, det: np.ndarray) -> np.ndarray:
    """Normal transforms of (K, 3, 3) linear parts: the inverse transpose, or for a singular one
    (an object scaled to zero on an axis, a common way to hide it) the cofactor matrix, which is
    det × the inverse transpose wherever that exists and stays defined when it does not: a box
    flattened onto a plane keeps the plane's normal on its two large faces."""
    regular = np.abs(det) > 1e-12 * np.maximum(np.abs(rot.astype(np.float64)).max(axis=(1, 2)) ** 3, 1e-300)
    out = np.empty_like(rot)
    if regular.all():
        return np.linalg.inv(rot).transpose(0, 2, 1)
    if regular.any():
        out[regular] = np.linalg.inv(rot[regular]).transpose(0, 2, 1)
    m = rot[~regular].astype(np.float64)
    # Rows of the cofactor matrix: cross products of the columns' complements (cof(M)[i] = m_j × m_k
    # over the columns j, k other than i, in cyclic order).
    columns = m.transpose(0, 2, 1)
    cofactor = np.stack([np.cross(columns[:, 1], columns[:, 2]), np.cross(columns[:, 2], columns[:, 0]),
                         np.cross(columns[:, 0], columns[:, 1])], axis=1).transpose(0, 2, 1)
    # cof(M) = det(M) M^-T: a nearly singular mirror would flip the normals that M^-T keeps.
    sign = np.where(det[~regular] < 0.0, -1.0, 1.0)[:, None, None]
    out[~regular] = (cofactor * sign).astype(rot.dtype)
    return out


def _unit_normals(normals: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Unit normals; where a transformed normal is zero or not finite (a degenerate transform, NaN in
    custom normals), the triangle's geometric normal, and +Z for a triangle of zero area."""
    length = np.linalg.norm(normals, axis=-1, keepdims=True)
    good = np.isfinite(length) & (length > 1e-30)
    if good.all():
        return normals / length
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        unit = normals / length
        p = positions.astype(np.float64)
        face = np.cross(p[..., 1, :] - p[..., 0, :], p[..., 2, :] - p[..., 0, :])
        face_length = np.linalg.norm(face, axis=-1, keepdims=True)
        face_ok = np.isfinite(face_length) & (face_length > 0.0)
        face = np.where(face_ok, face / np.where(face_ok, face_length, 1.0), np.array([0.0, 0.0, 1.0]))
    fallback = np.broadcast_to(face[..., None, :], normals.shape).astype(normals.dtype)
    return np.where(good, unit, fallback)


def _place(meshes: dict, placements: dict) -> Geometry:
    """World-space triangles of every placement, all instances of one mesh transformed at once."""
    parts = []
    for (key, table), placed in placements.items():
        arrays = meshes[key]
        table = np.array(table, np.int32)
        material_index = table[np.clip(arrays.slot, 0, len(table) - 1)]
        matrices = np.stack([m for m, _ in placed]).astype(np.float32)  # (K, 4, 4)
        rot = matrices[:, :3, :3]
        det = np.linalg.det(rot.astype(np.float64))
        positions = np.einsum("kij,tcj->ktci", rot, arrays.corners) + matrices[:, None, None, :3, 3]
        normals = np.einsum("kij,tcj->ktci", _normal_matrices(rot, det), arrays.normals)
        normals = _unit_normals(normals, positions)
        uvs = np.broadcast_to(arrays.uvs, (len(placed), *arrays.uvs.shape))
        # A mirroring transform reverses the winding; swap two corners to keep front faces front.
        mirrored = det < 0
        if mirrored.any():
            order = [0, 2, 1]
            positions[mirrored] = positions[mirrored][:, :, order]
            normals[mirrored] = normals[mirrored][:, :, order]
            uvs = uvs.copy()
            uvs[mirrored] = uvs[mirrored][:, :, order]
        n_tris = arrays.corners.shape[0]
        object_index = np.repeat(np.array([i for _, i in placed], np.int32), n_tris)
        parts.append(
            (
                positions.reshape(-1, 3, 3),
                normals.reshape(-1, 3, 3),
                np.ascontiguousarray(uvs).reshape(-1, 3, 2),
                np.tile(material_index, len(placed)),
                object_index,
            )
        )
    if not parts:
        return Geometry.empty()
    # Triangles in the order objects were met (object_index ascending), independent of the cache.
    order = np.argsort(np.concatenate([p[4] for p in parts]), kind="stable")
    return Geometry(
        positions=np.ascontiguousarray(np.concatenate([p[0] for p in parts])[order], np.float32),
        normals=np.ascontiguousarray(np.concatenate([p[1] for p in parts])[order], np.float32),
        uvs=np.ascontiguousarray(np.concatenate([p[2] for p in parts])[order], np.float32),
        material_index=np.concatenate([p[3] for p in parts])[order].astype(np.int32),
        object_index=np.concatenate([p[4] for p in parts])[order].astype(np.int32),
    )


# --- materials ----------------------------------------------------------------------------------


class _MaterialTable:
    """Distinct materials in the order met; index 0 is the default surface."""

    def __init__(self) -> None:
        self.list: list[Material] = [DEFAULT_MATERIAL]
        self._index: dict[int, int] = {}
        self._images: dict[int, np.ndarray | None] = {}

    def index(self, material: bpy.types.Material | None) -> int:
        if material is None:
            return 0
        uid = material.original.session_uid
        if uid not in self._index:
            self._index[uid] = len(self.list)
            self.list.append(_read_material(material, self._images))
        return self._index[uid]


def _upstream(socket: bpy.types.NodeSocket) -> bpy.types.NodeSocket | None:
    """The output socket feeding ``socket``, through reroutes; None when unlinked."""
    while socket.is_linked:
        link = next((l for l in socket.links if not l.is_muted), None)
        if link is None:
            return None
        if link.from_node.type != "REROUTE":
            return link.from_socket
        socket = link.from_node.inputs[0]
    return None


def _output_node(tree: bpy.types.ShaderNodeTree) -> bpy.types.Node | None:
    # EEVEE first: like EEVEE, the passes rasterise; a Cycles-only output is what Cycles shows.
    for target in ("EEVEE", "ALL", "CYCLES"):
        node = tree.get_output_node(target)
        if node is not None:
            return node
    return None


def _viewport_fallback(material: bpy.types.Material, reason: str) -> Material:
    return Material(
        name=material.original.name,
        base_color=np.array(material.diffuse_color[:3], np.float32),
        roughness=float(material.roughness),
        metallic=float(material.metallic),
        specular_ior_level=_FALLBACK_SPECULAR_IOR_LEVEL,
        ior=_FALLBACK_IOR,
        approximated=True,
        approximation=reason,
    )


def _read_material(material: bpy.types.Material, images: dict) -> Material:
    tree = material.node_tree
    output = _output_node(tree) if tree is not None else None
    if output is None:
        return _viewport_fallback(material, "no material output")
    shader = _upstream(output.inputs["Surface"])
    if shader is None:
        return _viewport_fallback(material, "nothing connected to Surface")
    node = shader.node
    if node.type != "BSDF_PRINCIPLED":
        return _viewport_fallback(material, f"surface is {node.bl_label}, not Principled BSDF")

    problems = []
    image = None
    image_name = ""
    color_source = _upstream(node.inputs["Base Color"])
    if color_source is not None:
        tex = color_source.node
        if tex.type == "TEX_IMAGE" and color_source.name == "Color" and tex.image is not None:
            image, problem = _read_image(tex.image, images)
            image_name = tex.image.name
            if problem:
                problems.append(problem)
            if tex.inputs["Vector"].is_linked:
                problems.append("image texture Vector linked (active UV map used)")
        else:
            problems.append(f"Base Color from {tex.bl_label}")
    handled = {"Base Color"}
    for socket in node.inputs:
        if socket.name not in handled and socket.enabled and _upstream(socket) is not None:
            problems.append(f"{socket.name} linked")

    return Material(
        name=material.original.name,
        base_color=np.array(node.inputs["Base Color"].default_value[:3], np.float32),
        roughness=float(node.inputs["Roughness"].default_value),
        metallic=float(node.inputs["Metallic"].default_value),
        specular_ior_level=float(node.inputs["Specular IOR Level"].default_value),
        ior=float(node.inputs["IOR"].default_value),
        base_color_image=image,
        base_color_image_name=image_name,
        approximated=bool(problems),
        approximation="; ".join(problems),
    )


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB decoding curve (IEC 61966-2-1), which Blender's "sRGB" colour space uses."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(c.dtype)


def _read_image(image: bpy.types.Image, cache: dict) -> tuple[np.ndarray | None, str]:
    """(H, W, 4) scene-linear float32 pixels of ``image``, and a problem description or ""."""
    colorspace = image.colorspace_settings.name
    # Float buffers are already scene-linear in memory (Blender linearises them when loading);
    # byte buffers hold the file's encoded values.
    decode_srgb = False
    problem = ""
    if not image.is_float and colorspace not in _EXACT_LINEAR_COLORSPACES:
        decode_srgb = not colorspace.startswith(_OTHER_LINEAR_PREFIXES)
        if colorspace != "sRGB":
            problem = f"image colour space {colorspace} read as {'sRGB' if decode_srgb else 'linear Rec.709'}"
    if image.source not in ("FILE", "GENERATED"):
        problem = "; ".join(filter(None, (problem, f"{image.source.lower()} image: its first tile/frame only")))
    uid = image.original.session_uid
    if uid not in cache:
        cache[uid] = _image_pixels(image, decode_srgb)
    if cache[uid] is None:
        return None, f"image {image.name} has no pixels (Base Color value used)"
    return cache[uid], problem


def _image_pixels(image: bpy.types.Image, decode_srgb: bool) -> np.ndarray | None:
    width, height = image.size
    channels = image.channels
    if width == 0 or height == 0 or channels == 0:
        return None
    flat = np.empty(width * height * channels, np.float32)
    image.pixels.foreach_get(flat)
    pixels = flat.reshape(height, width, channels)
    if channels != 4:
        rgba = np.ones((height, width, 4), np.float32)
        rgba[..., : min(channels, 3)] = pixels[..., : min(channels, 3)]
        if channels < 3:  # grey (+ alpha): replicate the grey
            rgba[..., 1:3] = pixels[..., :1]
        if channels == 2:
            rgba[..., 3] = pixels[..., 1]
        pixels = rgba
    if decode_srgb:
        pixels[..., :3] = srgb_to_linear(pixels[..., :3])
    return pixels


# --- camera -------------------------------------------------------------------------------------


def _read_camera(depsgraph: bpy.types.Depsgraph) -> tuple[Camera | None, str]:
    scene = depsgraph.scene_eval
    if scene.camera is None or scene.camera.type != "CAMERA":
        return None, ""
    cam_obj = scene.camera.evaluated_get(depsgraph)
    cam = cam_obj.data
    render = scene.render
    warning = ""
    if cam.type == "PANO":
        warning = f"VSGL: panoramic camera {cam_obj.name} projected as a perspective camera"
    # The size the image is rendered at (Blender's integer rule), so that the aspect matches it.
    resolution = render_size(render)
    return (
        Camera(
            name=cam_obj.name,
            matrix_world=np.array(cam_obj.matrix_world, np.float64),
            type="ORTHO" if cam.type == "ORTHO" else "PERSP",
            lens=float(cam.lens),
            sensor_width=float(cam.sensor_width),
            sensor_height=float(cam.sensor_height),
            sensor_fit=cam.sensor_fit,
            ortho_scale=float(cam.ortho_scale),
            shift_x=float(cam.shift_x),
            shift_y=float(cam.shift_y),
            clip_start=float(cam.clip_start),
            clip_end=float(cam.clip_end),
            resolution=resolution,
            pixel_aspect=(float(render.pixel_aspect_x), float(render.pixel_aspect_y)),
        ),
        warning,
    )
