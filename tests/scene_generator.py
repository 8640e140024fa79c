# SPDX-License-Identifier: GPL-3.0-or-later
"""Seeded random scenes of the kind that breaks renderers: degenerate transforms and meshes, lights at
the ends of their ranges, every material kind, cameras inside geometry, empty scenes and crowds.

``build(seed)`` makes one scene on a factory-empty file (through tests/scene_builders.py) and returns a
``GeneratedScene`` that says what it holds, so a failing seed can be read and rebuilt by hand:

    python -c "import sys; sys.path[:0] = ['tests', '.']; import bpy, scene_generator as g; print(g.build(7))"

Also here: ``rna_dump()``, a plain-value dump of the user's data (scenes, objects, meshes, materials,
lights, cameras, collections, worlds, images, node groups) for checking that rendering changed none of
it, and ``GPUResourceTracker``, which counts the GPU resources made while it is active that are still
referenced afterwards.
"""

from __future__ import annotations

import hashlib
import math
import sys
from dataclasses import dataclass, field

import bpy
import numpy as np
from mathutils import Matrix

import scene_builders as sb

LIGHT_POWERS = (0.0, 1e-3, 1.0, 100.0, 1e4, 1e6)
SUN_STRENGTHS = (0.0, 1e-3, 1.0, 1e3)
SPOT_SIZES_DEG = (1.0, 30.0, 90.0, 179.0, 180.0)
SPOT_BLENDS = (0.0, 0.5, 1.0)
SUN_ANGLES_DEG = (0.0, 0.5, 10.0, 90.0, 180.0)
AREA_SIZES = (0.0, 1e-3, 1.0, 10.0)
AREA_SHAPES = ("SQUARE", "RECTANGLE", "DISK", "ELLIPSE")
LIGHT_RADII = (0.0, 0.1, 2.0)
# Object scales of lights: a spot's cone, an area's size follow them; zero hides a light.
LIGHT_FACTORS = (0.0, 0.5, 1.0, 10.0)
LIGHT_SCALES = ((1, 1, 1), (1, 1, 1), (0, 0, 0), (1, 1, 0), (1e-4,) * 3, (1e4,) * 3, (-1, 1, 1),
                (1e4, 1e4, 1e-4))

TRANSFORMS = ("plain", "zero-axis", "zero-all", "negative", "tiny", "huge", "shear")
MESHES = ("plane", "box", "zero-area", "collinear", "loose-vertices", "edges-only", "nan-normals")
MATERIALS = ("principled", "principled-extreme", "glass", "emission", "noise-texture", "none", "mix",
             "transparent")
CAMERAS = ("perspective", "orthographic", "panoramic", "inside-box", "wide", "narrow")

CROWD_SIZE = 10_000


@dataclass
class GeneratedScene:
    seed: int
    lights: list[str] = field(default_factory=list)
    meshes: list[str] = field(default_factory=list)
    camera: str = ""
    crowd: int = 0

    def __str__(self) -> str:
        return (f"seed {self.seed}: lights [{'; '.join(self.lights)}], meshes [{'; '.join(self.meshes)}], "
                f"camera {self.camera}, crowd {self.crowd}")


def _transform(kind: str, rng: np.random.Generator) -> Matrix:
    location = rng.uniform((-2.0, -2.0, 0.0), (2.0, 2.0, 1.5))
    rotation = Matrix.Rotation(float(rng.uniform(0, 2 * math.pi)), 4, "Z") @ Matrix.Rotation(
        float(rng.uniform(-1, 1)), 4, "X")
    scale = {"plain": (1, 1, 1), "zero-axis": tuple(np.roll([0.0, 1.0, 1.0], int(rng.integers(3)))),
             "zero-all": (0, 0, 0), "negative": (-1, 1, 1), "tiny": (1e-4,) * 3,
             "huge": (1e4, 1e4, 1e-4) if rng.random() < 0.5 else (1e4,) * 3, "shear": (1, 1, 1)}[kind]
    matrix = Matrix.Translation(location) @ rotation @ Matrix.Diagonal((*scale, 1.0))
    if kind == "shear":
        matrix = matrix @ Matrix(((1, 0.8, 0, 0), (0, 1, 0.5, 0), (0, 0, 1, 0), (0, 0, 0, 1)))
    return matrix


def _material(kind: str, rng: np.random.Generator, index: int) -> bpy.types.Material | None:
    name = f"{kind}.{index}"
    if kind == "none":
        return None
    if kind == "principled":
        return sb.principled(name, base_color=tuple(rng.uniform(0, 1, 3)), roughness=float(rng.uniform(0, 1)),
                             metallic=float(rng.choice([0.0, 1.0])))
    if kind == "principled-extreme":
        material = sb.principled(name, base_color=tuple(rng.choice([0.0, 1.0], 3)),
                                 roughness=float(rng.choice([0.0, 1e-3, 1.0])),
                                 metallic=float(rng.choice([0.0, 1.0])),
                                 specular_ior_level=float(rng.choice([0.0, 1.0])),
                                 ior=float(rng.choice([1.0, 1.0001, 3.0])))
        bsdf = sb.principled_node(material)
        bsdf.inputs["Alpha"].default_value = float(rng.choice([0.0, 1.0]))
        bsdf.inputs["Transmission Weight"].default_value = float(rng.choice([0.0, 1.0]))
        bsdf.inputs["Emission Strength"].default_value = float(rng.choice([0.0, 1e3]))
        return material
    if kind == "glass":
        return sb.shader_material(name, "ShaderNodeBsdfGlass", Roughness=float(rng.choice([0.0, 0.5])))
    if kind == "emission":
        return sb.shader_material(name, "ShaderNodeEmission", Strength=float(rng.choice([0.0, 10.0, 1e4])))
    if kind == "transparent":
        return sb.shader_material(name, "ShaderNodeBsdfTransparent")
    if kind == "noise-texture":
        material = sb.principled(name, roughness=0.4)
        noise = material.node_tree.nodes.new("ShaderNodeTexNoise")
        material.node_tree.links.new(noise.outputs["Color"], sb.principled_node(material).inputs["Base Color"])
        return material
    if kind == "mix":
        material = sb.shader_material(name, "ShaderNodeMixShader")
        nodes, links = material.node_tree.nodes, material.node_tree.links
        mix = next(n for n in nodes if n.type == "MIX_SHADER")
        links.new(nodes.new("ShaderNodeBsdfDiffuse").outputs[0], mix.inputs[1])
        links.new(nodes.new("ShaderNodeBsdfGlossy").outputs[0], mix.inputs[2])
        return material
    raise ValueError(kind)


def _mesh(kind: str, name: str, material, matrix: Matrix) -> bpy.types.Object:
    if kind == "plane":
        obj = sb.plane(name, size=2.0, material=material)
    elif kind == "box":
        obj = sb.box(name, size=1.0, material=material)
    elif kind == "zero-area":  # a triangle whose three corners coincide, beside a good one
        obj = sb.mesh_object(name, [(0, 0, 0), (0, 0, 0), (0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)],
                             [(0, 1, 2), (3, 4, 5)], material=material)
    elif kind == "collinear":
        obj = sb.mesh_object(name, [(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0)], [(0, 1, 2), (0, 2, 3)],
                             material=material)
    elif kind == "loose-vertices":
        obj = sb.mesh_object(name, [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], material=material)
    elif kind == "edges-only":
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 1), (1, 2)], [])
        obj = bpy.data.objects.new(name, mesh)
        bpy.context.scene.collection.objects.link(obj)
    elif kind == "nan-normals":
        obj = sb.plane(name, size=2.0, material=material)
        try:  # Blender may sanitise what it stores; the extraction must survive either way
            obj.data.normals_split_custom_set([(math.nan, 0.0, 1.0)] * len(obj.data.loops))
        except (RuntimeError, ValueError):
            pass
    else:
        raise ValueError(kind)
    obj.matrix_world = matrix
    return obj


def _light(rng: np.random.Generator, index: int, inside: Matrix | None) -> tuple[bpy.types.Object, str]:
    obj, text = _light_of_kind(rng, index, inside)
    scale = LIGHT_SCALES[int(rng.integers(len(LIGHT_SCALES)))]
    if scale != (1, 1, 1):
        obj.scale = scale
        text += f" scale {scale}"
    if rng.random() < 0.4:
        obj.data.diffuse_factor, obj.data.specular_factor = (float(v) for v in rng.choice(LIGHT_FACTORS, 2))
        text += f" factors {obj.data.diffuse_factor:g}/{obj.data.specular_factor:g}"
    return obj, text


def _link(light: bpy.types.Object, objects: list, rng: np.random.Generator) -> str:
    """Light linking and shadow linking of ``light`` to random members of ``objects``, with random
    include / exclude states (an empty collection too)."""
    words = []
    for kind in ("receiver", "blocker"):
        if rng.random() < 0.5 or not objects:
            continue
        collection = bpy.data.collections.new(f"{light.name} {kind}s")
        members = [o for o in objects if rng.random() < 0.5]
        for obj in members:
            collection.objects.link(obj)
        for entry in collection.collection_objects:
            entry.light_linking.link_state = str(rng.choice(["INCLUDE", "EXCLUDE"]))
        setattr(light.light_linking, f"{kind}_collection", collection)
        words.append(f"{kind}s {len(members)}")
    return ", ".join(words)


def _light_of_kind(rng: np.random.Generator, index: int, inside: Matrix | None) -> tuple[bpy.types.Object, str]:
    kind = str(rng.choice(["POINT", "SPOT", "SUN", "AREA"]))
    location = tuple(rng.uniform((-3.0, -3.0, 0.2), (3.0, 3.0, 4.0))) if inside is None else inside.translation
    target = tuple(rng.uniform((-1.0, -1.0, -0.5), (1.0, 1.0, 0.5)))
    name = f"{kind.title()}.{index}"
    if kind == "SUN":
        strength, angle = float(rng.choice(SUN_STRENGTHS)), float(rng.choice(SUN_ANGLES_DEG))
        obj = sb.sun_light(strength, math.radians(angle), name=name, location=location, look_at_point=target)
        return obj, f"{name} {strength:g} W/m² angle {angle:g}°"
    power = float(rng.choice(LIGHT_POWERS))
    if kind == "SPOT":
        size, blend = float(rng.choice(SPOT_SIZES_DEG)), float(rng.choice(SPOT_BLENDS))
        obj = sb.spot_light(power, math.radians(size), blend, float(rng.choice(LIGHT_RADII)), name=name,
                            location=location, look_at_point=target)
        detail = f"size {size:g}° blend {blend:g}"
    elif kind == "AREA":
        shape, size = str(rng.choice(AREA_SHAPES)), float(rng.choice(AREA_SIZES))
        size_y = float(rng.choice(AREA_SIZES)) if shape in ("RECTANGLE", "ELLIPSE") else None
        obj = sb.area_light(power, size, size_y, shape, name=name, location=location, look_at_point=target)
        detail = f"{shape} {size:g}×{size_y if size_y is not None else size:g}"
    else:
        obj = sb.point_light(power, float(rng.choice(LIGHT_RADII)), name=name, location=location)
        detail = f"radius {obj.data.shadow_soft_size:g}"
    where = " inside a closed box" if inside is not None else ""
    return obj, f"{name} {power:g} W {detail}{where}"


def _crowd(count: int) -> None:
    """`count` collection instances of a small box (empties instancing one collection)."""
    collection = bpy.data.collections.new("Crowd source")
    sb.box("Crowd member", size=0.05, material=sb.principled("Crowd", roughness=0.6), collection=collection)
    side = math.ceil(math.sqrt(count))
    scene = bpy.context.scene
    for i in range(count):
        empty = bpy.data.objects.new(f"Crowd.{i}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = collection
        empty.location = (4.0 * (i % side) / side - 2.0, 4.0 * (i // side) / side - 2.0, 0.03)
        scene.collection.objects.link(empty)


def _camera(kind: str, rng: np.random.Generator, resolution) -> None:
    if kind == "inside-box":
        sb.box("Enclosure", size=1.0, location=(0, 0, 1.0), material=sb.principled("Enclosure"))
        sb.camera(location=(0, 0, 1.0), look_at_point=(0, 1, 1.0), resolution=resolution)
        return
    location = tuple(rng.uniform((-5.0, -7.0, 0.5), (5.0, -3.0, 5.0)))
    if kind == "orthographic":
        sb.camera(location=location, kind="ORTHO", ortho_scale=float(rng.choice([1e-3, 6.0, 1e3])),
                  resolution=resolution)
    elif kind == "panoramic":
        sb.camera(location=location, kind="PANO", resolution=resolution)
    elif kind == "wide":
        sb.camera(location=location, lens=1.0, clip_start=1e-4, clip_end=1e6, resolution=resolution)
    elif kind == "narrow":
        sb.camera(location=location, lens=5000.0, resolution=resolution)
    else:
        sb.camera(location=location, resolution=resolution)


def build(seed: int, resolution=(32, 24)) -> GeneratedScene:
    """One random scene on a factory-empty file. Seed 0 holds the 10,000-instance crowd; one seed in
    eight has no lights and one in eight no meshes."""
    rng = np.random.default_rng(seed)
    sb.reset()
    generated = GeneratedScene(seed)
    if seed == 0:
        _crowd(CROWD_SIZE)
        generated.crowd = CROWD_SIZE
    mesh_count = 0 if seed % 8 == 5 else int(rng.integers(1, 6))
    closed_boxes, objects = [], []
    for i in range(mesh_count):
        kind, transform = str(rng.choice(MESHES)), str(rng.choice(TRANSFORMS))
        material_kind = str(rng.choice(MATERIALS))
        matrix = _transform(transform, rng)
        obj = _mesh(kind, f"{kind}.{i}", _material(material_kind, rng, i), matrix)
        objects.append(obj)
        hidden = [name for name in ("visible_diffuse", "visible_glossy", "visible_shadow") if rng.random() < 0.15]
        for name in hidden:
            setattr(obj, name, False)
        if hidden:
            material_kind += " not " + "/".join(name.removeprefix("visible_") for name in hidden)
        if kind == "box" and transform == "plain":
            closed_boxes.append(matrix)
        generated.meshes.append(f"{kind} {transform} {material_kind}")
    if mesh_count:  # a floor, so that most lights have something to bounce from
        sb.plane("Floor", size=8.0, material=sb.principled("Floor", roughness=float(rng.uniform(0, 1))))
        generated.meshes.append("floor")
    light_count = 0 if seed % 8 == 3 else int(rng.integers(1, 4))
    for i in range(light_count):
        inside = closed_boxes[0] if closed_boxes and i == 0 and rng.random() < 0.5 else None
        light, text = _light(rng, i, inside)
        links = _link(light, objects, rng)
        generated.lights.append(f"{text} linked {links}" if links else text)
    generated.camera = str(rng.choice(CAMERAS))
    _camera(generated.camera, rng, resolution)
    return generated


def render_through_engine(scene, exr_path=None) -> dict:
    """Render ``scene`` with the VSGL engine through Blender's render pipeline (the add-on registered
    for the call): the engine's statistics of the frame (empty when no frame came out), and the
    multilayer EXR of every pass at ``exr_path`` when given."""
    from vsgl_addon import engine, register, unregister

    register()
    try:
        scene.render.engine = "VSGL"
        engine.last_frame_statistics.clear()
        bpy.ops.render.render(scene=scene.name)
        statistics = dict(engine.last_frame_statistics)
        if exr_path is not None:
            scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
            scene.render.image_settings.color_depth = "32"
            bpy.data.images["Render Result"].save_render(str(exr_path), scene=scene)
    finally:
        unregister()
    return statistics


# --- the user's data, dumped to plain values -------------------------------------------------------

_DATA_COLLECTIONS = ("scenes", "objects", "meshes", "materials", "lights", "cameras", "collections",
                     "worlds", "images", "node_groups")
_SKIP = {"rna_type", "vsgl", "is_evaluated", "original", "session_uid", "is_dirty", "users",
         "use_fake_user", "is_runtime_data", "tag", "is_missing", "bound_box", "use_nodes",
         "depsgraph"}  # a view layer's depsgraph is evaluated state, not the user's data
_ITEMS = 64  # items of one RNA collection that are dumped in full; longer ones by count and hash


def _value(value, depth: int):
    if isinstance(value, bpy.types.ID):
        return ("ID", type(value).__name__, value.name_full)
    if isinstance(value, (bool, int, str)) or value is None:
        return value
    if isinstance(value, float):
        return value.hex()
    if isinstance(value, bpy.types.bpy_struct):
        return _struct(value, depth - 1) if depth > 0 else type(value).__name__
    try:
        items = list(value)
    except TypeError:
        return repr(value)
    if len(items) > _ITEMS:
        return ("items", len(items), hashlib.sha256(repr([_value(v, 0) for v in items]).encode()).hexdigest())
    return [_value(v, depth) for v in items]


def _struct(struct, depth: int) -> dict:
    out = {}
    for prop in struct.bl_rna.properties:
        name = prop.identifier
        if name in _SKIP:
            continue
        try:
            value = getattr(struct, name)
        except (AttributeError, RuntimeError, TypeError, ReferenceError):
            continue
        out[name] = _value(value, depth)
    return out


def _mesh_arrays(mesh) -> str:
    digest = hashlib.sha256()
    for collection, attribute, width in ((mesh.vertices, "co", 3), (mesh.loops, "vertex_index", 1),
                                         (mesh.polygons, "material_index", 1)):
        array = np.empty(len(collection) * width, np.float64 if attribute == "co" else np.int64)
        collection.foreach_get(attribute, array)
        digest.update(array.tobytes())
    normals = np.empty(len(mesh.loops) * 3, np.float32)
    mesh.corner_normals.foreach_get("vector", normals)
    digest.update(normals.tobytes())
    return digest.hexdigest()


def rna_dump(depth: int = 3) -> dict:
    """Every ID of the user's data kinds as nested plain values (floats exactly, as hex), meshes'
    geometry as a hash. Two dumps compare equal when nothing the user made was changed."""
    dump = {}
    for kind in _DATA_COLLECTIONS:
        for item in getattr(bpy.data, kind):
            if item.name == "Render Result":
                continue
            entry = _struct(item, depth)
            if kind == "meshes":
                entry["geometry"] = _mesh_arrays(item)
            dump[(kind, item.name_full)] = entry
    return dump


def dump_differences(before: dict, after: dict, limit: int = 10) -> list[str]:
    """Readable paths where two dumps differ (for a failure message)."""
    found = []

    def walk(a, b, path):
        if len(found) >= limit:
            return
        if isinstance(a, dict) and isinstance(b, dict):
            for key in sorted(set(a) | set(b), key=str):
                walk(a.get(key, "<missing>"), b.get(key, "<missing>"), f"{path}.{key}")
        elif isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
            for i, (x, y) in enumerate(zip(a, b)):
                walk(x, y, f"{path}[{i}]")
        elif a != b:
            found.append(f"{path}: {a!r} -> {b!r}")

    walk(before, after, "")
    return found


# --- GPU resources --------------------------------------------------------------------------------

_GPU_TYPES = ("GPUTexture", "GPUFrameBuffer", "GPUOffScreen", "GPUBatch", "GPUVertBuf", "GPUIndexBuf",
              "GPUUniformBuf")


class GPUResourceTracker:
    """While active, every GPU object made through ``gpu.types.<type>(...)`` is recorded; ``alive()``
    names those still referenced by anything but the tracker (Blender frees a GPU resource when its
    Python object goes)."""

    def __init__(self):
        self.made: list[tuple[str, object]] = []
        self._real: dict[str, object] = {}

    def __enter__(self):
        import gpu
        import gpu_extras.batch

        for name in _GPU_TYPES:
            real = getattr(gpu.types, name)
            self._real[name] = real

            def factory(*args, _real=real, _name=name, **kwargs):
                made = _real(*args, **kwargs)
                self.made.append((_name, made))
                return made

            setattr(gpu.types, name, factory)
            # gpu_extras.batch imported the types by name: its batches are counted too.
            if hasattr(gpu_extras.batch, name):
                setattr(gpu_extras.batch, name, factory)
        return self

    def __exit__(self, *exc):
        import gpu
        import gpu_extras.batch

        for name, real in self._real.items():
            setattr(gpu.types, name, real)
            if hasattr(gpu_extras.batch, name):
                setattr(gpu_extras.batch, name, real)

    def alive(self) -> list[str]:
        """Names of the recorded resources that something else still references. The tracker lets go
        of the others round by round (a batch it holds keeps its vertex buffers alive), so after this
        call it holds only what it returns."""
        import gc

        pending, self.made = self.made, []
        while True:
            gc.collect()
            # References to a live entry's object: the entry tuple and getrefcount's argument.
            keep = [entry for entry in pending if sys.getrefcount(entry[1]) > 2]
            if len(keep) == len(pending):
                break
            pending = keep
        self.made = pending
        return [name for name, _ in pending]
