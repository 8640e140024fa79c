# SPDX-License-Identifier: GPL-3.0-or-later
"""The viewport overlay's state and scheduling, without Blender's bpy (the glue is overlay.py).

:class:`OverlayCache` decides what to render next, one unit of work per :meth:`OverlayCache.step`,
so the interface stays responsive:

* the **light passes** (RSMs, VSGL tables: :class:`~vsgl_addon.renderer.SceneLights`) when the
  scene changed (:meth:`~OverlayCache.mark_scene_dirty`) or the pass settings differ;
* else one viewport whose view or scene state changed, at the **coarse** resolution (a quarter of
  the overlay's per side); a view change reuses the light passes (G-buffer + shading only);
* else, once nothing changed for REFINE_DELAY seconds, one **refined** viewport at the overlay's
  resolution, in bands of rows sized to STEP_BUDGET from the measured time per pixel.

It never reads bpy.context: the timer hands it the scene description, settings, scale and time.
The GPU work goes through a backend (:class:`GPUBackend`: the renderer's passes, texture upload,
the draw shader), which tests replace with a fake one, and time through an injected clock, so the
scheduling runs without Blender or a GPU.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from .settings import OVERLAY_DISPLAYS, VSGLSettings
from .views import band_projection

#: Coarse images have 1/COARSE_DIVISOR of the overlay's resolution per side.
COARSE_DIVISOR = 4
#: Seconds without any change before a coarse image is refined.
REFINE_DELAY = 0.3
#: Seconds one timer step may spend on a refined image: it is rendered in bands of rows sized
#: to fit (from the measured time per pixel), so the interface never waits much longer than this.
STEP_BUDGET = 0.06
LIGHTS, COARSE, REFINED = "lights", "coarse", "refined"
#: The cached images of a view (the overlay shader's samplers) and the FrameImages array of each.
IMAGE_ARRAYS = {"indirect_diffuse": "indirect_diffuse", "indirect_specular": "indirect_specular",
                "direct_light": "direct"}


def overlay_size(region_size, scale: float, level: str) -> tuple[int, int]:
    """Pixels of the overlay image of a region of `region_size` (w, h) at `level`."""
    divisor = COARSE_DIVISOR if level == COARSE else 1
    return tuple(max(1, int(round(side * scale / divisor))) for side in region_size)


@dataclass
class ViewRequest:
    """What a viewport last drew with: its view, projection and region size."""

    view_matrix: np.ndarray
    projection_matrix: np.ndarray
    region_size: tuple[int, int]


@dataclass
class ViewImages:
    """A viewport's cached overlay: GPU textures and what they were rendered for."""

    request: ViewRequest
    level: str
    scene_version: int
    size: tuple[int, int]
    textures: dict = field(default_factory=dict)  # the keys of IMAGE_ARRAYS
    seconds: float = 0.0
    timings: dict = field(default_factory=dict)

    def free(self) -> None:
        self.textures.clear()


@dataclass
class _Refinement:
    """A refined image being rendered band by band (rows from the bottom)."""

    request: ViewRequest
    scene_version: int
    size: tuple[int, int]
    arrays: dict  # "indirect_diffuse", "indirect_specular", "direct": (h, w, 3); "coverage": (h, w)
    rows_done: int = 0
    bands: int = 0
    seconds: float = 0.0
    max_step_seconds: float = 0.0
    timings: dict = field(default_factory=dict)
    counts: dict = field(default_factory=dict)


def _plan(lights) -> dict:
    """The JSON form of the frame plan the light passes ran (planner.FramePlan.to_dict), {} without one."""
    plan = getattr(lights, "plan", None)
    return plan.to_dict() if plan is not None else {}


def same_view(a: ViewRequest, b: ViewRequest) -> bool:
    return (a.region_size == b.region_size and np.array_equal(a.view_matrix, b.view_matrix)
            and np.array_equal(a.projection_matrix, b.projection_matrix))


class OverlayProgram:
    """The draw shader and its full-screen triangle, compiled outside the draw callback."""

    def __init__(self):
        from gpu_extras.batch import batch_for_shader

        from .shaders import ShaderInterface, create_shader

        self.shader = create_shader(
            "vsgl_overlay", ShaderInterface(
                push_constants=[("INT", "mode"), ("FLOAT", "scale"), ("FLOAT", "gamma"), ("INT", "encode_srgb")],
                samplers=[("FLOAT_2D", name) for name in IMAGE_ARRAYS],
                vertex_inputs=[("VEC2", "position")], varyings=[("VEC2", "uv")],
                fragment_outputs=[("VEC4", "color")]),
            vertex="fullscreen_triangle.vert.glsl", fragment="overlay/overlay.frag.glsl")
        self.batch = batch_for_shader(self.shader, "TRIS", {"position": [(-1.0, -1.0), (3.0, -1.0), (-1.0, 3.0)]})

    def draw(self, textures: dict, display: str, scale: float, gamma: float, encode_srgb: bool) -> None:
        """Draw `textures` into the bound framebuffer as OVERLAY_DISPLAYS option `display` shows them."""
        import gpu

        mode = OVERLAY_DISPLAYS.number(display) if display in OVERLAY_DISPLAYS.names else 0
        saved_blend = gpu.state.blend_get()
        try:
            gpu.state.blend_set("ADDITIVE_PREMULT" if display == "added" else "ALPHA")
            self.shader.bind()
            self.shader.uniform_int("mode", mode)
            self.shader.uniform_float("scale", float(scale))
            self.shader.uniform_float("gamma", float(gamma) if gamma > 0 else 1.0)
            self.shader.uniform_int("encode_srgb", 1 if encode_srgb else 0)
            for name, texture in textures.items():
                self.shader.uniform_sampler(name, texture)
            self.batch.draw(self.shader)
        finally:
            gpu.state.blend_set(saved_blend)


class GPUBackend:
    """What OverlayCache renders and draws with: the renderer's passes and Blender's gpu module."""

    def frame_renderer(self):
        from .renderer import FrameRenderer

        return FrameRenderer()

    def scene_lights(self, description, settings: VSGLSettings):
        from .renderer import SceneLights

        return SceneLights.build(description, settings)

    def texture(self, rgba: np.ndarray):
        from .passes.gpu_util import texture_from_array

        return texture_from_array(rgba)

    def program(self) -> OverlayProgram:
        return OverlayProgram()


class OverlayCache:
    """The overlay's state: light passes per scene state, images per viewport, update statistics."""

    def __init__(self, backend=None, clock=time.perf_counter):
        self.backend = GPUBackend() if backend is None else backend
        self.clock = clock  # the time of changes and of every measured duration
        self.scene_version = 0  # bumped by mark_scene_dirty()
        self.lights = None  # renderer.SceneLights of lights_version / lights_settings
        self.lights_version = -1
        self.lights_settings: VSGLSettings | None = None
        self.renderer = None  # renderer.FrameRenderer
        self.requests: dict[int, ViewRequest] = {}
        self.views: dict[int, ViewImages] = {}
        self.last_change = 0.0
        self.statistics: dict = {}  # last update: level, seconds, timings, counts, size
        self.history: deque = deque(maxlen=64)  # the last updates' statistics, oldest first
        self.updates = 0  # how many units of work were done (history index of the next one)
        self.warnings: tuple[str, ...] = ()
        self.error: str | None = None
        self._program: OverlayProgram | None = None
        self._refining: dict[int, _Refinement] = {}
        self._seconds_per_pixel: float | None = None  # of the last view render (sizes the bands)

    def _now(self, now: float | None) -> float:
        return self.clock() if now is None else now

    # --- inputs -----------------------------------------------------------------------------
    def mark_scene_dirty(self, now: float | None = None) -> None:
        self.scene_version += 1
        self.error = None
        self.last_change = self._now(now)

    def request_view(self, key: int, view_matrix, projection_matrix, region_size, now: float | None = None) -> bool:
        """Record a viewport's view (from the draw callback: plain numbers only). True if it changed."""
        request = ViewRequest(np.array(view_matrix, np.float64), np.array(projection_matrix, np.float64),
                              (int(region_size[0]), int(region_size[1])))
        old = self.requests.get(key)
        if old is not None and same_view(old, request):
            return False
        self.requests[key] = request
        self.last_change = self._now(now)
        return True

    def retain_views(self, keys) -> None:
        """Forget every viewport not in `keys` (closed ones), so nothing is rendered for them."""
        for key in [key for key in self.requests if key not in keys]:
            self.forget_view(key)

    def forget_view(self, key: int) -> None:
        self.requests.pop(key, None)
        self._refining.pop(key, None)
        view = self.views.pop(key, None)
        if view is not None:
            view.free()

    def is_current(self, key: int) -> bool:
        """Whether viewport `key`'s cached images show its last requested view of the current scene."""
        view, request = self.views.get(key), self.requests.get(key)
        return (view is not None and request is not None and view.scene_version == self.scene_version
                and same_view(view.request, request))

    # --- work (main thread, GPU context) --------------------------------------------------------
    def pending(self, scale: float, now: float | None = None) -> str | None:
        """The next unit of work: LIGHTS, COARSE, REFINED or None."""
        now = self._now(now)
        if not self.requests or self.error is not None:
            return None
        if self.lights is None or self.lights_version != self.scene_version:
            return LIGHTS
        if self._next_view(COARSE, scale) is not None:
            return COARSE
        if now - self.last_change >= REFINE_DELAY and self._next_view(REFINED, scale) is not None:
            return REFINED
        return None

    def _next_view(self, level: str, scale: float):
        for key, request in self.requests.items():
            cached = self.views.get(key)
            fresh = (cached is not None and cached.scene_version == self.lights_version
                     and same_view(cached.request, request)
                     and cached.size == overlay_size(request.region_size, scale, cached.level))
            if level == COARSE and not fresh:
                return key
            if level == REFINED and fresh and cached.level == COARSE:
                return key
        return None

    def step(self, describe_scene, settings: VSGLSettings, scale: float, now: float | None = None) -> str | None:
        """Do one unit of work; returns what it did (see pending()) or None.

        `describe_scene()` returns the SceneDescription (called only when the light passes rerun).
        A pass that fails stores its message in `error` (shown in the panel) and stops updates
        until the scene changes again.
        """
        if self.lights_settings is not None and settings != self.lights_settings and self.lights is not None:
            self.mark_scene_dirty(now)
        work = self.pending(scale, now)
        if work is None:
            return None
        try:
            self.ensure_draw_resources()
            if work == LIGHTS:
                self._rebuild_lights(describe_scene, settings)
            else:
                self._render_view(self._next_view(work, scale), work, scale)
            self.history.append({"index": self.updates, **self.statistics})
            self.updates += 1
        except Exception as error:  # noqa: BLE001 - shown in the panel, never raised into Blender's loop
            self.error = f"{type(error).__name__}: {error}"
            self.free_lights()
        return work

    def _rebuild_lights(self, describe_scene, settings: VSGLSettings) -> None:
        started = self.clock()
        self.free_lights()
        description = describe_scene()
        extraction = self.clock() - started
        self.warnings = tuple(description.warnings)
        if self.renderer is None:
            self.renderer = self.backend.frame_renderer()
        version = self.scene_version
        self.lights = self.backend.scene_lights(description, settings)
        self.lights.timings = {"scene_extraction": extraction, **self.lights.timings}
        self.lights_version = version
        self.lights_settings = settings
        self.statistics = {"level": LIGHTS, "seconds": self.clock() - started, "timings": {},
                           "light_timings": dict(self.lights.timings), "plan": _plan(self.lights), "counts": {}, "size": None}

    def _render(self, request: ViewRequest, width: int, height: int, projection_matrix):
        """(FrameImages, seconds, view-only timings) of one render_view call."""
        started = self.clock()
        images = self.renderer.render_view(self.lights, self.lights_settings, width, height,
                                           request.view_matrix, projection_matrix)
        seconds = self.clock() - started
        self._seconds_per_pixel = seconds / (width * height)
        # render_view's timings start with the light passes' (run earlier, once per scene state).
        timings = {name: value for name, value in images.timings.items() if name not in self.lights.timings}
        return images, seconds, timings

    def _store(self, key, request, level, size, arrays, seconds, timings, counts, extra=None) -> None:
        coverage = arrays["coverage"][..., None]
        textures = {name: self.backend.texture(np.concatenate([arrays[array], coverage], axis=-1))
                    for name, array in IMAGE_ARRAYS.items()}
        old = self.views.get(key)
        if old is not None:
            old.free()
        self.views[key] = ViewImages(request, level, self.lights_version, size, textures, seconds, timings)
        self.statistics = {"level": level, "seconds": seconds, "timings": timings,
                           "light_timings": dict(self.lights.timings), "plan": _plan(self.lights), "counts": dict(counts), "size": size,
                           **(extra or {})}

    def _render_view(self, key: int, level: str, scale: float) -> None:
        request = self.requests[key]
        width, height = overlay_size(request.region_size, scale, level)
        if level == COARSE:
            self._refining.pop(key, None)
            images, seconds, timings = self._render(request, width, height, request.projection_matrix)
            arrays = {"indirect_diffuse": images.indirect_diffuse, "indirect_specular": images.indirect_specular,
                      "direct": images.direct, "coverage": images.coverage}
            self._store(key, request, COARSE, (width, height), arrays, seconds, timings, images.counts)
            return
        self._refine_band(key, request, width, height)

    def _refine_band(self, key: int, request: ViewRequest, width: int, height: int) -> None:
        """Render the next band of rows of viewport `key`'s refined image; store it when complete."""
        job = self._refining.get(key)
        if job is None or job.scene_version != self.lights_version or job.size != (width, height) \
                or not same_view(job.request, request):
            job = _Refinement(request, self.lights_version, (width, height), {
                "indirect_diffuse": np.zeros((height, width, 3), np.float32),
                "indirect_specular": np.zeros((height, width, 3), np.float32),
                "direct": np.zeros((height, width, 3), np.float32),
                "coverage": np.zeros((height, width), np.float32)})
            self._refining[key] = job
        rows = height
        if self._seconds_per_pixel:
            rows = int(STEP_BUDGET / (self._seconds_per_pixel * width))
        first = job.rows_done
        end = min(height, first + max(1, rows))
        images, seconds, timings = self._render(request, width, end - first,
                                                band_projection(request.projection_matrix, first, end, height))
        job.arrays["indirect_diffuse"][first:end] = images.indirect_diffuse
        job.arrays["indirect_specular"][first:end] = images.indirect_specular
        job.arrays["direct"][first:end] = images.direct
        job.arrays["coverage"][first:end] = images.coverage
        job.rows_done, job.bands = end, job.bands + 1
        job.seconds += seconds
        job.max_step_seconds = max(job.max_step_seconds, seconds)
        for name, value in timings.items():
            job.timings[name] = job.timings.get(name, 0.0) + value
        job.counts = dict(images.counts)
        if end < height:
            self.statistics = {"level": "refining", "seconds": seconds, "timings": timings,
                               "light_timings": dict(self.lights.timings), "plan": _plan(self.lights), "counts": dict(images.counts),
                               "size": (width, end - first), "rows": (first, end, height)}
            return
        del self._refining[key]
        self._store(key, request, REFINED, (width, height), job.arrays, job.seconds, job.timings, job.counts,
                    {"bands": job.bands, "max_step_seconds": job.max_step_seconds})

    def ensure_draw_resources(self) -> None:
        """Compile the draw shader and make its triangle (outside the draw callback)."""
        if self._program is None:
            self._program = self.backend.program()

    # --- drawing (inside the draw callback: no pass, no upload) ----------------------------------
    def draw(self, key: int, display: str, scale: float, gamma: float = 1.0, encode_srgb: bool = False) -> bool:
        """Draw viewport `key`'s cached images into the bound framebuffer, as OVERLAY_DISPLAYS option
        `display` shows them; False if there are none."""
        view = self.views.get(key)
        if view is None or self._program is None or not view.textures:
            return False
        self._program.draw(view.textures, display, scale, gamma, encode_srgb)
        return True

    # --- freeing -----------------------------------------------------------------------------
    def free_lights(self) -> None:
        if self.lights is not None:
            self.lights.free()
        self.lights = None
        self.lights_version = -1
        self.lights_settings = None

    def free(self) -> None:
        """Release every GPU resource; the next request starts from scratch."""
        self.free_lights()
        for view in self.views.values():
            view.free()
        self.views.clear()
        self.requests.clear()
        self._refining.clear()
        self._seconds_per_pixel = None
        if self.renderer is not None:
            self.renderer.free()
        self.renderer = None
        self._program = None
        self.statistics = {}
        self.history.clear()
        self.warnings = ()
        self.error = None

    def gpu_resource_count(self) -> int:
        """How many GPU objects the cache holds (0 after free()): textures, the light passes'
        resources, the renderer, the draw shader and its triangle."""
        return (sum(len(view.textures) for view in self.views.values()) + (self.lights is not None)
                + (self.renderer is not None) + 2 * (self._program is not None))
