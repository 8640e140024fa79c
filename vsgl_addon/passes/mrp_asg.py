# SPDX-License-Identifier: GPL-3.0-or-later
"""Glossy interreflection from rectangle proxies with MRP-ASG on the GPU (001; formulas.md §8).
Twin of ``vsgl_addon/reference/mrp_asg.py`` (whose module documentation derives every step) through
``glsl/lib/mrp_asg.glsl``; stage ``glsl/mrp_asg/mrp_asg.frag.glsl``.

    pass_ = MRPASG()
    texture = pass_.run(gbuffer, camera, lights, views_by_light, lit, disk_radius=0.1, mode="asg")
    image = pass_.read()          # (h, w, 4) float32, row 0 = bottom
    pass_.free()

Owns one cell of ``light-paths.md``: light → the specular lobe of a sharp glossy rectangle proxy →
the receiver's specular lobe. Per receiver pixel (G-buffer position and normal with GGX α or the
perceptual roughness, the shading inputs' specular F0), per light (one draw, added by blending),
per proxy that light reaches (``lit``: :func:`vsgl_addon.proxies.lit_proxies` pairs): the radiance
001 Eqs. 6–37 give, with the light's shadow at the specular peak from its RSM depth (the direct
light's test), and, given the mirror shadow maps of :mod:`.mrp_visibility`, from the peak to the
receiver (001 assumes no occlusion; that module says what is and is not shadowed).
Output: one RGBA32F texture ``indirect_glossy_reflectors`` (RGB, W/(m² sr), alpha 0), the
``Indirect Glossy Reflectors`` render pass; the renderer adds it to the indirect specular image.

Cost: pixels × Σ over lights of the proxies it reaches. Needs a GPU context, main thread.
"""

from __future__ import annotations

import numpy as np

from ..layouts import GBUFFER, PROXY_TABLE, SHADING_INPUTS
from ..proxies import proxy_table_array
from ..reference.mrp_asg import MODES
from ..shaders import ShaderInterface
from .contract import GPUPass, ShaderSpec, Step
from .direct_light import DEPTH_BIAS, MAX_VIEWS, NORMAL_OFFSET, light_constants
from .gpu_util import fullscreen_triangle_batch, read_texture, set_uniform, texture_from_array


def _interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("VEC4", "camera"), ("VEC4", "mrp_params"), ("VEC4", "shadow_params"),
                        ("VEC4", "receiver_range"), ("VEC4", "mirror_params")],
        samplers=[("FLOAT_2D", "gbuffer_position"), ("FLOAT_2D", "gbuffer_normal"),
                  ("FLOAT_2D", "shading_inputs_specular_f0"), ("FLOAT_2D", "shading_inputs_diffuse_reflectance"),
                  ("FLOAT_2D", "proxy_table"), ("FLOAT_2D", "light_constants"),
                  ("FLOAT_2D", "mirror_depth"), ("FLOAT_2D", "mirror_constants")]
        + [("FLOAT_2D", f"rsm_depth_{k}") for k in range(MAX_VIEWS)],
        vertex_inputs=[("VEC2", "position")],
        varyings=[("VEC2", "uv")],
        fragment_outputs=[("VEC4", "glossy_reflectors")],
    )


def _shader_spec() -> ShaderSpec:
    return ShaderSpec(_interface, {"vertex": "fullscreen_triangle.vert.glsl", "fragment": "mrp_asg/mrp_asg.frag.glsl"},
                      code=lambda: {"fragment": GBUFFER.glsl() + SHADING_INPUTS.glsl("samplers_load")
                                    + PROXY_TABLE.glsl("sampler_load")})


def _composite_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("INT", "gated")],
        samplers=[("FLOAT_2D", "whole_specular"), ("FLOAT_2D", "glossy_specular"), ("FLOAT_2D", "glossy_reflectors")],
        vertex_inputs=[("VEC2", "position")],
        varyings=[("VEC2", "uv")],
        fragment_outputs=[("VEC4", "indirect_specular")],
    )


def _composite_spec() -> ShaderSpec:
    return ShaderSpec(_composite_interface, {"vertex": "fullscreen_triangle.vert.glsl",
                                             "fragment": "mrp_asg/specular_composite.frag.glsl"})


class MRPASG:
    """The pass, keeping its output texture (and framebuffer) between frames."""

    def __init__(self):
        self.texture = None
        self._framebuffer = None
        self._size = None
        self.specular = None
        self._specular_framebuffer = None

    def free(self) -> None:
        self._framebuffer = None
        self.texture = None
        self._size = None
        self._specular_framebuffer = None
        self.specular = None

    def composite_specular(self, whole_specular, glossy_specular, gated: bool):
        """The frame's indirect specular texture (glsl/mrp_asg/specular_composite.frag.glsl) from the
        VSGL shading of every reflector, that of the RSM without the proxies' specular flux and this
        pass's last image, without a read-back; the texture is overwritten by the next call."""
        import gpu

        width, height = self._size
        program = PASS.shader("specular_composite")
        batch = PASS.resource("composite_triangle", lambda: fullscreen_triangle_batch(program))
        if self.specular is None or (self.specular.width, self.specular.height) != (width, height):
            self._specular_framebuffer = None
            self.specular = gpu.types.GPUTexture((width, height), format="RGBA32F")
            self._specular_framebuffer = gpu.types.GPUFrameBuffer(color_slots=[self.specular])
        saved = (gpu.state.blend_get(), gpu.state.depth_test_get(), tuple(gpu.state.viewport_get()))
        try:
            with self._specular_framebuffer.bind():
                gpu.state.viewport_set(0, 0, width, height)
                gpu.state.depth_test_set("NONE")
                gpu.state.blend_set("NONE")
                program.bind()
                program.uniform_int("gated", 1 if gated else 0)
                program.uniform_sampler("whole_specular", whole_specular)
                program.uniform_sampler("glossy_specular", glossy_specular)
                program.uniform_sampler("glossy_reflectors", self.texture)
                batch.draw(program)
        finally:
            gpu.state.blend_set(saved[0])
            gpu.state.depth_test_set(saved[1])
            gpu.state.viewport_set(*saved[2])
        return self.specular

    def _target(self, width: int, height: int) -> None:
        import gpu

        if self._size != (width, height):
            self._framebuffer = None
            self.texture = gpu.types.GPUTexture((width, height), format="RGBA32F")
            self._framebuffer = gpu.types.GPUFrameBuffer(color_slots=[self.texture])
            self._size = (width, height)

    def run(self, gbuffer, camera, lights, views_by_light, lit, disk_radius: float, mode: str = "asg",
            shadows: bool = True, receiver_range=(0.0, 1.0), mirror_maps=None):
        """Shade every pixel of ``gbuffer`` (a passes.vsgl_shading.ShadingGBuffer) with the proxies of
        ``lit`` ((proxy, lit-by mask over ``lights``) pairs) for every light that reaches one;
        ``views_by_light``: light index -> its RSM views (the shadows). ``receiver_range``: the GGX α
        of the receivers shaded (others get 0 and alpha 0; served pixels alpha 1). ``mirror_maps``
        (passes.mrp_visibility.MirrorMaps of the same ``lit``): the proxy-to-receiver shadows; None:
        not shadowed there. Returns the texture."""
        import gpu

        from .vsgl_shading import camera_uniform

        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        if not (np.isfinite(disk_radius) and disk_radius >= 0.0):
            raise ValueError(f"disk radius must be a finite number >= 0, got {disk_radius}")
        program = PASS.shader("mrp_asg")
        batch = PASS.resource("fullscreen_triangle", lambda: fullscreen_triangle_batch(program))
        dummy = PASS.resource("dummy_depth", lambda: gpu.types.GPUTexture((1, 1), format="DEPTH_COMPONENT32F"))
        width, height = int(gbuffer.width), int(gbuffer.height)
        self._target(width, height)
        keep_alive = []
        saved = (gpu.state.blend_get(), gpu.state.depth_test_get(), gpu.state.depth_mask_get(),
                 tuple(gpu.state.viewport_get()))
        try:
            with self._framebuffer.bind():
                self._framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0))
                gpu.state.viewport_set(0, 0, width, height)
                gpu.state.depth_test_set("NONE")
                gpu.state.depth_mask_set(False)
                gpu.state.blend_set("ADDITIVE_PREMULT")
                program.bind()
                set_uniform(program.uniform_float, "camera", camera_uniform(camera))
                set_uniform(program.uniform_float, "receiver_range",
                            (float(receiver_range[0]), float(receiver_range[1]), 0.0, 0.0))
                program.uniform_sampler("gbuffer_position", gbuffer.position)
                program.uniform_sampler("gbuffer_normal", gbuffer.normal)
                program.uniform_sampler("shading_inputs_specular_f0", gbuffer.specular_f0)
                program.uniform_sampler("shading_inputs_diffuse_reflectance", gbuffer.diffuse_reflectance)
                for index, light in enumerate(lights):
                    proxies = [proxy for proxy, mask in lit if mask[index]]
                    views = list(views_by_light.get(index, [])) if isinstance(views_by_light, dict) \
                        else list(views_by_light[index])
                    if not proxies or (shadows and not views):
                        continue
                    if len(views) > MAX_VIEWS:
                        raise ValueError(f"light {light.name!r} has {len(views)} views, at most {MAX_VIEWS}")
                    table = texture_from_array(proxy_table_array(proxies))
                    constants = texture_from_array(light_constants(light, views, index))
                    keep_alive += [table, constants]
                    program.uniform_sampler("proxy_table", table)
                    program.uniform_sampler("light_constants", constants)
                    for k in range(MAX_VIEWS):
                        program.uniform_sampler(f"rsm_depth_{k}", views[k].textures["depth"] if k < len(views) else dummy)
                    mirror = mirror_maps.atlases.get(index) if mirror_maps is not None else None
                    program.uniform_sampler("mirror_depth", mirror[0] if mirror is not None else dummy)
                    program.uniform_sampler("mirror_constants", mirror[1] if mirror is not None else constants)
                    set_uniform(program.uniform_float, "mirror_params",
                                (1.0 if mirror is not None else 0.0,
                                 float(mirror_maps.size) if mirror is not None else 1.0, 0.0, 0.0))
                    size = views[0].size if views else 1
                    set_uniform(program.uniform_float, "mrp_params",
                                (float(disk_radius), float(len(proxies)), float(MODES.index(mode)),
                                 1.0 if gbuffer.roughness_is_perceptual else 0.0))
                    set_uniform(program.uniform_float, "shadow_params",
                                (float(size), NORMAL_OFFSET, DEPTH_BIAS, 1.0 if shadows else 0.0))
                    batch.draw(program)
        finally:
            gpu.state.blend_set(saved[0])
            gpu.state.depth_test_set(saved[1])
            gpu.state.depth_mask_set(saved[2])
            gpu.state.viewport_set(*saved[3])
        return self.texture

    def read(self) -> np.ndarray:
        width, height = self._size
        return read_texture(self.texture, width, height)


def run(gbuffer, camera, lights, views_by_light, lit, disk_radius: float, mode: str = "asg",
        shadows: bool = True, mrp: "MRPASG | None" = None, receiver_range=(0.0, 1.0), mirror_maps=None) -> MRPASG:
    """The pass's entry: a :class:`MRPASG` (new, or ``mrp`` reused) holding the image; ``free()`` it."""
    mrp = MRPASG() if mrp is None else mrp
    mrp.run(gbuffer, camera, lights, views_by_light, lit, disk_radius, mode, shadows, receiver_range, mirror_maps)
    return mrp


PASS = GPUPass(
    name="mrp_asg",
    label="Glossy Reflectors (MRP-ASG)",
    step=Step("mrp_asg", "Glossy Reflectors (MRP-ASG)", {"proxies": "Rectangle Proxies"}),
    shaders={"mrp_asg": _shader_spec(), "specular_composite": _composite_spec()},
    # The proxy table is made from the scene (vsgl_addon/proxies.py), not by an earlier pass.
    reads=(GBUFFER.name, SHADING_INPUTS.name, "scene", "rsm_depth", "mirror_depth"),
    writes=("indirect_glossy_reflectors",),
    run=run,
)
