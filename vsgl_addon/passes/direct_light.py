# SPDX-License-Identifier: GPL-3.0-or-later
"""Direct light on the GPU: spot, point, sun and area lights over the camera G-buffer, with shadows
from the lights' RSM depth, Principled diffuse + GGX specular in Blender's units.
Never touches ``bpy.context``.

    scene_gpu = SceneGPU(scene)
    gbuffer = render_camera_gbuffer(scene_gpu)
    views = {i: render_rsm_views(scene_gpu, i, size=256) for i in range(len(scene.lights))}
    direct = render_direct_light(gbuffer, scene.lights, views)
    diffuse, glossy = direct.to_numpy()        # (h, w, 3) float32 each, row 0 = bottom
    direct.free()

Output per pixel (two RGBA32F textures, alpha 0): **diffuse direct** and **glossy direct** radiance
towards the camera, RGB, W/(m²·sr), summed over the lights — what Cycles' Diffuse Direct × Diffuse
Color and Glossy Direct × Glossy Color hold. Background pixels are 0.

Light model (formulas.md §4; float64 twins :mod:`vsgl_addon.reference.direct_light` and
:mod:`vsgl_addon.reference.lights`, GLSL ``glsl/direct_light/light_at_surface.glsl`` on the
emission model ``glsl/lib/light_emission.glsl`` the RSM shares): point and spot P/(4π) W/sr (spot:
Blender's cone smoothstep), sun S W/m², area lights as Lambertian point emitters
I(θ) = (P/π) cos θ from their centre; light radius / sun angle are not modelled (hard shadows). The
light's colour and its diffuse/specular factors multiply the result. Material:
:mod:`vsgl_addon.reference.principled` (Cycles' Principled BSDF base layer: Lambert under a
dielectric GGX layer, metallic GGX, multiple scattering).

Shadows: for each light, the first of its RSM views whose frustum contains the point decides (a
point light's cube face by direction); the point, pushed along its normal by ``normal_offset``
texels of that view's footprint, is lit when its linear depth is within ``depth_bias`` texels
(× (1 + tan θ), θ the light's incidence, tan capped at 8) of the RSM's stored depth. The test is
filtered by bilinear percentage-closer filtering over the 2×2 texels around the point: the
nearest-texel test box-filtered over one texel, so a shadow edge is a ramp one texel wide, not the
map's staircase magnified on screen (the light's size is not modelled: the penumbra is the map's,
not Cycles'). The per-view lookup and depth comparison are the shared ``glsl/lib/shadow.glsl``
(float64 twin: the ``shadow_*`` functions and ``direct_light_visibility`` of
:mod:`vsgl_addon.reference.direct_light`). A point
inside no view (outside a spot's frustum, behind an area light) is unlit. Without views for a light
(it hits nothing) the light is skipped; ``shadows=False`` ignores the views and lights every point
in front of the light.

One full-screen draw per light, added by blending; each draw re-derives the pixel's Principled
terms (an 8×8 + 4×4×4 albedo quadrature, see principled.glsl). Shader compiled once per process.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..layouts import GBUFFER
from ..reference.lights import light_params
from ..shaders import ShaderInterface
from .contract import GPUPass, ShaderSpec, Step
from .gbuffer import ATTACHMENTS as GBUFFER_ATTACHMENTS
from .gpu_util import fullscreen_triangle_batch, read_texture, texture_from_array
from .scene_gpu import light_links_rows

MAX_VIEWS = 6
#: Defaults of the shadow test, in texels of the RSM view at the point.
NORMAL_OFFSET = 1.0
DEPTH_BIAS = 1.0


def _interface() -> ShaderInterface:
    samplers = [("FLOAT_2D", f"gbuffer_{name}") for name in GBUFFER_ATTACHMENTS]
    samplers += [("FLOAT_2D", "light_constants"), ("FLOAT_2D", "light_links")]
    samplers += [("FLOAT_2D", f"rsm_depth_{k}") for k in range(MAX_VIEWS)]
    return ShaderInterface(
        push_constants=[("VEC4", "camera"), ("VEC4", "shadow_params")],
        samplers=samplers,
        vertex_inputs=[("VEC2", "position")],
        varyings=[("VEC2", "uv")],
        fragment_outputs=[("VEC4", "direct_diffuse"), ("VEC4", "direct_glossy")],
    )


def shader():
    """The direct-light shader (glsl/direct_light/), compiled on first use and cached."""
    return PASS.shader()


def free_shaders() -> None:
    PASS.free_shaders()


def _fullscreen_batch():
    return PASS.resource("fullscreen_triangle", lambda: fullscreen_triangle_batch(shader()))


def _no_links():
    """A 1×1 light-links texture for scenes without light linking (never read: rows 0)."""
    return PASS.resource("no_links", lambda: texture_from_array(np.ones((1, 1, 4), np.float32)))


def _dummy():
    """A 1×1 depth texture for the unused view slots (never read)."""
    import gpu

    return PASS.resource("dummy_depth", lambda: gpu.types.GPUTexture((1, 1), format="DEPTH_COMPONENT32F"))


def light_constants(light, views, light_index: int = 0, links_rows: int = 0) -> np.ndarray:
    """(1, 8 + 5·MAX_VIEWS, 4) float32: the per-light constants of direct_light.frag.glsl."""
    constants = np.zeros((1, 8 + 5 * MAX_VIEWS, 4), np.float32)
    constants[0, 0] = (*np.asarray(light.position, np.float64), float(len(views)))
    axis = np.asarray(light.direction, np.float64)
    constants[0, 1, :3] = axis / np.linalg.norm(axis)
    constants[0, 2] = light_params(light)
    constants[0, 3, :3] = np.asarray(light.color, np.float64)
    constants[0, 4] = (float(light.diffuse_factor), float(light.specular_factor), float(light_index),
                       float(links_rows))
    constants[0, 5:8, :3] = np.linalg.inv(np.asarray(light.matrix_world, np.float64)[:3, :3])
    for k, view in enumerate(views[:MAX_VIEWS]):
        base = 8 + 5 * k
        projection = np.asarray(view.projection_matrix, np.float64)
        constants[0, base:base + 4] = projection @ np.asarray(view.view_matrix, np.float64)
        perspective = abs(projection[3, 3]) < 0.5
        constants[0, base + 4] = (1.0 if perspective else 0.0, projection[0, 0], projection[2, 2],
                                  projection[2, 3])
    return constants


@dataclass
class DirectLight:
    """Diffuse and glossy direct radiance on the GPU (RGBA32F, alpha 0)."""

    width: int
    height: int
    textures: dict = field(default_factory=dict)  # "diffuse", "glossy" -> GPUTexture
    framebuffer: object = None
    seconds: float = 0.0

    def to_numpy(self) -> tuple[np.ndarray, np.ndarray]:
        """(diffuse, glossy) as (h, w, 3) float32, row 0 = bottom."""
        return tuple(read_texture(self.textures[name], self.width, self.height)[..., :3]
                     for name in ("diffuse", "glossy"))

    def free(self) -> None:
        self.framebuffer = None
        self.textures.clear()


def render_direct_light(gbuffer, lights, views_by_light, *, shadows: bool = True,
                        normal_offset: float = NORMAL_OFFSET, depth_bias: float = DEPTH_BIAS,
                        scene_gpu=None) -> DirectLight:
    """Direct light of ``lights`` (a sequence of scene lights) on ``gbuffer``.

    ``views_by_light``: a dict (or sequence) light index -> list of :class:`RSMView` of that light
    (``render_rsm_views``); all views must share one RSM size. A light without views is skipped
    when ``shadows`` (it hits nothing), lit unshadowed otherwise. ``scene_gpu`` (the
    :class:`SceneGPU` the G-buffer was drawn from, whose lights ``lights`` are) brings the lights'
    receivers (light linking); without it every object receives every light. Shadow linking needs
    nothing here: the RSM depth holds only each light's blockers.
    """
    import time

    import gpu

    start = time.perf_counter()
    width, height = gbuffer.width, gbuffer.height
    textures = {name: gpu.types.GPUTexture((width, height), format="RGBA32F") for name in ("diffuse", "glossy")}
    framebuffer = gpu.types.GPUFrameBuffer(color_slots=[textures["diffuse"], textures["glossy"]])
    program = shader()
    batch = _fullscreen_batch()
    keep_alive = []
    with framebuffer.bind():
        framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0))
        gpu.state.viewport_set(0, 0, width, height)
        gpu.state.depth_test_set("NONE")
        gpu.state.depth_mask_set(False)
        gpu.state.face_culling_set("NONE")
        gpu.state.blend_set("ADDITIVE_PREMULT")
        program.bind()
        program.uniform_float("camera", tuple(float(v) for v in gbuffer.camera_vector))
        links_rows = light_links_rows(scene_gpu.scene) if scene_gpu is not None else 0
        program.uniform_sampler("light_links", scene_gpu.light_links() if links_rows else _no_links())
        for name in GBUFFER_ATTACHMENTS:
            program.uniform_sampler(f"gbuffer_{name}", gbuffer.textures[name])
        for index, light in enumerate(lights):
            views = list(views_by_light.get(index, []) if isinstance(views_by_light, dict)
                         else views_by_light[index])
            if shadows and not views:
                continue
            if len(views) > MAX_VIEWS:
                raise ValueError(f"light {light.name!r} has {len(views)} views, at most {MAX_VIEWS}")
            sizes = {view.size for view in views}
            if len(sizes) > 1:
                raise ValueError(f"light {light.name!r}: RSM views of different sizes {sorted(sizes)}")
            size = sizes.pop() if sizes else 1
            constants = texture_from_array(light_constants(light, views, index, links_rows))
            keep_alive.append(constants)
            program.uniform_sampler("light_constants", constants)
            for k in range(MAX_VIEWS):
                depth = views[k].textures["depth"] if k < len(views) else _dummy()
                program.uniform_sampler(f"rsm_depth_{k}", depth)
            program.uniform_float("shadow_params", (float(size), float(normal_offset), float(depth_bias),
                                                    1.0 if shadows else 0.0))
            batch.draw(program)
        gpu.state.blend_set("NONE")
    result = DirectLight(width, height, textures, framebuffer)
    result.seconds = time.perf_counter() - start
    return result


PASS = GPUPass(
    name="direct_light",
    label="Direct Light",
    step=Step("direct_light", "Direct Light"),
    shaders={"direct_light": ShaderSpec(_interface, {"vertex": "fullscreen_triangle.vert.glsl",
                                                     "fragment": "direct_light/direct_light.frag.glsl"},
                                        code=lambda: {"fragment": GBUFFER.glsl("samplers_load")})},
    reads=("gbuffer", "rsm_depth"),
    writes=("direct_light",),
    run=render_direct_light,
)
