# SPDX-License-Identifier: GPL-3.0-or-later
"""The scene's triangles on the GPU, shared by the passes that rasterise the scene (the RSM views
of :mod:`.rsm`, the camera G-buffer of :mod:`.gbuffer`): :class:`SceneGPU` uploads them once, and
every such pass draws them with the same vertex stage (``glsl/scene_triangles.vert.glsl``), the
same vertex interface and the same per-material inputs (:func:`scene_shader_interface`,
:meth:`SceneGPU.draw`).

Per-material inputs of the fragment stage: ``material_base_color`` = (rgb, 1 when the base colour
image is used), ``material_params`` = (roughness, metallic, Specular IOR Level, IOR) and the
``base_color_image`` sampler (a 1x1 white texture when the material has none), sampled by
``glsl/lib/image.glsl``.

Needs a GPU context, main thread.
"""

from __future__ import annotations

import numpy as np

from ..scene_description import LINK_BLOCKS
from ..shaders import ShaderInterface
from .gpu_util import texture_from_array

#: The vertex stage of every pass that draws :class:`SceneGPU`.
VERTEX_STAGE = "scene_triangles.vert.glsl"


def scene_shader_interface(push_constants, samplers, fragment_outputs) -> ShaderInterface:
    """The interface of a shader that draws :class:`SceneGPU` with :data:`VERTEX_STAGE`: the
    view-projection, the per-material inputs (see the module documentation), then the pass's own
    ``push_constants`` and ``samplers`` (lists of (type, name)), and its ``fragment_outputs``."""
    # Push constants: these 96 bytes first, so a pass has 32 of the 128 every backend guarantees.
    return ShaderInterface(
        push_constants=[
            ("MAT4", "view_projection"),
            ("VEC4", "material_base_color"),  # (rgb, 1 when the image is used)
            ("VEC4", "material_params"),  # (roughness, metallic, specular IOR level, IOR)
            *push_constants,
        ],
        samplers=[("FLOAT_2D", "base_color_image"), *samplers],
        vertex_inputs=[("VEC3", "position"), ("VEC3", "normal"), ("VEC3", "face_normal"),
                       ("VEC2", "uv"), ("FLOAT", "object_index")],
        varyings=[("VEC3", "world_position"), ("VEC3", "corner_normal"), ("VEC2", "texcoord")],
        flat_varyings=[("VEC3", "face_normal_flat"), ("FLOAT", "object_index_flat")],
        fragment_outputs=list(fragment_outputs),
    )


class PointTextureCache:
    """passes/ism.py upload_points of the scene's point sets, kept across SceneGPUs of the same
    triangles, counts and seed (scene_points.point_sets_key): the viewport makes a SceneGPU per
    light build, two per change at two samples, and a light moved leaves the triangles as they were;
    the sets are 8 MB at the default 16384 points × 64 sets. The last ENTRIES draws are kept (the
    coarse preview's smaller sets and two samples' seeds, of two geometry states); its owner frees it
    with the viewport."""

    ENTRIES = 6

    def __init__(self):
        self._textures: dict = {}

    def textures(self, geometry, points_per_set: int, set_count: int, seed: int, upload) -> tuple:
        """The textures of that draw, made by ``upload()`` when not kept."""
        from ..scene_points import point_sets_key

        key = point_sets_key(geometry, points_per_set, set_count, seed)
        textures = self._textures.pop(key, None)
        if textures is None:
            textures = upload()
        self._textures[key] = textures
        while len(self._textures) > self.ENTRIES:
            self._textures.pop(next(iter(self._textures)))
        return textures

    def __len__(self) -> int:
        return len(self._textures)

    def free(self) -> None:
        self._textures.clear()  # Blender frees a GPUTexture with its last reference


class SceneGPU:
    """The scene's triangles on the GPU, uploaded once and shared by every light and view.

    One vertex per triangle corner (position, shading normal, face normal, UV), sorted by material
    so each material is one ``draw_range``; base colour images as RGBA32F textures.
    """

    def __init__(self, scene, point_cache: PointTextureCache | None = None):
        """``point_cache``: where the point sets' textures outlive this upload (the viewport's)."""
        import gpu

        self.scene = scene
        self._point_cache = point_cache
        geometry = scene.geometry
        count = geometry.triangle_count
        self.triangle_count = count
        order = np.argsort(geometry.material_index, kind="stable")
        positions = np.asarray(geometry.positions, np.float64)[order]
        self.positions = positions  # (T, 3, 3) float64, material order (CPU frustum tests)
        self.bounds = (positions.reshape(-1, 3).min(axis=0), positions.reshape(-1, 3).max(axis=0)) \
            if count else None
        materials = np.asarray(geometry.material_index)[order]
        self.ranges: list[tuple[int, int, int]] = []  # (material index, first vertex, vertex count)
        if count:
            starts = np.flatnonzero(np.r_[True, materials[1:] != materials[:-1]])
            ends = np.r_[starts[1:], count]
            self.ranges = [(int(materials[s]), 3 * int(s), 3 * int(e - s)) for s, e in zip(starts, ends)]
        self.batch = None
        self.vertex_buffer = None
        if count:
            face = np.cross(positions[:, 1] - positions[:, 0], positions[:, 2] - positions[:, 0])
            face_normals = np.repeat(face[:, None, :], 3, axis=1)
            fmt = gpu.types.GPUVertFormat()
            fmt.attr_add(id="position", comp_type="F32", len=3, fetch_mode="FLOAT")
            fmt.attr_add(id="normal", comp_type="F32", len=3, fetch_mode="FLOAT")
            fmt.attr_add(id="face_normal", comp_type="F32", len=3, fetch_mode="FLOAT")
            fmt.attr_add(id="uv", comp_type="F32", len=2, fetch_mode="FLOAT")
            fmt.attr_add(id="object_index", comp_type="F32", len=1, fetch_mode="FLOAT")
            vbo = gpu.types.GPUVertBuf(fmt, 3 * count)

            def fill(name, array, width):
                vbo.attr_fill(id=name, data=np.ascontiguousarray(
                    np.asarray(array, np.float32).reshape(3 * count, width)))

            fill("position", positions, 3)
            fill("normal", np.asarray(geometry.normals)[order], 3)
            fill("face_normal", face_normals, 3)
            fill("uv", np.asarray(geometry.uvs)[order], 2)
            # Exact as a float up to 2^24 objects.
            fill("object_index", np.repeat(np.asarray(geometry.object_index, np.float64)[order], 3), 1)
            self.vertex_buffer = vbo
            self.batch = gpu.types.GPUBatch(type="TRIS", buf=vbo)
        self._images: dict[int, object] = {}
        self._white = None
        self._light_links = None
        self._non_blockers = None
        self._points: dict = {}
        self._point_textures: dict = {}

    def material_image(self, material_index: int):
        """The base colour texture of a material, or a 1x1 white one (uploaded once)."""
        material = self.scene.materials[material_index]
        if material.base_color_image is None:
            if self._white is None:
                self._white = texture_from_array(np.ones((1, 1, 4), np.float32))
            return self._white
        if material_index not in self._images:
            self._images[material_index] = texture_from_array(np.asarray(material.base_color_image, np.float32))
        return self._images[material_index]

    def light_links(self):
        """The scene's light and shadow links and ray visibility (SceneDescription.light_links) as one
        RGBA32F texture for glsl/lib/light_links.glsl: object o of light l at texel
        (o mod LIGHT_LINKS_WIDTH, l * rows + o div LIGHT_LINKS_WIDTH), ``rows`` per light (uploaded
        once; a 1 x 1 texture when no light or object uses them)."""
        if self._light_links is None:
            self._light_links = texture_from_array(light_links_array(self.scene))
        return self._light_links

    def scene_points(self, points_per_set: int, set_count: int, seed: int):
        """The scene's surface point sets for imperfect shadow maps (scene_points.scene_point_sets),
        drawn once per upload and settings: a static scene's maps do not change."""
        from ..scene_points import cached_scene_point_sets

        key = (int(points_per_set), int(set_count), int(seed))
        if key not in self._points:
            self._points[key] = cached_scene_point_sets(self.scene.geometry, *key)
        return self._points[key]

    def point_textures(self, points_per_set: int, set_count: int, seed: int) -> tuple:
        """passes/ism.py upload_points of :meth:`scene_points`, uploaded once per upload and settings:
        every VSGL set of a frame (up to three) splats the same point sets."""
        from .ism import upload_points

        key = (int(points_per_set), int(set_count), int(seed))
        if key not in self._point_textures:
            if self._point_cache is not None:
                self._point_textures[key] = self._point_cache.textures(
                    self.scene.geometry, *key, lambda: upload_points(self.scene_points(*key)))
            else:
                self._point_textures[key] = upload_points(self.scene_points(*key))
        return self._point_textures[key]

    def has_non_blockers(self, light_index: int) -> bool:
        """Whether some object does not block light ``light_index`` (shadow linking, or an object
        that casts no shadow): its RSM then takes two draws."""
        if light_links_rows(self.scene) == 0:
            return False
        if self._non_blockers is None:
            self._non_blockers = (self.scene.light_links()[..., LINK_BLOCKS] < 0.5).any(axis=1)
        return bool(self._non_blockers[light_index])

    def draw(self, program, per_material=None) -> None:
        """Draw every material's triangles with ``program`` (bound, with the interface of
        :func:`scene_shader_interface`), setting the per-material inputs first;
        ``per_material(program, material_index)`` sets a pass's own per-material uniforms."""
        for material_index, first, count in self.ranges:
            material = self.scene.materials[material_index]
            use_image = material.base_color_image is not None
            program.uniform_float("material_base_color",
                                  (*np.asarray(material.base_color, float)[:3], 1.0 if use_image else 0.0))
            program.uniform_float("material_params", (float(material.roughness), float(material.metallic),
                                                      float(material.specular_ior_level), float(material.ior)))
            program.uniform_sampler("base_color_image", self.material_image(material_index))
            if per_material is not None:
                per_material(program, material_index)
            self.batch.draw_range(program, elem_start=first, elem_count=count)

    def free(self) -> None:
        """Drop the GPU objects (Blender frees them with their last reference)."""
        self.batch = None
        self.vertex_buffer = None
        self._images.clear()
        self._point_textures.clear()
        self._white = None
        self._light_links = None


#: Objects per texture row of the light-links texture (glsl/lib/light_links.glsl's LIGHT_LINKS_WIDTH).
LIGHT_LINKS_WIDTH = 4096


def light_links_rows(scene) -> int:
    """Texture rows per light of the light-links texture (0 when the scene uses no links)."""
    if not scene.uses_light_links or not scene.lights:
        return 0
    return max(1, -(-len(scene.object_names) // LIGHT_LINKS_WIDTH))


def light_links_array(scene) -> np.ndarray:
    """(rows x lights, width, 4) float32 of :meth:`SceneGPU.light_links` (1 x 1 when unused)."""
    rows = light_links_rows(scene)
    if rows == 0:
        return np.ones((1, 1, 4), np.float32)
    table = scene.light_links()  # (L, O, 4)
    lights, objects = table.shape[:2]
    width = min(objects, LIGHT_LINKS_WIDTH) if objects else 1
    padded = np.ones((lights, rows * width, 4), np.float32)
    padded[:, :objects] = table
    return np.ascontiguousarray(padded.reshape(lights * rows, width, 4))
