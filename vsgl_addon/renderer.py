# SPDX-License-Identifier: GPL-3.0-or-later
"""One frame from a scene description: the GPU passes in order, and the images they make.

    scene description -> SceneGPU (triangles uploaded once)
                      -> RSM views of every light -> VSGL tables       (pipeline.py; 000 §3-4)
                      -> camera G-buffer -> direct light (RSM-depth shadows)
                                         -> shading inputs -> VSGL shading (000 app. C)
                      -> FrameImages (numpy, linear, Blender's units)

Never touches bpy.context (the engine and the command line do). Needs a GPU context, main thread.
Every GPU resource a frame makes is released before render() returns, or by free().
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .layouts import GBUFFER
from .passes import READ_BACK, UPLOAD, direct_light, gbuffer as gbuffer_pass, ism, mrp_asg, shading_inputs, vsgl_shading
from .passes.contract import LIGHT_PASSES
from .passes.gpu_util import finish
from .passes.rsm import SceneGPU
from .pipeline import build_visibility, render_scene_vsgls, view_receivers
from .planner import PROXY_CACHE, RECEIVER_ALPHA_RANGE, kept_proxies, plan_frame
from .proxies import ProxyCache
from .reference.vsgl_shading import diffuse_mode_for_kernel
from .settings import VSGLSettings


@dataclass
class FrameImages:
    """(H, W, 3) float32 radiance images, W/(m² sr), row 0 at the bottom; coverage (H, W) in [0, 1]."""

    direct_diffuse: np.ndarray
    direct_specular: np.ndarray
    indirect_diffuse: np.ndarray
    indirect_specular: np.ndarray
    coverage: np.ndarray
    timings: dict[str, float] = field(default_factory=dict)  # seconds per pass, GPU finished
    counts: dict[str, int] = field(default_factory=dict)
    # The part of indirect_specular MRP-ASG carries (light reflected by a rectangle proxy onto
    # glossy receivers, 001); None: zeros.
    indirect_glossy_reflectors: np.ndarray | None = None
    plan: object = None  # the planner.FramePlan the frame executed

    def __post_init__(self):
        if self.indirect_glossy_reflectors is None:
            self.indirect_glossy_reflectors = np.zeros_like(self.indirect_specular)

    @property
    def direct(self) -> np.ndarray:
        return self.direct_diffuse + self.direct_specular

    @property
    def indirect(self) -> np.ndarray:
        return self.indirect_diffuse + self.indirect_specular

    @property
    def combined(self) -> np.ndarray:
        return self.direct + self.indirect


def _finish(texture) -> None:
    """Wait for the GPU to finish writing `texture`, so the pass's time is its own."""
    finish(texture)


def _rgb(image: np.ndarray) -> np.ndarray:
    # No NaN or Inf may reach a pixel: a non-finite value is a bug upstream, but the image must stay usable.
    return np.nan_to_num(np.asarray(image[..., :3], np.float32), nan=0.0, posinf=0.0, neginf=0.0)


@dataclass
class SceneLights:
    """The view-independent part of a frame: the scene on the GPU, the RSM views and VSGL tables.

    Built once per scene state and settings; any number of views can then be rendered from it
    (FrameRenderer.render_view) without rerunning the light passes. `free()` releases it all.
    """

    scene: object  # SceneDescription
    scene_gpu: object  # SceneGPU
    vsgls: object  # pipeline.SceneVSGLs: every reflector, or those seen by diffuse rays
    timings: dict[str, float] = field(default_factory=dict)
    # When some object is hidden from diffuse or glossy rays (SceneDescription.receiver_lobe_split),
    # or MRP-ASG carries the proxies' specular light to glossy receivers: the VSGLs of the
    # reflectors glossy rays see (without the proxies' specular flux), for the receivers' specular lobes.
    glossy_vsgls: object = None
    # MRP-ASG (001): (rectangle proxy, lit-by mask over scene.lights) of the proxies the plan keeps.
    proxies: list = field(default_factory=list)
    plan: object = None  # planner.FramePlan: what these light passes ran, and why

    @classmethod
    def build(cls, scene, settings: VSGLSettings, proxy_cache: ProxyCache | None = None,
              view=None) -> "SceneLights":
        """``view``: (view matrix, projection matrix) of the one view the frame is seen from, when
        known, so the plan can skip the work no receiver in it needs and weigh the RSM texels by it
        (the view PDF); None: any view (the viewport)."""
        view_projection = None if view is None else np.asarray(view[1]) @ np.asarray(view[0])
        plan = plan_frame(scene, settings, proxy_cache, view_projection)
        clock = time.perf_counter()
        scene_gpu = SceneGPU(scene)
        timings = {UPLOAD.name: time.perf_counter() - clock}
        proxies = plan.proxies
        sets = []
        try:
            clock = time.perf_counter()
            # The plan's VSGL sets: one, or one per receiver lobe when some object is hidden from
            # diffuse or glossy rays, or MRP-ASG runs (light-paths.md: the proxies' specular light
            # leaves the glossy set).
            receivers = view_receivers(scene_gpu, *view) if plan.runs("view_pdf") else None
            for lobe in plan.receiver_sets:
                sets.append(render_scene_vsgls(scene_gpu, settings, lobe,
                                               [proxy for proxy, _ in proxies] if lobe == "glossy" else (), plan,
                                               receivers))
                if sets[-1].generations:
                    _finish(sets[-1].generations[-1][2].table)
            timings[LIGHT_PASSES.name] = time.perf_counter() - clock
            clock = time.perf_counter()
            if plan.runs("visibility"):
                first_map = 0  # each set's maps draw other point sets
                for table_set in sets:
                    first_map = build_visibility(scene_gpu, table_set, settings, first_map)
                    if table_set.isms:
                        _finish(table_set.isms[-1].texture)
            timings[ism.PASS.step.name] = time.perf_counter() - clock
        except BaseException:
            for table_set in sets:
                table_set.free()
            scene_gpu.free()
            raise
        return cls(scene, scene_gpu, sets[0], timings, sets[1] if len(sets) > 1 else None, proxies, plan)

    def free(self) -> None:
        if self.vsgls is not None:
            self.vsgls.free()
            self.vsgls = None
        if self.glossy_vsgls is not None:
            self.glossy_vsgls.free()
            self.glossy_vsgls = None
        if self.scene_gpu is not None:
            self.scene_gpu.free()
            self.scene_gpu = None


def scene_proxies(scene, settings: VSGLSettings, proxy_cache: ProxyCache | None = None, overrides=None) -> list:
    """(proxy, lit-by mask) of the rectangle proxies of ``scene`` some light reaches
    (planner.kept_proxies), from ``proxy_cache`` or the planner's."""
    return kept_proxies(scene, settings, PROXY_CACHE if proxy_cache is None else proxy_cache, overrides)


@dataclass
class ViewTextures:
    """One view's images left on the GPU (RGBA32F, row 0 at the bottom, all of one size): the
    keys of TEXTURES. ``position`` and ``normal`` are the view's G-buffer attachments (position.a =
    coverage), the guide of joint bilateral upsampling. The indirect textures belong to the
    FrameRenderer and are overwritten by its next view: use them before. `free()` drops the rest."""

    width: int
    height: int
    textures: dict
    counts: dict = field(default_factory=dict)
    gbuffer: object = None  # the view's GBuffer (the guide of a full-resolution render)
    _owned: list = field(default_factory=list)

    TEXTURES = ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular", "position", "normal")

    def free(self) -> None:
        for item in self._owned:
            item.free()
        self._owned.clear()
        self.textures.clear()
        self.gbuffer = None


class FrameRenderer:
    """Renders frames; holds the shading passes' textures between frames (free() releases them)."""

    def __init__(self):
        self._shading = vsgl_shading.VSGLShading()
        self._glossy_shading = None  # the second shading of receiver-lobe split scenes (GPU path)
        self._mrp = mrp_asg.MRPASG()

    def free(self) -> None:
        self._shading.free()
        self._mrp.free()
        if self._glossy_shading is not None:
            self._glossy_shading.free()
            self._glossy_shading = None

    def render_view_textures(self, lights: SceneLights, settings: VSGLSettings, width: int, height: int,
                             view_matrix, projection_matrix) -> ViewTextures:
        """The passes of render_view, with nothing read back: the images stay textures (the
        viewport draws them). No wait for the GPU either: the caller finishes what it times."""
        scene = lights.scene
        gbuffer = direct = None
        try:
            gbuffer = gbuffer_pass.PASS.run(lights.scene_gpu, view_matrix, projection_matrix, (width, height))
            direct = direct_light.PASS.run(gbuffer, scene.lights, lights.vsgls.views_by_light,
                                           scene_gpu=lights.scene_gpu)
            inputs = shading_inputs.PASS.run(gbuffer)
            mode = diffuse_mode_for_kernel(settings.kernel)
            vsgl_shading.PASS.run(inputs, gbuffer.camera_vector, lights.vsgls.tables(), mode, shading=self._shading)
            specular = self._shading.specular
            if lights.glossy_vsgls is not None:
                # The receivers' specular lobes see only the reflectors glossy rays see: their own
                # shading, into textures of their own (no read-back between the two).
                if self._glossy_shading is None:
                    self._glossy_shading = vsgl_shading.VSGLShading()
                vsgl_shading.PASS.run(inputs, gbuffer.camera_vector, lights.glossy_vsgls.tables(), mode,
                                      shading=self._glossy_shading)
                specular = self._glossy_shading.specular
            if lights.proxies:
                # MRP-ASG's cell, composed as render_view composes it, on the GPU.
                gated = not scene.receiver_lobe_split
                mrp_asg.PASS.run(inputs, gbuffer.camera_vector, scene.lights, lights.vsgls.views_by_light,
                                 lights.proxies, settings.disk_radius, settings.reflector_mode, mrp=self._mrp,
                                 receiver_range=RECEIVER_ALPHA_RANGE if gated else (0.0, 1.0))
                specular = self._mrp.composite_specular(self._shading.specular, specular, gated)
        except BaseException:
            for item in (direct, gbuffer):
                if item is not None:
                    item.free()
            raise
        textures = {"direct_diffuse": direct.textures["diffuse"], "direct_specular": direct.textures["glossy"],
                    "indirect_diffuse": self._shading.diffuse, "indirect_specular": specular,
                    "position": gbuffer.textures["position"], "normal": gbuffer.textures["normal"]}
        glossy_count = lights.glossy_vsgls.vsgl_count if lights.glossy_vsgls is not None else 0
        counts = {"lights": len(scene.lights), "vsgls": lights.vsgls.vsgl_count + glossy_count,
                  "triangles": int(len(scene.geometry.positions)), "proxies": len(lights.proxies)}
        return ViewTextures(width, height, textures, counts, gbuffer, [direct, gbuffer])

    def guide(self, lights: SceneLights, width: int, height: int, view_matrix, projection_matrix):
        """The view's G-buffer alone (a GBuffer: position, normal, ...), the full-resolution guide of
        joint bilateral upsampling; the caller frees it."""
        return gbuffer_pass.PASS.run(lights.scene_gpu, view_matrix, projection_matrix, (width, height))

    def render(self, scene, settings: VSGLSettings, width: int, height: int,
               view_matrix=None, projection_matrix=None) -> FrameImages:
        """The frame of `scene` (a SceneDescription) at width × height pixels.

        Seen from the scene's camera, or from `view_matrix` (world -> view, 4×4) and
        `projection_matrix` (OpenGL clip, 4×4; orthographic when [3][3] == 1) when both are given,
        e.g. a 3D viewport's own view.
        """
        if (view_matrix is None) != (projection_matrix is None):
            raise ValueError("give both view_matrix and projection_matrix, or neither")
        if view_matrix is None:
            if scene.camera is None:
                raise ValueError("the scene has no camera")
            view_matrix, projection_matrix = scene.camera.view_matrix(), scene.camera.projection_matrix()
        lights = SceneLights.build(scene, settings, view=(view_matrix, projection_matrix))
        try:
            return self.render_view(lights, settings, width, height, view_matrix, projection_matrix)
        finally:
            lights.free()

    def render_view(self, lights: SceneLights, settings: VSGLSettings, width: int, height: int,
                    view_matrix, projection_matrix) -> FrameImages:
        """One view of already built `lights`: G-buffer, direct light, VSGL shading, read-back.
        `settings` must be the ones `lights` was built with (the kernel picks the diffuse mode)."""
        scene = lights.scene
        timings: dict[str, float] = dict(lights.timings)
        clock = time.perf_counter()

        def lap(name):
            nonlocal clock
            now = time.perf_counter()
            timings[name] = now - clock
            clock = now

        vsgls = lights.vsgls
        gbuffer = direct = None
        try:
            gbuffer = gbuffer_pass.PASS.run(lights.scene_gpu, view_matrix, projection_matrix, (width, height))
            _finish(gbuffer.textures["position"])
            lap(gbuffer_pass.PASS.step.name)
            direct = direct_light.PASS.run(gbuffer, scene.lights, vsgls.views_by_light, scene_gpu=lights.scene_gpu)
            _finish(direct.textures["diffuse"])
            lap(direct_light.PASS.step.name)
            inputs = shading_inputs.PASS.run(gbuffer)
            mode = diffuse_mode_for_kernel(settings.kernel)
            vsgl_shading.PASS.run(inputs, gbuffer.camera_vector, vsgls.tables(), mode, shading=self._shading)
            _finish(self._shading.diffuse)
            glossy = lights.glossy_vsgls
            if glossy is not None:
                # The receivers' specular lobes see only the reflectors glossy rays see: a second
                # shading of the same pixels, after the first one's diffuse image is read.
                indirect_diffuse, whole_specular = self._shading.read()
                vsgl_shading.PASS.run(inputs, gbuffer.camera_vector, glossy.tables(), mode, shading=self._shading)
                _finish(self._shading.diffuse)
            lap(vsgl_shading.PASS.step.name)
            if glossy is not None:
                _, indirect_specular = self._shading.read()
            else:
                indirect_diffuse, indirect_specular = self._shading.read()
            glossy_reflectors = served = None
            # Without Blender's ray-visibility split the first set is every reflector's light, so a
            # receiver outside MRP-ASG's range can take the proxies' light from it instead.
            gated = bool(lights.proxies) and not scene.receiver_lobe_split
            if lights.proxies:
                # MRP-ASG's cell (light-paths.md): proxy-reflected light onto glossy receivers.
                mrp_asg.PASS.run(inputs, gbuffer.camera_vector, scene.lights, vsgls.views_by_light, lights.proxies,
                                 settings.disk_radius, settings.reflector_mode, mrp=self._mrp,
                                 receiver_range=RECEIVER_ALPHA_RANGE if gated else (0.0, 1.0))
                _finish(self._mrp.texture)
            lap(mrp_asg.PASS.step.name)
            if lights.proxies:
                image = self._mrp.read()
                glossy_reflectors = _rgb(image)
                served = image[..., 3] > 0.0
                if gated:
                    indirect_specular = np.where(served[..., None], indirect_specular, whole_specular)
            direct_diffuse, direct_specular = direct.to_numpy()
            coverage = GBUFFER.unpack_slots(gbuffer.to_numpy(), ["coverage"])["coverage"]
            lap(READ_BACK.name)
            glossy_count = lights.glossy_vsgls.vsgl_count if lights.glossy_vsgls is not None else 0
            counts = {"lights": len(scene.lights), "rsm_views": sum(len(v) for v in vsgls.views_by_light.values()),
                      "vsgls": vsgls.vsgl_count + glossy_count, "triangles": int(len(scene.geometry.positions)),
                      "proxies": len(lights.proxies)}
        finally:
            if direct is not None:
                direct.free()
            if gbuffer is not None:
                gbuffer.free()
        indirect_specular = _rgb(indirect_specular)
        if glossy_reflectors is not None:
            indirect_specular = indirect_specular + glossy_reflectors
        return FrameImages(_rgb(direct_diffuse), _rgb(direct_specular), _rgb(indirect_diffuse),
                           indirect_specular, np.clip(np.nan_to_num(coverage), 0.0, 1.0).astype(np.float32),
                           timings, counts, glossy_reflectors, lights.plan)
