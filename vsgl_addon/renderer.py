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
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .layouts import GBUFFER
from .passes import (READ_BACK, UPLOAD, VPL_EXTRACTION, direct_light, gbuffer as gbuffer_pass, ism, mrp_asg,
                     mrp_visibility, shading_inputs, vpl_culling, vsgl_shading)
from .passes.contract import LIGHT_PASSES, run_stages
from .passes.gpu_util import finish, read_texture
from .passes.rsm import SceneGPU
from .pipeline import build_visibility_stages, render_scene_vsgls, view_receivers
from .planner import PROXY_CACHE, RECEIVER_ALPHA_RANGE, kept_proxies, plan_frame
from .proxies import ProxyCache, describe_proxies
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
    # The part of indirect_diffuse the glossy VPLs carry (sharp reflectors' light on diffuse
    # receivers, 004); None: zeros.
    indirect_caustics: np.ndarray | None = None
    # The rectangle proxies MRP-ASG shaded (proxies.describe_proxies rows: object, size, roughness,
    # lit by which lights), for the statistics panel and the render report.
    proxies: list = field(default_factory=list)
    plan: object = None  # the planner.FramePlan the frame executed

    def __post_init__(self):
        if self.indirect_glossy_reflectors is None:
            self.indirect_glossy_reflectors = np.zeros_like(self.indirect_specular)
        if self.indirect_caustics is None:
            self.indirect_caustics = np.zeros_like(self.indirect_diffuse)

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


class _StageClock:
    """A stage's seconds in a staged light build (SceneLights.build_stages), without the pauses
    between the viewport's steps, so its timings are the GPU work's alone as in one build."""

    def __init__(self):
        self.restart()

    def restart(self) -> None:
        self.started, self.paused = time.perf_counter(), 0.0

    def pause(self):
        paused = time.perf_counter()
        yield
        self.paused += time.perf_counter() - paused

    def through(self, stages):
        """``yield from`` the staged build ``stages``, pausing at each of its yields; its result."""
        while True:
            try:
                next(stages)
            except StopIteration as done:
                return done.value
            yield from self.pause()

    def seconds(self) -> float:
        return time.perf_counter() - self.started - self.paused


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
    # Glossy VPLs (004, passes/vpl_culling.py VPLSet) when the scene needs them (light_paths.py); then
    # `vsgls` holds no sharp reflector's specular flux (the VPLs carry it to diffuse receivers).
    vpls: object = None
    # With VPLs and MRP-ASG gated by receiver roughness: the VSGLs of every reflector, whose specular
    # image lights the receivers MRP-ASG leaves (the first set no longer holds the proxies' light).
    whole_vsgls: object = None
    # With visibility on: the proxies' mirror shadow maps (passes/mrp_visibility.py), MRP-ASG's
    # proxy-to-receiver shadows.
    mirror_maps: object = None
    plan: object = None  # planner.FramePlan: what these light passes ran, and why

    @classmethod
    def build(cls, scene, settings: VSGLSettings, proxy_cache: ProxyCache | None = None,
              view=None, point_cache=None) -> "SceneLights":
        """``view``: (view matrix, projection matrix) of the one view the frame is seen from, when
        known, so the plan can skip the work no receiver in it needs and weigh the RSM texels by it
        (the view PDF); None: any view (the viewport). ``point_cache``: a passes.scene_gpu
        PointTextureCache that keeps the ISMs' point sets on the GPU across builds (the viewport's)."""
        return run_stages(cls.build_stages(scene, settings, proxy_cache, view, point_cache))

    @classmethod
    def build_stages(cls, scene, settings: VSGLSettings, proxy_cache: ProxyCache | None = None,
                     view=None, point_cache=None):
        """:meth:`build` as a generator that yields between its stages (each VSGL set's RSM views
        and tables, each set's shadow maps, the VPLs, the mirror maps), each finished on the GPU,
        and returns the SceneLights: the viewport spreads a build over steps of its time budget.
        Closing it early frees what it made."""
        view_projection = None if view is None else np.asarray(view[1]) @ np.asarray(view[0])
        plan = plan_frame(scene, settings, proxy_cache, view_projection)
        clock = _StageClock()
        scene_gpu = SceneGPU(scene, point_cache)
        timings = {UPLOAD.name: clock.seconds()}
        proxies = plan.proxies
        caustics = plan.runs("vpl_pass")
        sets = []
        vpls = mirror_maps = None
        try:
            clock.restart()
            # The plan's VSGL sets (light-paths.md): one, or one per receiver lobe when the VPLs take
            # the sharp reflectors' specular flux from the diffuse receivers, MRP-ASG the proxies' from
            # the glossy ones, or Blender's ray visibility hides some object from one ray type; with
            # both passes and MRP-ASG gated by receiver roughness, a third of every reflector.
            receivers = view_receivers(scene_gpu, *view) if plan.runs("view_pdf") else None
            for lobe in plan.receiver_sets:
                cut_proxies = proxies if lobe == "glossy" else ()
                sharp_alpha = settings.caustic_roughness if caustics and lobe == "diffuse" else 0.0
                sets.append(render_scene_vsgls(scene_gpu, settings, lobe, cut_proxies, sharp_alpha, plan, receivers))
                if sets[-1].generations:
                    _finish(sets[-1].generations[-1][2].table)
                yield from clock.pause()
            timings[LIGHT_PASSES.name] = clock.seconds()
            clock.restart()
            if plan.runs("visibility"):
                first_map = 0  # each set's maps draw other point sets
                starts = []
                for index, table_set in enumerate(sets):
                    # The whole set differs from the glossy one only by the proxies' specular flux: its
                    # maps draw the same point sets, so MRP-ASG serving no receiver gives the image of
                    # MRP-ASG off exactly.
                    start = starts[1] if index == 2 else first_map
                    starts.append(start)
                    first_map = max(first_map, (yield from clock.through(
                        build_visibility_stages(scene_gpu, table_set, settings, start))))
                    if table_set.isms:
                        _finish(table_set.isms[-1].texture)
                    yield from clock.pause()
            timings[ism.PASS.step.name] = clock.seconds()
            clock.restart()
            if caustics:
                # Made on the GPU, with their clusters' shadow maps when VPL shadows are on, with nothing
                # read back: the viewport rebuilds them per change.
                shadows = settings if settings.visibility and settings.vpl_visibility else None
                vpls = yield from clock.through(vpl_culling.extract_vpls_stages(
                    scene_gpu, settings.rsm_size, settings.caustic_roughness, shadows))
                _finish(vpls.table if vpls.isms is None else vpls.isms.texture)
                yield from clock.pause()
            timings[VPL_EXTRACTION.name] = clock.seconds()
            clock.restart()
            if settings.visibility and proxies:
                mirror_maps = mrp_visibility.PASS.run(scene_gpu, proxies, settings.rsm_size, settings.disk_radius)
                for depth, _ in mirror_maps.atlases.values():
                    _finish(depth)
            timings[mrp_visibility.PASS.step.name] = clock.seconds()
        except BaseException:
            for item in (*sets, vpls, mirror_maps):
                if item is not None:
                    item.free()
            scene_gpu.free()
            raise
        return cls(scene, scene_gpu, sets[0], timings, sets[1] if len(sets) > 1 else None, proxies, vpls,
                   sets[2] if len(sets) > 2 else None, mirror_maps, plan)

    def free(self) -> None:
        for name in ("vsgls", "glossy_vsgls", "whole_vsgls", "vpls", "mirror_maps"):
            if getattr(self, name) is not None:
                getattr(self, name).free()
                setattr(self, name, None)
        if self.scene_gpu is not None:
            self.scene_gpu.free()
            self.scene_gpu = None


def scene_proxies(scene, settings: VSGLSettings, proxy_cache: ProxyCache | None = None, overrides=None) -> list:
    """(proxy, lit-by mask) of the rectangle proxies of ``scene`` some light reaches
    (planner.kept_proxies), from ``proxy_cache`` or the planner's."""
    return kept_proxies(scene, settings, PROXY_CACHE if proxy_cache is None else proxy_cache, overrides)


class ViewCounts(Mapping):
    """A view's counts (key -> number), where a value given as a function is computed when first
    read: the number of VPLs the GPU extracted is a read-back (4 bytes), which the viewport makes only
    when its statistics are shown, F12 and the report when they copy the counts (``dict(counts)``)."""

    def __init__(self, values: dict, deferred: dict | None = None):
        self._values = dict(values)
        self._deferred = dict(deferred or {})
        self._keys = list(self._values) + [key for key in self._deferred if key not in self._values]

    def __getitem__(self, key):
        if key in self._deferred:
            self._values[key] = self._deferred.pop(key)()
        return self._values[key]

    def __iter__(self):
        return iter(self._keys)

    def __len__(self) -> int:
        return len(self._keys)


def _vpl_count(vpls):
    """The VPL count of ``vpls`` (a passes.vpl_culling.VPLSet), or None once it was freed unread."""
    if vpls.count_texture is None and vpls._count is None:
        return None
    return vpls.count


@dataclass
class ViewTextures:
    """One view's images left on the GPU (RGBA32F, row 0 at the bottom, all of one size): the
    keys of TEXTURES. ``position`` and ``normal`` are the view's G-buffer attachments (position.a =
    coverage), the guide of joint bilateral upsampling. The indirect textures belong to the
    FrameRenderer and are overwritten by its next view: use them before. `free()` drops the rest."""

    width: int
    height: int
    textures: dict
    counts: Mapping = field(default_factory=dict)  # a ViewCounts: the VPL count is read when asked
    gbuffer: object = None  # the view's GBuffer (the guide of a full-resolution render)
    _owned: list = field(default_factory=list)

    TEXTURES = ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular", "position", "normal")
    # Also "indirect_glossy_reflectors" (MRP-ASG's part of indirect_specular) when a proxy is lit.

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
        self._whole_shading = None  # the shading of SceneLights.whole_vsgls
        self._mrp = mrp_asg.MRPASG()
        self._vpls = vpl_culling.VPLCaustics()

    def free(self) -> None:
        self._shading.free()
        self._mrp.free()
        self._vpls.free()
        if self._whole_shading is not None:
            self._whole_shading.free()
            self._whole_shading = None
        if self._glossy_shading is not None:
            self._glossy_shading.free()
            self._glossy_shading = None

    def render_view_textures(self, lights: SceneLights, settings: VSGLSettings, width: int, height: int,
                             view_matrix, projection_matrix, timings: dict | None = None,
                             vpl_stride: int = 1) -> ViewTextures:
        """One view's passes, with nothing read back: the images stay textures (the viewport draws
        them, render_view reads them). Without ``timings`` no wait for the GPU either (the caller
        finishes what it times); with it, each pass is finished and its seconds stored under its step.
        ``vpl_stride`` S > 1: the glossy VPL pass shades every S-th VPL, weighted S (the viewport's
        coarse preview; passes/vpl_culling.py run)."""
        scene = lights.scene
        clock = time.perf_counter()

        def lap(step, texture):
            nonlocal clock
            if timings is None:
                return
            _finish(texture)
            now = time.perf_counter()
            timings[step.name] = now - clock
            clock = now

        gbuffer = direct = None
        try:
            gbuffer = gbuffer_pass.PASS.run(lights.scene_gpu, view_matrix, projection_matrix, (width, height))
            lap(gbuffer_pass.PASS.step, gbuffer.textures["position"])
            direct = direct_light.PASS.run(gbuffer, scene.lights, lights.vsgls.views_by_light,
                                           scene_gpu=lights.scene_gpu)
            lap(direct_light.PASS.step, direct.textures["diffuse"])
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
            whole_specular = self._shading.specular
            if lights.whole_vsgls is not None:
                if self._whole_shading is None:
                    self._whole_shading = vsgl_shading.VSGLShading()
                vsgl_shading.PASS.run(inputs, gbuffer.camera_vector, lights.whole_vsgls.tables(), mode,
                                      shading=self._whole_shading)
                whole_specular = self._whole_shading.specular
            lap(vsgl_shading.PASS.step, whole_specular)
            diffuse = self._shading.diffuse
            caustics = None
            vpls_per_pixel = 0.0
            if lights.vpls is not None:
                # The glossy VPLs' cell (light-paths.md): sharp reflectors' specular light on the
                # receivers' diffuse lobes, added to the diffuse VSGLs, which leave it out.
                vpls_per_pixel = self._vpls.render(inputs, lights.vpls, view_matrix, projection_matrix, settings,
                                                   diffuse, count=timings is not None, stride=vpl_stride)
                diffuse, caustics = self._vpls.diffuse, self._vpls.caustics
                lap(vpl_culling.PASS.step, diffuse)
            elif timings is not None:
                timings[vpl_culling.PASS.step.name] = 0.0
            glossy_reflectors = None
            if lights.proxies:
                # MRP-ASG's cell (light-paths.md): proxy-reflected light onto glossy receivers. Without
                # Blender's ray-visibility split the first set is every reflector's light, so a
                # receiver outside MRP-ASG's range takes the proxies' light from it instead.
                gated = not scene.receiver_lobe_split
                mrp_asg.PASS.run(inputs, gbuffer.camera_vector, scene.lights, lights.vsgls.views_by_light,
                                 lights.proxies, settings.disk_radius, settings.reflector_mode, mrp=self._mrp,
                                 receiver_range=RECEIVER_ALPHA_RANGE if gated else (0.0, 1.0),
                                 mirror_maps=lights.mirror_maps)
                specular = self._mrp.composite_specular(whole_specular, specular, gated)
                glossy_reflectors = self._mrp.texture
                lap(mrp_asg.PASS.step, specular)
            elif timings is not None:
                timings[mrp_asg.PASS.step.name] = 0.0
        except BaseException:
            for item in (direct, gbuffer):
                if item is not None:
                    item.free()
            raise
        textures = {"direct_diffuse": direct.textures["diffuse"], "direct_specular": direct.textures["glossy"],
                    "indirect_diffuse": diffuse, "indirect_specular": specular,
                    "position": gbuffer.textures["position"], "normal": gbuffer.textures["normal"]}
        if glossy_reflectors is not None:
            textures["indirect_glossy_reflectors"] = glossy_reflectors
        if caustics is not None:
            textures["indirect_caustics"] = caustics
        vsgl_count = sum(table_set.vsgl_count for table_set in (lights.vsgls, lights.glossy_vsgls, lights.whole_vsgls)
                         if table_set is not None)
        vpls = lights.vpls
        counts = ViewCounts({"lights": len(scene.lights), "rsm_views": sum(len(v) for v in lights.vsgls.views_by_light.values()),
                             "vsgls": vsgl_count, "triangles": int(len(scene.geometry.positions)),
                             "vpls": 0, "vpls_per_pixel": float(vpls_per_pixel or 0.0), "proxies": len(lights.proxies)},
                            {"vpls": lambda: _vpl_count(vpls)} if vpls is not None else None)
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
        """One view of already built `lights`: render_view_textures, each pass timed, then read back.
        `settings` must be the ones `lights` was built with (the kernel picks the diffuse mode)."""
        timings: dict[str, float] = dict(lights.timings)
        view = self.render_view_textures(lights, settings, width, height, view_matrix, projection_matrix, timings)
        try:
            clock = time.perf_counter()
            images = {name: read_texture(texture, width, height) for name, texture in view.textures.items()
                      if name != "normal"}
            timings[READ_BACK.name] = time.perf_counter() - clock
            counts = dict(view.counts)
        finally:
            view.free()
        optional = {name: None if images.get(name) is None else _rgb(images[name])
                    for name in ("indirect_glossy_reflectors", "indirect_caustics")}
        return FrameImages(_rgb(images["direct_diffuse"]), _rgb(images["direct_specular"]),
                           _rgb(images["indirect_diffuse"]), _rgb(images["indirect_specular"]),
                           np.clip(np.nan_to_num(GBUFFER.unpack_slots(images, ["coverage"])["coverage"]), 0.0, 1.0).astype(np.float32),
                           timings, counts, **optional, proxies=describe_proxies(lights.proxies, lights.scene),
                           plan=lights.plan)
