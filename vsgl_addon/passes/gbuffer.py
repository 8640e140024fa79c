# SPDX-License-Identifier: GPL-3.0-or-later
"""Camera G-buffer on the GPU: what the camera sees, per pixel, for direct light and VSGL shading.
Never touches ``bpy.context``: takes a :class:`~vsgl_addon.passes.scene_gpu.SceneGPU`
(the scene's triangles, uploaded once and shared with the RSM pass), the camera's view and
projection matrices and a resolution.

    scene_gpu = SceneGPU(scene)
    gbuffer = render_gbuffer(scene_gpu, camera.view_matrix(), camera.projection_matrix(), (w, h))
    arrays = gbuffer.to_numpy()          # dict of (h, w, 4) float32, row 0 = bottom
    gbuffer.free()

**Layout** (RGBA32F colour attachments, names of ``ATTACHMENTS`` = keys of ``GBuffer.textures``;
row 0 = the bottom of the image, as ``GPUTexture.read`` returns it):

=============  =======================================  =====================================
texture        .rgb                                     .a
=============  =======================================  =====================================
``position``   world position (m)                       coverage: 1 geometry, 0 background
``normal``     world shading normal (unit), flipped     Principled roughness (perceptual,
               to face the camera (two-sided)           α = roughness²)
``base_color`` base colour, scene-linear (the image     metallic
               texture sampled at the UV when present)
``material``   (Specular IOR Level, IOR,                1 (coverage)
               material index into scene.materials)
``depth``      DEPTH_COMPONENT32F window depth [0, 1] of the camera's projection (1 = background)
=============  =======================================  =====================================

Background pixels are all zero in every colour attachment. The view direction of a pixel is
``camera_position − position`` for a perspective camera, ``GBuffer.view_direction`` (towards the
camera) for an orthographic one: ``GBuffer.camera_vector`` holds (position, 1) or (direction, 0),
the form the shading passes take as a uniform. The effective Principled reflectances (diffuse albedo
under the dielectric layer, Fresnel, multiple scattering) are view-dependent and computed by the
shading passes from these inputs with ``glsl/lib/principled.glsl``.

Needs a GPU context, main thread. The shader is compiled once per process.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..layouts import GBUFFER
from ..views import camera_vector
from .contract import GPUPass, ShaderSpec, Step
from .gpu_util import matrix, read_texture
from .scene_gpu import VERTEX_STAGE, SceneGPU, scene_shader_interface

#: The colour attachments, in the order of :data:`vsgl_addon.layouts.GBUFFER`.
ATTACHMENTS = GBUFFER.slot_names

#: Largest G-buffer side (the GPU's texture limit on llvmpipe and most GPUs).
MAX_SIDE = 16384


def _interface():
    return scene_shader_interface(
        push_constants=[
            ("VEC4", "camera"),  # (position, 1) perspective or (towards the camera, 0) ortho
            ("FLOAT", "material_index"),
        ],
        samplers=[],
        fragment_outputs=[("VEC4", f"gbuffer_{name}") for name in GBUFFER.slot_names],
    )


def shader():
    """The G-buffer shader (glsl/gbuffer/gbuffer.frag.glsl after the scene's vertex stage),
    compiled on first use and cached for the process."""
    return PASS.shader()


def free_shaders() -> None:
    PASS.free_shaders()


@dataclass
class GBuffer:
    """The camera G-buffer on the GPU (see the module documentation for the layout)."""

    width: int
    height: int
    view_matrix: np.ndarray
    projection_matrix: np.ndarray
    textures: dict = field(default_factory=dict)  # ATTACHMENTS and "depth" -> GPUTexture
    framebuffer: object = None

    @property
    def camera_vector(self) -> np.ndarray:
        return camera_vector(self.view_matrix, self.projection_matrix)

    def to_numpy(self) -> dict[str, np.ndarray]:
        """Every attachment read back: (h, w, 4) float32 colour, "depth" (h, w); row 0 = bottom."""
        out = {name: read_texture(self.textures[name], self.width, self.height) for name in GBUFFER.slot_names}
        out["depth"] = read_texture(self.textures["depth"], self.width, self.height, 1)[..., 0]
        return out

    def free(self) -> None:
        self.framebuffer = None
        self.textures.clear()


def render_gbuffer(scene_gpu: SceneGPU, view_matrix, projection_matrix, resolution) -> GBuffer:
    """Rasterise the scene from the camera into a new :class:`GBuffer` of ``resolution`` (w, h)."""
    import gpu

    width, height = (int(v) for v in resolution)
    if not (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE):
        raise ValueError(f"G-buffer resolution must be within 1..{MAX_SIDE} per side, not {resolution}")
    view = np.asarray(view_matrix, np.float64)
    projection = np.asarray(projection_matrix, np.float64)
    names = GBUFFER.slot_names
    textures = {name: gpu.types.GPUTexture((width, height), format="RGBA32F") for name in names}
    textures["depth"] = gpu.types.GPUTexture((width, height), format="DEPTH_COMPONENT32F")
    framebuffer = gpu.types.GPUFrameBuffer(depth_slot=textures["depth"],
                                           color_slots=[textures[name] for name in names])
    with framebuffer.bind():
        framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
        if scene_gpu.batch is not None:
            program = shader()
            gpu.state.viewport_set(0, 0, width, height)
            gpu.state.blend_set("NONE")
            gpu.state.depth_test_set("LESS")
            gpu.state.depth_mask_set(True)
            gpu.state.face_culling_set("NONE")
            program.bind()
            program.uniform_float("view_projection", matrix(projection @ view))
            program.uniform_float("camera", tuple(float(v) for v in camera_vector(view, projection)))
            scene_gpu.draw(program, lambda program, index: program.uniform_float("material_index",
                                                                                 float(index)))
            gpu.state.depth_test_set("NONE")
            gpu.state.depth_mask_set(False)
    return GBuffer(width, height, view, projection, textures, framebuffer)


def render_camera_gbuffer(scene_gpu: SceneGPU, resolution=None) -> GBuffer:
    """The G-buffer of the scene's camera at ``resolution`` (default: the camera's)."""
    camera = scene_gpu.scene.camera
    if camera is None:
        raise ValueError("the scene has no camera")
    return render_gbuffer(scene_gpu, camera.view_matrix(), camera.projection_matrix(),
                          resolution or camera.resolution)


PASS = GPUPass(
    name="gbuffer",
    label="G-Buffer",
    step=Step("gbuffer", "G-Buffer"),
    shaders={"gbuffer": ShaderSpec(_interface, {"vertex": VERTEX_STAGE, "fragment": "gbuffer/gbuffer.frag.glsl"},
                                   code=lambda: {"fragment": GBUFFER.glsl("outputs_store")})},
    reads=("scene",),
    writes=(GBUFFER.name, "camera_depth"),
    run=render_gbuffer,
)
