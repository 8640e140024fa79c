# SPDX-License-Identifier: GPL-3.0-or-later
"""The live viewport overlay of the VSGL light (Blender-facing; the passes are renderer.py's).

Three parts, each doing one kind of work:

* the **draw callback** (``SpaceView3D.draw_handler_add``, every 3D viewport, POST_PIXEL) only
  records the viewport's view and projection and draws the cached images of that viewport with a
  shader compiled beforehand: no pass, no upload, no compilation;
* the **depsgraph handler** (``depsgraph_update_post``, ``frame_change_post``) only marks the scene
  dirty when something that changes the light changed (an object moved, a mesh, light, material,
  world or image changed, a VSGL parameter changed); selection and overlay display settings do not;
* the **timer** does the work, one unit per call so the interface stays responsive: rebuild the
  light passes (RSMs, VSGL tables: :class:`~vsgl_addon.renderer.SceneLights`) when the scene is dirty,
  else render one viewport whose view or scene state changed at the coarse resolution (a quarter of
  the overlay's per side), else, once nothing changed for REFINE_DELAY seconds, refine one viewport
  at the overlay's resolution. A view change reuses the light passes (G-buffer + shading only).

:class:`OverlayCache` holds all state and GPU resources (no bpy.context: the timer and the tests
hand it the scene description, settings and times). It frees everything when the overlay is
switched off, a file is loaded (``load_pre``) or the add-on is unregistered.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from .settings import VSGLSettings

#: Coarse images have 1/COARSE_DIVISOR of the overlay's resolution per side.
COARSE_DIVISOR = 4
#: Seconds without any change before a coarse image is refined.
REFINE_DELAY = 0.3
#: Seconds one timer step may spend on a refined image: it is rendered in bands of rows sized
#: to fit (from the measured time per pixel), so the interface never waits much longer than this.
STEP_BUDGET = 0.06
#: Timer intervals (seconds): work pending, idle with the overlay on, overlay off.
BUSY_INTERVAL = 0.02
IDLE_INTERVAL = 0.1
OFF_INTERVAL = 0.5
MODE_INDEX = {"INDIRECT": 0, "ADDED": 1, "INDIRECT_DIFFUSE": 2, "INDIRECT_SPECULAR": 3, "DIRECT": 4, "COMBINED": 5}
COARSE, REFINED = "coarse", "refined"


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
    textures: dict = field(default_factory=dict)  # "indirect_diffuse", "indirect_specular", "direct_light"
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


def band_projection(projection_matrix, first_row: int, end_row: int, height: int) -> np.ndarray:
    """The projection of rows [first_row, end_row) of an image `height` rows high (row 0 at the
    bottom): the same view, NDC y of that band stretched to [-1, 1]. Perspective or orthographic."""
    y0 = -1.0 + 2.0 * first_row / height
    y1 = -1.0 + 2.0 * end_row / height
    crop = np.eye(4)
    crop[1, 1] = 2.0 / (y1 - y0)
    crop[1, 3] = -(y1 + y0) / (y1 - y0)
    return crop @ np.asarray(projection_matrix, np.float64)


def _same_view(a: ViewRequest, b: ViewRequest) -> bool:
    return (a.region_size == b.region_size and np.array_equal(a.view_matrix, b.view_matrix)
            and np.array_equal(a.projection_matrix, b.projection_matrix))


def _rgba_texture(rgb: np.ndarray, alpha: np.ndarray):
    from .passes.gpu_util import texture_from_array

    return texture_from_array(np.concatenate([rgb, alpha[..., None]], axis=-1))


class OverlayCache:
    """The overlay's state: light passes per scene state, images per viewport, update statistics."""

    def __init__(self):
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
        self._draw_shader = None
        self._draw_batch = None
        self._refining: dict[int, _Refinement] = {}
        self._seconds_per_pixel: float | None = None  # of the last view render (sizes the bands)

    # --- inputs -----------------------------------------------------------------------------
    def mark_scene_dirty(self, now: float | None = None) -> None:
        self.scene_version += 1
        self.error = None
        self.last_change = time.perf_counter() if now is None else now

    def request_view(self, key: int, view_matrix, projection_matrix, region_size, now: float | None = None) -> bool:
        """Record a viewport's view (from the draw callback: plain numbers only). True if it changed."""
        request = ViewRequest(np.array(view_matrix, np.float64), np.array(projection_matrix, np.float64),
                              (int(region_size[0]), int(region_size[1])))
        old = self.requests.get(key)
        if old is not None and _same_view(old, request):
            return False
        self.requests[key] = request
        self.last_change = time.perf_counter() if now is None else now
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

    # --- work (main thread, GPU context) --------------------------------------------------------
    def pending(self, scale: float, now: float | None = None) -> str | None:
        """The next unit of work: "lights", COARSE, REFINED or None."""
        now = time.perf_counter() if now is None else now
        if not self.requests or self.error is not None:
            return None
        if self.lights is None or self.lights_version != self.scene_version:
            return "lights"
        if self._next_view(COARSE, scale) is not None:
            return COARSE
        if now - self.last_change >= REFINE_DELAY and self._next_view(REFINED, scale) is not None:
            return REFINED
        return None

    def _next_view(self, level: str, scale: float):
        for key, request in self.requests.items():
            cached = self.views.get(key)
            fresh = (cached is not None and cached.scene_version == self.lights_version
                     and _same_view(cached.request, request)
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
            if work == "lights":
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
        from .renderer import FrameRenderer, SceneLights

        started = time.perf_counter()
        self.free_lights()
        description = describe_scene()
        extraction = time.perf_counter() - started
        self.warnings = tuple(description.warnings)
        if self.renderer is None:
            self.renderer = FrameRenderer()
        version = self.scene_version
        self.lights = SceneLights.build(description, settings)
        self.lights.timings = {"scene_extraction": extraction, **self.lights.timings}
        self.lights_version = version
        self.lights_settings = settings
        self.statistics = {"level": "lights", "seconds": time.perf_counter() - started, "timings": {},
                           "light_timings": dict(self.lights.timings), "counts": {}, "size": None}

    def _render(self, request: ViewRequest, width: int, height: int, projection_matrix):
        """(FrameImages, seconds, view-only timings) of one render_view call."""
        started = time.perf_counter()
        images = self.renderer.render_view(self.lights, self.lights_settings, width, height,
                                           request.view_matrix, projection_matrix)
        seconds = time.perf_counter() - started
        self._seconds_per_pixel = seconds / (width * height)
        # render_view's timings start with the light passes' (run earlier, once per scene state).
        timings = {name: value for name, value in images.timings.items() if name not in self.lights.timings}
        return images, seconds, timings

    def _store(self, key, request, level, size, arrays, seconds, timings, counts, extra=None) -> None:
        coverage = arrays["coverage"]
        textures = {
            "indirect_diffuse": _rgba_texture(arrays["indirect_diffuse"], coverage),
            "indirect_specular": _rgba_texture(arrays["indirect_specular"], coverage),
            "direct_light": _rgba_texture(arrays["direct"], coverage),
        }
        old = self.views.get(key)
        if old is not None:
            old.free()
        self.views[key] = ViewImages(request, level, self.lights_version, size, textures, seconds, timings)
        self.statistics = {"level": level, "seconds": seconds, "timings": timings,
                           "light_timings": dict(self.lights.timings), "counts": dict(counts), "size": size,
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
                or not _same_view(job.request, request):
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
                               "light_timings": dict(self.lights.timings), "counts": dict(images.counts),
                               "size": (width, end - first), "rows": (first, end, height)}
            return
        del self._refining[key]
        self._store(key, request, REFINED, (width, height), job.arrays, job.seconds, job.timings, job.counts,
                    {"bands": job.bands, "max_step_seconds": job.max_step_seconds})

    def ensure_draw_resources(self) -> None:
        """Compile the draw shader and make its triangle (outside the draw callback)."""
        if self._draw_shader is None:
            from gpu_extras.batch import batch_for_shader

            from .shaders import ShaderInterface, create_shader

            self._draw_shader = create_shader(
                "vsgl_overlay", ShaderInterface(
                    push_constants=[("INT", "mode"), ("FLOAT", "scale"), ("FLOAT", "gamma"), ("INT", "encode_srgb")],
                    samplers=[("FLOAT_2D", "indirect_diffuse"), ("FLOAT_2D", "indirect_specular"),
                              ("FLOAT_2D", "direct_light")],
                    vertex_inputs=[("VEC2", "position")], varyings=[("VEC2", "uv")],
                    fragment_outputs=[("VEC4", "color")]),
                vertex="fullscreen_triangle.vert.glsl", fragment="overlay/overlay.frag.glsl")
            self._draw_batch = batch_for_shader(self._draw_shader, "TRIS",
                                                {"position": [(-1.0, -1.0), (3.0, -1.0), (-1.0, 3.0)]})

    # --- drawing (inside the draw callback: no pass, no upload) ----------------------------------
    def draw(self, key: int, mode: str, scale: float, gamma: float = 1.0, encode_srgb: bool = False) -> bool:
        """Draw viewport `key`'s cached images into the bound framebuffer; False if there are none."""
        import gpu

        view = self.views.get(key)
        if view is None or self._draw_shader is None or not view.textures:
            return False
        program = self._draw_shader
        saved_blend = gpu.state.blend_get()
        try:
            gpu.state.blend_set("ADDITIVE_PREMULT" if mode == "ADDED" else "ALPHA")
            program.bind()
            program.uniform_int("mode", MODE_INDEX.get(mode, 0))
            program.uniform_float("scale", float(scale))
            program.uniform_float("gamma", float(gamma) if gamma > 0 else 1.0)
            program.uniform_int("encode_srgb", 1 if encode_srgb else 0)
            for name, texture in view.textures.items():
                program.uniform_sampler(name, texture)
            self._draw_batch.draw(program)
        finally:
            gpu.state.blend_set(saved_blend)
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
        self._draw_shader = None
        self._draw_batch = None
        self.statistics = {}
        self.history.clear()
        self.warnings = ()
        self.error = None

    def gpu_resource_count(self) -> int:
        """How many GPU objects the cache holds (0 after free())."""
        return (sum(len(view.textures) for view in self.views.values()) + (self.lights is not None)
                + (self.renderer is not None) + (self._draw_shader is not None) + (self._draw_batch is not None))


# ---------------------------------------------------------------------------------------------
# Blender-facing glue: one cache per process, the draw handler, handlers and the timer.
# ---------------------------------------------------------------------------------------------

cache = OverlayCache()
_draw_handle = None
# Updates of these ID types change the light; an Object update only when it moved or changed.
_LIGHT_ID_TYPES = {"MESH", "LIGHT", "MATERIAL", "WORLD", "IMAGE", "NODETREE", "CURVE", "CURVES", "METABALL",
                   "POINTCLOUD", "VOLUME", "GREASEPENCIL", "TEXTURE", "COLLECTION"}


def _matrix(m) -> np.ndarray:
    return np.array([list(row) for row in m], np.float64)


def _view_transform(scene) -> tuple[float, float]:
    """(intensity × 2^exposure, gamma) of the scene's Standard view transform."""
    settings = scene.vsgl
    view = getattr(scene, "view_settings", None)
    exposure = float(getattr(view, "exposure", 0.0)) if view is not None else 0.0
    gamma = float(getattr(view, "gamma", 1.0)) if view is not None else 1.0
    return float(settings.overlay_intensity) * 2.0 ** exposure, gamma


def draw_callback() -> None:
    """SpaceView3D POST_PIXEL callback: record this viewport's view, draw its cached images."""
    import bpy

    context = bpy.context
    scene = context.scene
    settings = getattr(scene, "vsgl", None)
    if settings is None or not settings.show_overlay:
        return
    region, rv3d, space = context.region, context.region_data, context.space_data
    if region is None or rv3d is None:
        return
    if space is not None and not space.overlay.show_overlays:
        return  # the viewport's own "Show Overlays" hides ours too
    key = rv3d.as_pointer()
    cache.request_view(key, _matrix(rv3d.view_matrix), _matrix(rv3d.window_matrix), (region.width, region.height))
    scale, gamma = _view_transform(scene)
    # The viewport's framebuffer encodes linear values to sRGB itself (checked in Blender 5.2).
    cache.draw(key, settings.overlay_mode, scale, gamma, encode_srgb=False)
    _draw_label(key, settings)


def _draw_label(key: int, settings) -> None:
    """One line at the viewport's bottom left: what the overlay shows and how fresh it is."""
    import blf

    from .properties import OVERLAY_MODE_ITEMS

    mode = next((label for identifier, label, *_ in OVERLAY_MODE_ITEMS if identifier == settings.overlay_mode), "")
    view = cache.views.get(key)
    if cache.error:
        state = "stopped: see the VSGL tab"
    elif view is None:
        state = "computing…"
    else:
        request = cache.requests.get(key)
        current = (request is not None and view.scene_version == cache.scene_version
                   and _same_view(view.request, request))
        state = f"{view.level} {view.size[0]}×{view.size[1]}" + ("" if current else ", updating…")
    font = 0
    blf.size(font, 12.0)
    blf.color(font, 1.0, 1.0, 1.0, 0.9)
    blf.enable(font, blf.SHADOW)
    blf.shadow(font, 3, 0.0, 0.0, 0.0, 0.8)
    blf.position(font, 60.0, 14.0, 0.0)
    blf.draw(font, f"VSGL overlay: {mode} ({state})")
    blf.disable(font, blf.SHADOW)


def _tag_redraw() -> None:
    import bpy

    for window in getattr(bpy.context.window_manager, "windows", ()):
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()


def on_overlay_toggled(enabled: bool) -> None:
    """show_overlay changed: on -> start updating; off -> free everything."""
    if enabled:
        cache.mark_scene_dirty()
    else:
        cache.free()
    _tag_redraw()


def _light_changed(depsgraph) -> bool:
    for update in depsgraph.updates:
        id_type = getattr(update.id, "id_type", "")
        if id_type == "OBJECT":
            if update.is_updated_transform or update.is_updated_geometry or update.is_updated_shading:
                return True
        elif id_type in _LIGHT_ID_TYPES:
            return True
    return False


def _import_bpy_persistent():
    import bpy

    return bpy.app.handlers.persistent


_persistent = _import_bpy_persistent()


@_persistent
def on_depsgraph_update(scene, depsgraph) -> None:
    """Mark the scene dirty when the light may have changed (the timer does the work)."""
    settings = getattr(scene, "vsgl", None)
    if settings is None or not settings.show_overlay:
        return
    if _light_changed(depsgraph):
        cache.mark_scene_dirty()
    # A VSGL parameter change is caught by the timer (settings compared); an overlay display
    # change needs only a redraw, which Blender does for a property change anyway.


@_persistent
def on_frame_change(scene, depsgraph=None) -> None:
    settings = getattr(scene, "vsgl", None)
    if settings is not None and settings.show_overlay:
        cache.mark_scene_dirty()


@_persistent
def on_load_pre(*_args) -> None:
    """Another file is loading: nothing of this one's may stay on the GPU."""
    cache.free()


def _open_viewport_keys() -> set[int]:
    """as_pointer() of the region data of every open 3D viewport (quad views included)."""
    import bpy

    keys = set()
    for window in getattr(bpy.context.window_manager, "windows", ()):
        for area in window.screen.areas:
            if area.type != "VIEW_3D":
                continue
            space = area.spaces.active
            keys.add(space.region_3d.as_pointer())
            keys.update(rv3d.as_pointer() for rv3d in space.region_quadviews)
    return keys


def describe_context_scene():
    import bpy

    from .scene import extract_scene

    return extract_scene(bpy.context.evaluated_depsgraph_get())


def timer() -> float:
    """bpy.app.timers callback: one unit of overlay work, then the delay until the next call."""
    import bpy

    scene = getattr(bpy.context, "scene", None)
    settings = getattr(scene, "vsgl", None) if scene is not None else None
    if settings is None or not settings.show_overlay:
        if cache.gpu_resource_count():
            cache.free()
        return OFF_INTERVAL
    try:
        pass_settings = VSGLSettings.from_properties(settings)
    except ValueError as error:
        cache.error = str(error)
        return OFF_INTERVAL
    if not bpy.app.background:
        cache.retain_views(_open_viewport_keys())
    done = cache.step(describe_context_scene, pass_settings, float(settings.overlay_resolution_scale))
    if done in (COARSE, REFINED) or cache.error:
        _tag_redraw()
    if done is not None or cache.pending(float(settings.overlay_resolution_scale)) is not None:
        return BUSY_INTERVAL
    return IDLE_INTERVAL


def install() -> None:
    """Add the draw handler (register())."""
    global _draw_handle
    import bpy

    if _draw_handle is None:
        _draw_handle = bpy.types.SpaceView3D.draw_handler_add(draw_callback, (), "WINDOW", "POST_PIXEL")


def uninstall() -> None:
    """Remove the draw handler and free every GPU resource (unregister())."""
    global _draw_handle
    import bpy

    if _draw_handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_draw_handle, "WINDOW")
        _draw_handle = None
    cache.free()
    _tag_redraw()


def is_installed() -> bool:
    return _draw_handle is not None


HANDLERS = (("depsgraph_update_post", on_depsgraph_update), ("frame_change_post", on_frame_change),
            ("load_pre", on_load_pre))
TIMERS = ((timer, {"first_interval": OFF_INTERVAL, "persistent": True}),)
HOOKS = ((install, uninstall),)
