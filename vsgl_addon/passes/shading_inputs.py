# SPDX-License-Identifier: GPL-3.0-or-later
"""Shading inputs: the camera G-buffer's material -> the reflectances VSGL shading reads.

VSGL shading (vsgl_shading.py, 000 app. C) takes per pixel a diffuse reflectance Rd and a Schlick
F0 for C(ξin). The G-buffer (gbuffer.py) stores Blender's Principled inputs instead (base colour,
metallic, Specular IOR Level, IOR, roughness), and the direct light derives the same terms per
light. This full-screen pass derives them once per frame with the material model calibrated against
Cycles (reference/principled.py, glsl/lib/principled.glsl): Rd = base (1 − metallic)(1 − E_spec(μo))
(Cycles' Diffuse Color), F0 = the dielectric F0 from IOR and level, or the base colour for metals.
Not carried into C(ξin): Cycles' real dielectric Fresnel and multiple-scattering compensation
(measured: 4.7 % on rough metals, 0.2 % on dielectrics for direct light; see test_direct_light.py).

Never touches bpy.context. Shader compiled once per process; outputs are the caller's to free.
"""

from __future__ import annotations

from ..layouts import GBUFFER, SHADING_INPUTS
from ..shaders import ShaderInterface
from .contract import GPUPass, ShaderSpec
from .gpu_util import fullscreen_triangle_batch
from .vsgl_shading import SHADING_STEP, ShadingGBuffer, camera_uniform


def _interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("VEC4", "camera")],
        samplers=[("FLOAT_2D", f"gbuffer_{name}") for name in GBUFFER.slot_names],
        vertex_inputs=[("VEC2", "position")],
        varyings=[("VEC2", "uv")],
        fragment_outputs=[("VEC4", f"shading_inputs_{name}") for name in SHADING_INPUTS.slot_names],
    )


def shader():
    return PASS.shader()


def free_shaders() -> None:
    PASS.free_shaders()


def _fullscreen_batch():
    return PASS.resource("fullscreen_triangle", lambda: fullscreen_triangle_batch(shader()))


def shading_gbuffer(gbuffer) -> ShadingGBuffer:
    """The :class:`ShadingGBuffer` of a camera :class:`~vsgl_addon.passes.gbuffer.GBuffer`: its
    position and normal textures as they are, Rd and F0 from this pass (new textures)."""
    import gpu

    width, height = gbuffer.width, gbuffer.height
    outputs = {name: gpu.types.GPUTexture((width, height), format="RGBA32F") for name in SHADING_INPUTS.slot_names}
    framebuffer = gpu.types.GPUFrameBuffer(color_slots=[outputs[name] for name in SHADING_INPUTS.slot_names])
    program = shader()
    batch = _fullscreen_batch()
    with framebuffer.bind():
        framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0))
        gpu.state.viewport_set(0, 0, width, height)
        gpu.state.depth_test_set("NONE")
        gpu.state.blend_set("NONE")
        program.bind()
        program.uniform_float("camera", camera_uniform(gbuffer.camera_vector))
        for name in GBUFFER.slot_names:
            program.uniform_sampler(f"gbuffer_{name}", gbuffer.textures[name])
        batch.draw(program)
    return ShadingGBuffer(position=gbuffer.textures["position"], normal=gbuffer.textures["normal"],
                          diffuse_reflectance=outputs["diffuse_reflectance"], specular_f0=outputs["specular_f0"],
                          width=width, height=height,
                          roughness_is_perceptual=True)


PASS = GPUPass(
    name="shading_inputs",
    label="Shading Inputs",
    step=SHADING_STEP,
    shaders={"shading_inputs": ShaderSpec(_interface, {"vertex": "fullscreen_triangle.vert.glsl",
                                                       "fragment": "shading_inputs/shading_inputs.frag.glsl"},
                                          code=lambda: {"fragment": GBUFFER.glsl("samplers_load")
                                                                    + SHADING_INPUTS.glsl("outputs_store")})},
    reads=(GBUFFER.name,),
    writes=(SHADING_INPUTS.name,),
    run=shading_gbuffer,
)
