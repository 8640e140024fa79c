# SPDX-License-Identifier: GPL-3.0-or-later
"""Reflective shadow maps (RSMs) on the GPU: one VPL per texel (formulas.md §4; 000 §4).
Never touches ``bpy.context``: takes the plain :class:`SceneDescription`.

    scene_gpu = SceneGPU(scene)                       # triangles uploaded once per scene
    views = render_rsm_views(scene_gpu, light_index, size=256)
    arrays = views[0].to_numpy()                       # RSMArrays: .rsm is reference.vsgl.RSM
    for view in views: view.free()
    scene_gpu.free()

**Views per light**: :func:`vsgl_addon.views.light_view_specs` (pure numpy): a spot's perspective
view or cube faces, a point light's cube, an area light's five front faces, a sun's orthographic
view fitted to what the camera sees; views whose frustum holds no triangle are not rendered, so a
light that hits nothing yields no views (zero flux).

**Per texel** (RGBA32F, at most 6 colour attachments; the layout
:class:`~vsgl_addon.passes.vsgl_generation.RSMTextures` reads, so the textures feed VSGL generation
directly): ``position`` (y, λs), ``normal`` (n facing the light, Principled roughness),
``flux_diffuse`` (Φ·Rd, Φ₁), ``flux_specular`` (Φ·Rs, dω), ``specular_axis`` (ξs, coverage), and a
32-bit float depth attachment (the light's shadow map). Φ₁ is the texel flux of a white light, Φ = Φ₁ ×
light colour; dω is the texel's solid angle (sr), or its area on the sun's plane (m²) for a sun.
Texels that see nothing are all zero. Texture rows start at the bottom of the view (row 0 =
NDC y = −1), as ``GPUTexture.read`` returns them; ``to_numpy`` keeps that order.

**Model** (documented in, and tested against, :mod:`vsgl_addon.reference.rsm`). The lights are
Blender's emission model shared with the direct light (``glsl/lib/light_emission.glsl``,
:mod:`vsgl_addon.reference.lights`). The reflectances are the Principled BSDF base layer the
direct light uses (``glsl/lib/principled.glsl``, :mod:`vsgl_addon.reference.principled`, calibrated
against Cycles) for the texel's incidence ω' (towards the light): Rd = base × (1 − metallic) ×
(1 − E_spec(n·ω')), the flux the dielectric layer lets through to the diffuse base, and Rs the
specular lobes' directional albedo for ω' (real dielectric Fresnel, metallic Schlick, multiple
scattering), so Φ·Rd and Φ·Rs are the powers the texel's diffuse and (normalized, 000 Eq. 7)
specular lobes reflect. The base colour image is sampled as Blender's Linear/Repeat Image Texture
(``glsl/lib/image.glsl``), as in the G-buffer.

Accuracy. A texel's flux is exact up to float32 (the texel solid angle is integrated, not the
midpoint cos³ rule: see ``glsl/rsm/rsm.frag.glsl``); a total over a surface errs only by coverage
at the surface's silhouette (texel centres decide), which is O(1/size): for a 6 m plane 1 m under
a point light (edges seen at 18° by the cube's side faces) +2.3 % at 32², −1.1 % at 64²,
+0.58 % at 128², −0.29 % at 256², +0.14 % at 512²; a spot's cone inside a plane: below 0.01 %
from 64² on (tests/test_rsm.py).

Not modelled (documented approximations): the size and shape of area lights and their spread (a
Lambertian point emitter), the radius of point and spot lights, the sun's angle; geometry closer
to a point, spot or area light than ``vsgl_addon.views.NEAR_FRACTION`` of its view's far plane is
clipped.

Each :class:`RSMView` keeps its light's ``view_matrix`` (world → light view, rotation and
translation) and ``projection_matrix`` (OpenGL clip space) for shadow lookups.

Needs a GPU context (:func:`vsgl_addon.gpu_context.ensure_gpu_context`), main thread. The shader is
compiled once per process (:func:`shader`, :func:`free_shaders`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..layouts import PROXY_TABLE, RSM as RSM_LAYOUT, RSM_VIEW
from ..reference.lights import light_params
from ..reference.vsgl import RSM
from ..views import RSMViewSpec, light_view_specs, view_sees_triangles
from .contract import LIGHT_PASSES, GPUPass, ShaderSpec
from .gpu_util import matrix, read_texture, texture_from_array
from ..scene_description import RECEIVER_LOBES
from .scene_gpu import VERTEX_STAGE, SceneGPU, light_links_rows, scene_shader_interface

#: Largest RSM side (a 2048² view holds five 64 MB colour textures).
MAX_RSM_SIZE = 4096

#: The colour attachments, in the order of :data:`vsgl_addon.layouts.RSM`.
ATTACHMENTS = RSM_LAYOUT.slot_names


# --- Shader ------------------------------------------------------------------------------------


def _interface():
    return scene_shader_interface(
        # (perspective 1 / ortho 0, half extent x, y, size)
        # (objects drawn, receiver lobe): see glsl/rsm/rsm.frag.glsl
        push_constants=[("VEC4", "view_params"), ("IVEC2", "rsm_mode")],
        # view_constants: a one-column RGBA32F table, vsgl_addon.layouts.RSM_VIEW (_view_constants);
        # light_links: SceneGPU.light_links (glsl/lib/light_links.glsl).
        # proxy_table: the rectangle proxies whose specular flux the glossy receivers' VSGLs leave
        # to MRP-ASG (vsgl_addon/proxies.py proxy_table_array; glsl/rsm/rsm.frag.glsl).
        samplers=[("FLOAT_2D", "view_constants"), ("FLOAT_2D", "light_links"), ("FLOAT_2D", "proxy_table")],
        fragment_outputs=[("VEC4", f"rsm_{name}") for name in RSM_LAYOUT.slot_names],
    )


def shader(split_draws: bool = True):
    """The RSM shader (glsl/rsm/rsm.frag.glsl after the scene's vertex stage), compiled on first use
    and cached for the process. ``split_draws``: the variant whose draws cover the blockers or the
    rest (rsm_mode.x); else the one that draws every object (DRAW_ALL) and never discards."""
    return PASS.shader("rsm" if split_draws else "rsm_one_draw")


def free_shaders() -> None:
    PASS.free_shaders()


# --- Rendering ---------------------------------------------------------------------------------


@dataclass
class RSMArrays:
    """An RSM view read back: the reference's :class:`RSM` and the texel quantities behind it.

    Arrays (H, W, ...), row 0 at the bottom of the view.
    """

    rsm: RSM
    flux: np.ndarray  # (H, W, 3) Φ per texel, W (RGB: Φ₁ × light colour)
    flux_white: np.ndarray  # (H, W) Φ₁, the texel flux of a white light
    texel_measure: np.ndarray  # (H, W) solid angle (sr), or area on the sun's plane (m²) for a sun
    roughness: np.ndarray  # (H, W) Principled roughness
    coverage: np.ndarray  # (H, W) bool, the texel sees geometry
    depth: np.ndarray  # (H, W) window depth in [0, 1] (1 = nothing)


@dataclass
class RSMView:
    """One rendered RSM view of a light: GPU textures plus the view's matrices."""

    light_index: int
    light: object
    spec: RSMViewSpec
    size: int
    textures: dict = field(default_factory=dict)  # ATTACHMENTS names and "depth" -> GPUTexture
    framebuffer: object = None
    constants: object = None  # the 10x1 view-constants texture the draw read

    @property
    def view_matrix(self) -> np.ndarray:
        return self.spec.view_matrix

    @property
    def projection_matrix(self) -> np.ndarray:
        return self.spec.projection_matrix

    def rsm_textures(self):
        """The view as VSGL generation's ``RSMTextures`` (no copy)."""
        from .vsgl_generation import RSMTextures

        return RSMTextures(self.size, **{name: self.textures[name] for name in RSM_LAYOUT.slot_names})

    def to_numpy(self) -> RSMArrays:
        s = self.size
        texels = {name: read_texture(self.textures[name], s, s) for name in RSM_LAYOUT.slot_names}
        fields = RSM_LAYOUT.unpack_slots(texels)
        depth = read_texture(self.textures["depth"], s, s, 1)[..., 0].astype(np.float64)
        rsm = RSM(
            position=fields["position"],
            normal=fields["normal"],
            flux_diffuse=fields["flux_diffuse"],
            flux_specular=fields["flux_specular"],
            specular_axis=fields["specular_axis"],
            specular_sharpness=fields["specular_sharpness"],
        )
        flux_white = fields["flux_white"]
        return RSMArrays(
            rsm=rsm,
            flux=flux_white[..., None] * np.asarray(self.light.color, np.float64),
            flux_white=flux_white,
            texel_measure=fields["texel_measure"],
            roughness=fields["roughness"],
            coverage=fields["coverage"] > 0.5,
            depth=depth,
        )

    def free(self) -> None:
        """Release the view's textures and framebuffer (Blender frees them with their last
        reference; nothing else keeps one)."""
        self.framebuffer = None
        self.constants = None
        self.textures.clear()


def _view_constants(light, spec: RSMViewSpec, light_index: int = 0, links_rows: int = 0,
                    sharp_alpha: float = 0.0) -> np.ndarray:
    """(rows, 1, 4) float32: the per-view constants of glsl/rsm/rsm.frag.glsl (layouts.RSM_VIEW)."""
    view_to_world = spec.view_to_world[:3, :3]
    world_to_local = np.linalg.inv(np.asarray(light.matrix_world, np.float64)[:3, :3])
    axis = np.asarray(light.direction, np.float64)
    values = {f"view_to_world_row{i}": view_to_world[i][None] for i in range(3)}
    values.update({f"world_to_local_row{i}": world_to_local[i][None] for i in range(3)})
    values.update(light_position=np.asarray(light.position, np.float64)[None],
                  light_axis=(axis / np.linalg.norm(axis))[None],
                  light_params=np.asarray(light_params(light), np.float64)[None],
                  light_color=np.asarray(light.color, np.float64)[None],
                  sharp_alpha=np.array([sharp_alpha], np.float64),
                  light_factors=np.array([[light.diffuse_factor, light.specular_factor]], np.float64),
                  light_index=np.array([light_index], np.float64),
                  light_links_rows=np.array([links_rows], np.float64))
    return RSM_VIEW.pack(values, 1)


#: rsm_mode.x of glsl/rsm/rsm.frag.glsl: which objects one draw covers.
DRAW_ALL, DRAW_BLOCKERS, DRAW_NON_BLOCKERS = 0, 1, 2


def _render(scene_gpu: SceneGPU, light_index: int, spec: RSMViewSpec, size: int, textures: dict,
            receiver_lobe: str = "all", proxies=(), sharp_alpha: float = 0.0):
    import gpu

    from ..proxies import proxy_table_array

    light = scene_gpu.scene.lights[light_index]
    targets = [textures[name] for name in RSM_LAYOUT.slot_names]
    framebuffer = gpu.types.GPUFrameBuffer(depth_slot=textures["depth"], color_slots=targets)
    constants = texture_from_array(_view_constants(light, spec, light_index, light_links_rows(scene_gpu.scene),
                                                   sharp_alpha))
    proxy_table = texture_from_array(proxy_table_array(proxies))
    # Shadow linking and objects that cast no shadow: the blockers first, writing depth (the shadow
    # map direct light reads), then the rest depth-tested only, so they reflect light without
    # occluding it (what lies behind such an object is not in the map: one layer per texel).
    split = scene_gpu.has_non_blockers(light_index)
    draws = [(DRAW_BLOCKERS, True), (DRAW_NON_BLOCKERS, False)] if split else [(DRAW_ALL, True)]
    program = shader(split)
    with framebuffer.bind():
        framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
        gpu.state.viewport_set(0, 0, size, size)
        gpu.state.blend_set("NONE")
        gpu.state.depth_test_set("LESS")
        gpu.state.face_culling_set("NONE")
        program.bind()
        program.uniform_float("view_projection", matrix(spec.view_projection))
        program.uniform_sampler("view_constants", constants)
        program.uniform_sampler("light_links", scene_gpu.light_links())
        program.uniform_sampler("proxy_table", proxy_table)
        program.uniform_float("view_params", (1.0 if spec.perspective else 0.0, spec.half_extent[0],
                                              spec.half_extent[1], float(size)))
        for draw, writes_depth in draws:
            gpu.state.depth_mask_set(writes_depth)
            program.uniform_int("rsm_mode", (draw, RECEIVER_LOBES.index(receiver_lobe)))
            scene_gpu.draw(program)
        gpu.state.depth_test_set("NONE")
        gpu.state.depth_mask_set(False)
    return framebuffer, constants


def visible_view_specs(scene_gpu: SceneGPU, light) -> list[RSMViewSpec]:
    """The views of ``light`` that render_rsm_views renders: those whose frustum holds a triangle."""
    return [spec for spec in light_view_specs(scene_gpu.scene, light, scene_gpu.bounds)
            if view_sees_triangles(spec, scene_gpu.positions, scene_gpu.bounds)]


def render_rsm_views(scene, light_index: int, size: int = 256, receiver_lobe: str = "all",
                     proxies=(), sharp_alpha: float = 0.0, specs=None) -> list[RSMView]:
    """Render the RSM views of ``scene.lights[light_index]`` at ``size`` x ``size`` texels.

    ``scene`` is a :class:`SceneGPU` (reuse it for every light) or a SceneDescription (uploaded for
    this call only). Views whose frustum holds no triangle are skipped, so a light that hits
    nothing returns []. Free each view with :meth:`RSMView.free` when done. ``receiver_lobe``
    (scene_description.RECEIVER_LOBES) keeps only the flux of reflectors seen by diffuse or by
    glossy rays; with ``receiver_lobe="glossy"``, texels on one of ``proxies``
    (:class:`~vsgl_addon.proxies.RectangleProxy`) keep no specular flux: MRP-ASG carries that light
    to the receivers' glossy lobes (light-paths.md). ``sharp_alpha`` > 0: texels whose GGX α
    (principled_alpha) is below it keep no specular flux either, the glossy VPLs (passes/vpl_culling.py)
    carry it to the receivers' diffuse lobes (the diffuse receivers' VSGLs with the VPL pass on).
    ``specs``: the light's :func:`visible_view_specs`, when the caller has them already.
    """
    import gpu

    size = int(size)
    if not 1 <= size <= MAX_RSM_SIZE:
        raise ValueError(f"RSM size must be in [1, {MAX_RSM_SIZE}], not {size}")
    scene_gpu = scene if isinstance(scene, SceneGPU) else SceneGPU(scene)
    light = scene_gpu.scene.lights[light_index]
    views = []
    for spec in visible_view_specs(scene_gpu, light) if specs is None else specs:
        textures = {name: gpu.types.GPUTexture((size, size), format="RGBA32F") for name in RSM_LAYOUT.slot_names}
        textures["depth"] = gpu.types.GPUTexture((size, size), format="DEPTH_COMPONENT32F")
        framebuffer, constants = _render(scene_gpu, light_index, spec, size, textures, receiver_lobe, proxies,
                                         sharp_alpha)
        views.append(RSMView(light_index, light, spec, size, textures, framebuffer, constants))
    return views


def total_flux(views: list[RSMView]) -> dict[str, np.ndarray]:
    """Sums over every texel of the views (read back, float64): Φ, Φ·Rd, Φ·Rs (RGB, W)."""
    totals = {"flux": np.zeros(3), "flux_diffuse": np.zeros(3), "flux_specular": np.zeros(3)}
    for view in views:
        arrays = view.to_numpy()
        totals["flux"] += arrays.flux.reshape(-1, 3).sum(axis=0)
        totals["flux_diffuse"] += arrays.rsm.flux_diffuse.reshape(-1, 3).sum(axis=0)
        totals["flux_specular"] += arrays.rsm.flux_specular.reshape(-1, 3).sum(axis=0)
    return totals


PASS = GPUPass(
    name="rsm",
    label="Reflective Shadow Maps",
    step=LIGHT_PASSES,
    shaders={key: ShaderSpec(_interface, {"vertex": VERTEX_STAGE, "fragment": "rsm/rsm.frag.glsl"},
                             defines=lambda split=split: {"RSM_SPLIT_DRAWS": int(split)},
                             code=lambda: {"fragment": RSM_LAYOUT.glsl("outputs_store")
                                                       + RSM_VIEW.glsl("sampler_load")
                                                       + PROXY_TABLE.glsl("sampler_load")})
             for key, split in (("rsm", True), ("rsm_one_draw", False))},
    reads=("scene",),
    writes=(RSM_LAYOUT.name, "rsm_depth"),
    run=render_rsm_views,
)
