# SPDX-License-Identifier: GPL-3.0-or-later
"""A viewport's progressive, GPU-resident view of the VSGL light, without Blender's bpy (the glue is
engine.py's view_update / view_draw for Rendered shading, overlay.py for the overlay over other
engines' viewports: both draw through this one pipeline).

:class:`ViewPipeline` does one unit of work per :meth:`ViewPipeline.step`, each sized to about
STEP_BUDGET seconds, so the interface stays responsive:

* after a scene change (:meth:`~ViewPipeline.mark_scene_dirty`, or other pass settings) the
  **light passes** (RSMs, VSGL tables) and, in the same step, a **coarse** image: the view passes at
  the resolution scale, upsampled to the viewport's pixels by the joint bilateral filter guided by
  the full-resolution G-buffer (glsl/lib/bilateral.glsl), so edges stay sharp;
* after a view-only change, the coarse image alone: the light passes are kept; the full-resolution
  guide is kept across changes that leave the view and the triangles (a light, a material);
* then, while nothing changes, **samples** at full resolution, each in bands of rows sized to the
  budget from the measured time per pixel; every sample after the first one has light passes of a
  new seed (a new rotation of the VSGL lattice per light and view, pipeline._rotation), and the
  samples are averaged, so the image converges to the techniques' expected value over the lattice
  rotation, as Cycles' viewport samples converge to its render.

Moving anything restarts from a coarse image. The images never leave the GPU: the backend
(view_gpu.GPUViewBackend) resolves every render into the viewport's accumulation textures and draws
their average; tests replace it with a fake one, and the clock with a fake clock.

:class:`ViewportSet` holds the overlay's pipelines, one per 3D viewport; :func:`step_next` steps the
pipeline whose turn it is, for the overlay's timer and the engine's alike.
"""

from __future__ import annotations

import time
import traceback
from collections import deque

import numpy as np

from dataclasses import dataclass

from .settings import VSGLSettings
from .views import band_projection

#: Seconds one step should take (one frame here): bands of full-resolution samples are sized to it.
STEP_BUDGET = 0.06
#: The share of a band's step left after its fixed cost that its rows are sized to when their costs
#: come from the previous sample's rows: another seed's lights and the machine's load make them
#: vary by tens of per cent, and sized to all of it, half the steps went over the budget
#: (benchmarks/results/interactive_session.md: refinement steps median 60 ms, 43 % over 60 ms).
BAND_SHARE = 0.8
#: The share of what a coarse image's step leaves after its light passes and its fixed view cost
#: (guide, resolve) that its view passes are sized to, for the same reason: the light passes and the
#: passes' own time vary from edit to edit, and sized to all of it the step's median sat at the
#: budget (benchmarks/results/latency_resolve_weights.md). Budget mode's predicted view render
#: (budget.coarse_factor) is fitted to this share of what the step leaves after its light passes.
COARSE_SHARE = 0.8
#: The share of the step a light-pass stage's time from the last build may fill: another seed's
#: stage costs more or less (in Blender 5.2's window 13 % of the samples' light-pass steps ran
#: 60-104 ms, benchmarks/results/latency_resolve_weights.md).
STAGE_SHARE = 0.8
#: Samples averaged before the viewport stops refining (the property viewport_samples overrides it).
DEFAULT_SAMPLES = 16
LIGHTS, COARSE, SAMPLE = "lights", "coarse", "sample"
#: The coarse image after a change is lit by light passes of N / PREVIEW_VSGL_DIVISOR VSGLs per set
#: (at least PREVIEW_MIN_VSGLS): as many fewer imperfect shadow maps, the light build's largest
#: stage (benchmarks/results/light_build_profile.md), and lobes summed per pixel by VSGL shading,
#: the coarse view passes' largest; and by RSMs of half the side (at least PREVIEW_MIN_RSM_SIZE):
#: a quarter of the texels to render, reduce into mip chains and extract VPLs from. Fewer VSGLs are
#: wider Gaussians of the same reflected light (000 Eq. 5), a smoother estimate of it. The preview
#: also leaves out the glossy VPLs and MRP-ASG (PREVIEW_CELLS): their cells' light (light-paths.md)
#: then stays in the VSGLs, the one set of every reflector that lights every receiver lobe, as with
#: both techniques off, so the coarse image keeps every path, blurrier, for one VSGL set's RSMs,
#: maps and shading instead of three sets' plus the VPLs' and proxies' passes; unless the viewport
#: shows that technique's own pass. The samples rebuild the passes at the settings' own N, RSM
#: size and techniques, so the converged image is the one without the preview
#: (benchmarks/first_coarse_image.py, tests/test_view_pipeline_gpu.py).
PREVIEW_VSGL_DIVISOR = 8
PREVIEW_MIN_VSGLS = 16
PREVIEW_MIN_RSM_SIZE = 32
#: The preview's imperfect shadow maps: PREVIEW_ISM_SIZE² texels of PREVIEW_ISM_POINTS points (or the
#: settings' own when smaller). N / 8 VSGLs are wide Gaussians whose lookups filter over several
#: texels of a 64² map, so smaller maps change the coarse image little: in a one-off comparison
#: when this was chosen (not kept as a benchmark), the coarse image's relative RMSE against the
#: converged one at 82×49 of a 328×197 region was 0.244 / 0.281 / 0.604 with these maps and 0.244 /
#: 0.297 / 0.604 with 64² maps of 4096 points (demo / caustic panel / polished metal floor), for
#: about a third of the maps' time.
PREVIEW_ISM_SIZE = 32
PREVIEW_ISM_POINTS = 1024
#: The techniques the preview leaves out: setting -> the viewport pass that shows that technique alone.
PREVIEW_CELLS = {"caustics": "indirect_caustics", "glossy_reflectors": "indirect_glossy_reflectors"}


def preview_light_settings(settings: VSGLSettings, view_pass: str | None = None) -> VSGLSettings:
    """The settings of the coarse image's light passes (see PREVIEW_VSGL_DIVISOR) for a viewport that
    shows ``view_pass``; ``settings`` itself when they would be no cheaper."""
    count = max(settings.vsgl_count // PREVIEW_VSGL_DIVISOR, min(PREVIEW_MIN_VSGLS, settings.vsgl_count))
    size = max(settings.rsm_size // 2, min(PREVIEW_MIN_RSM_SIZE, settings.rsm_size))
    cells = {name: False for name, shown_by in PREVIEW_CELLS.items()
             if getattr(settings, name) and view_pass != shown_by}
    ism_size, ism_points = min(settings.ism_size, PREVIEW_ISM_SIZE), min(settings.ism_points, PREVIEW_ISM_POINTS)
    if (count >= settings.vsgl_count and size >= settings.rsm_size and not cells
            and (ism_size, ism_points) == (settings.ism_size, settings.ism_points)):
        return settings
    return settings.overridden(vsgl_count=count, rsm_size=size, ism_size=ism_size, ism_points=ism_points, **cells)


@dataclass
class ViewRequest:
    """What a viewport last drew with: its view, projection and region size."""

    view_matrix: np.ndarray
    projection_matrix: np.ndarray
    region_size: tuple[int, int]


def same_view(a: ViewRequest, b: ViewRequest) -> bool:
    return (a.region_size == b.region_size and np.array_equal(a.view_matrix, b.view_matrix)
            and np.array_equal(a.projection_matrix, b.projection_matrix))


@dataclass(frozen=True)
class OverlayLook:
    """How the overlay lays a view over another engine's viewport (the Rendered mode draws with
    None: opaque, linear, Blender's colour management after). `scale` = intensity × 2^exposure and
    `gamma` are the Standard view transform's; `added`: blended onto the viewport (ONE, ONE) instead
    of over it by coverage; `encode_srgb`: for framebuffers that do not encode to sRGB themselves."""

    scale: float = 1.0
    gamma: float = 1.0
    added: bool = False
    encode_srgb: bool = False


def geometry_key(scene) -> bytes | None:
    """What the guide G-buffer's positions and normals depend on besides the view: the triangles'
    corners and shading normals (a hash of their bytes); None for a scene without geometry arrays."""
    geometry = getattr(scene, "geometry", None)
    if geometry is None:
        return None
    import hashlib

    digest = hashlib.blake2b(digest_size=16)
    for array in (geometry.positions, geometry.normals):
        array = np.ascontiguousarray(array)
        digest.update(repr(array.shape).encode())
        digest.update(array.tobytes())
    return digest.digest()


def view_size(region_size, scale: float) -> tuple[int, int]:
    """Pixels of a view render of a region of `region_size` (w, h) at resolution `scale`."""
    return tuple(max(1, int(round(side * scale))) for side in region_size)


class ViewPipeline:
    """One viewport's light passes, accumulation images and progress (see the module documentation)."""

    def __init__(self, backend=None, clock=time.perf_counter, step_budget: float = STEP_BUDGET,
                 preview_lights: bool = True):
        """``preview_lights``: light the coarse image after a change with preview_light_settings'
        passes (False: with the settings' own, as every sample is)."""
        if backend is None:
            from .view_gpu import GPUViewBackend

            backend = GPUViewBackend()
        self.backend = backend
        self.clock = clock
        self.step_budget = step_budget
        self.scene_version = 0
        self.lights = None  # renderer.SceneLights of lights_version, base settings + lights_seed
        self.lights_version = -1
        self.lights_settings: VSGLSettings | None = None  # the base settings (seed offset 0)
        self.lights_seed = 0  # seed offset of the current light passes
        self.preview_lights = preview_lights
        self.lights_preview = False  # the current light passes are preview_light_settings'
        self.view_pass: str | None = None  # the pass last drawn, which the preview keeps (PREVIEW_CELLS)
        self._lights_built = None  # the settings the current light passes were built with
        # A staged build of the samples' light passes under way: [key, settings, generator, stages
        # done].
        self._building = None
        self._stage_seconds: dict = {}  # settings -> seconds of each stage of their last build
        self.renderer = None
        self.request: ViewRequest | None = None
        self.target = None  # accumulation images at the region's size
        self.sample_target = None  # the full-resolution sample being rendered band by band
        # The full-resolution guide of the coarse image's upsampling (a G-buffer: positions, normals),
        # kept while the view and the triangles stay: a light or material edit reuses it.
        self.guide = None
        self._guide_for = None  # (geometry key, request) of `guide`
        self._geometry = None  # (scene description, geometry_key) of the last description hashed
        self.guide_builds = 0
        self._accumulated_for = None  # (lights_version, request, scale) of the target's content
        self.samples = 0  # full-resolution samples in the target (0: it holds the coarse image)
        self._seeds_used: set[int] = set()
        self._rows_done = 0
        self._band_seed = None
        self._seconds_per_pixel: float | None = None
        # A band's cost is a fixed part (passes set up per light, the resolve, the wait for the GPU)
        # plus a part per pixel, fitted to the last bands' (pixels, seconds): with the per-pixel part
        # alone, a slow machine's fixed cost shrinks the bands to a row each.
        self._band_times: deque = deque(maxlen=8)
        self._band_fixed_seconds: float | None = None
        # Seconds of each row beyond the band's fixed part, measured band by band over the last
        # sample of this view: the next sample's rows cost the same, so its bands are sized from it.
        self._row_seconds: np.ndarray | None = None
        # The coarse image's resolution as a fraction of the asked scale: lowered when a coarse image
        # took longer than the step budget, raised again when it took well under (never above 1).
        self.coarse_factor = 1.0
        # The backend's cost model (budget.CostModel; None: the backend has none): in Budget mode it
        # sets the first coarse factor of each new light passes' settings, measured times take over.
        self.cost_model = None
        self._model_settings = None  # the settings the coarse factor was last predicted for
        self.has_image = False
        self.step_args = None  # set by the glue: (settings, scale, samples) of the timer's steps
        self.steps = 0
        self.statistics: dict = {}
        self.history: deque = deque(maxlen=4096)
        self.warnings: tuple[str, ...] = ()
        self.error: str | None = None

    # --- inputs -----------------------------------------------------------------------------
    def mark_scene_dirty(self) -> None:
        self.scene_version += 1
        self.error = None

    def request_view(self, view_matrix, projection_matrix, region_size) -> bool:
        """Record the viewport's view (view_draw: plain numbers only). True if it changed."""
        request = ViewRequest(np.array(view_matrix, np.float64), np.array(projection_matrix, np.float64),
                              (int(region_size[0]), int(region_size[1])))
        if self.request is not None and same_view(self.request, request):
            return False
        self.request = request
        return True

    # --- what next ------------------------------------------------------------------------------
    def _lights_stale(self, settings: VSGLSettings) -> bool:
        return (self.lights is None or self.lights_version != self.scene_version
                or settings != self.lights_settings)

    def _fresh(self, scale: float) -> bool:
        key = self._accumulated_for
        return (key is not None and self.target is not None and key[0] == self.lights_version
                and key[2] == scale and same_view(key[1], self.request))

    def pending(self, settings: VSGLSettings, scale: float, max_samples: int = DEFAULT_SAMPLES) -> str | None:
        """The next unit of work: LIGHTS (followed by COARSE in the same step), COARSE, SAMPLE or None."""
        if self.request is None or self.error is not None:
            return None
        if self._lights_stale(settings):
            return LIGHTS
        if not self._fresh(scale):
            return COARSE
        if self.samples < max_samples:
            return SAMPLE
        return None

    def converged(self, max_samples: int = DEFAULT_SAMPLES) -> bool:
        return self.has_image and self.samples >= max_samples

    # --- work (main thread, GPU context) --------------------------------------------------------
    def step(self, describe_scene, settings: VSGLSettings, scale: float,
             max_samples: int = DEFAULT_SAMPLES) -> str | None:
        """Do one unit of work; returns what it did (LIGHTS means light passes and a coarse image).

        `describe_scene()` returns the SceneDescription (called only when the light passes rerun). A
        failure stores its message in `error` and stops updates until the scene changes again.
        """
        work = self.pending(settings, scale, max_samples)
        if work is None:
            return None
        started = self.clock()
        entry = {"index": self.steps, "work": work}
        try:
            if work == LIGHTS:
                entry["light_seconds"] = self._rebuild_lights(describe_scene, settings, 0,
                                                              preview=self._coarse_is_preview(scale))
                entry["preview_lights"] = self.lights_preview
                work = COARSE
            if work == COARSE or not self._fresh(scale):
                entry.update(self._render_coarse(scale, entry.get("light_seconds", 0.0)))
            else:
                entry.update(self._refine(describe_scene, settings, started, max_samples))
        except Exception as error:  # noqa: BLE001 - shown in the header, never raised into Blender's loop
            self.error = f"{type(error).__name__}: {error}"
            self._close_build()
            self._free_lights()
            entry["error"] = self.error
            entry["traceback"] = traceback.format_exc()
        entry["started"], entry["ended"] = started, self.clock()
        entry["seconds"] = entry["ended"] - started
        entry["samples"] = self.samples
        self.statistics = entry
        self.history.append(entry)
        self.steps += 1
        return entry["work"]

    def _coarse_is_preview(self, scale: float) -> bool:
        """Whether the coarse image about to be made is smaller than the region (at its size it is
        the first sample, whose light passes are the settings' own)."""
        full = tuple(self.request.region_size)
        return self.preview_lights and view_size(full, scale * self.coarse_factor) != full

    def _describe(self, describe_scene):
        """The scene description of the current scene state: the current light passes' own when
        they are of it (a new seed or the preview's replacement changes nothing of the scene), else
        describe_scene()'s."""
        if self.lights is not None and self.lights_version == self.scene_version:
            description = getattr(self.lights, "scene", None)
            if description is not None:
                return description
        description = describe_scene()
        self.warnings = tuple(description.warnings)
        return description

    def _rebuild_lights(self, describe_scene, settings: VSGLSettings, seed_offset: int,
                        preview: bool = False) -> float:
        started = self.clock()
        self._close_build()
        description = self._describe(describe_scene)
        self._free_lights()
        if self.renderer is None:
            self.renderer = self.backend.frame_renderer()
        version = self.scene_version
        seeded = settings if seed_offset == 0 else settings.overridden(seed=settings.seed + seed_offset)
        # Passes of the settings' own that another viewport holds cost nothing: no preview then.
        if preview and getattr(self.backend, "has_lights", lambda _: False)(seeded):
            preview = False
        built = preview_light_settings(seeded, self.view_pass) if preview else seeded
        self.lights = self.backend.scene_lights(description, built)
        self.lights_version, self.lights_settings, self.lights_seed = version, settings, seed_offset
        self.lights_preview, self._lights_built = built is not seeded, built
        return self.clock() - started

    def _advance_lights(self, describe_scene, settings: VSGLSettings, seed_offset: int, started: float):
        """The samples' light passes of ``seed_offset``, built in stages (the backend's
        scene_lights_stages) over as many steps as the step budget needs: a step runs one stage,
        then the next ones while each one's predicted time still fits in it; the current light
        passes stay until the new ones are complete (a view change in between renders its coarse
        image with them). Returns (complete, seconds of this step's stages). A backend without
        stages builds them at once."""
        stages_of = getattr(self.backend, "scene_lights_stages", None)
        if stages_of is None:
            return True, self._rebuild_lights(describe_scene, settings, seed_offset)
        clock = self.clock()
        key = (self.scene_version, settings, seed_offset)
        if self._building is None or self._building[0] != key:
            self._close_build()
            seeded = settings if seed_offset == 0 else settings.overridden(seed=settings.seed + seed_offset)
            self._building = [key, seeded, stages_of(self._describe(describe_scene), seeded), 0]
        _, seeded, stages, _ = self._building
        # Each stage's seconds in the last build of these settings (another seed's: the same work)
        # predict whether the next one still fits in this step.
        known = self._stage_seconds.get(settings, [])
        last = None
        while True:
            index = self._building[3]
            if last is not None:
                predicted = known[index] if index < len(known) else last
                if self.clock() - started + predicted / STAGE_SHARE > self.step_budget:
                    return False, self.clock() - clock
            stage_started = self.clock()
            try:
                next(stages)
            except StopIteration as done:
                self._building = None
                self._free_lights()
                if self.renderer is None:
                    self.renderer = self.backend.frame_renderer()
                self.lights = done.value
                self.lights_version, self.lights_settings, self.lights_seed = key
                self.lights_preview, self._lights_built = False, seeded
                return True, self.clock() - clock
            except BaseException:
                self._building = None
                raise
            last = self.clock() - stage_started
            seconds = self._stage_seconds.setdefault(settings, [])
            seconds[index:index + 1] = [last]
            self._building[3] = index + 1

    def _close_build(self) -> None:
        """Abandon a staged light build (what it made so far is freed)."""
        if self._building is not None:
            building, self._building = self._building, None
            building[2].close()

    def _ensure_target(self, attribute: str, size):
        target = getattr(self, attribute)
        if target is None or tuple(target.size) != tuple(size):
            if target is not None:
                target.free()
            target = self.backend.target(*size)
            setattr(self, attribute, target)
        return target

    def _seeded_settings(self):
        """The settings the current light passes were built with (the view passes read them too)."""
        return self._lights_built

    def _render_coarse(self, scale: float, spent: float = 0.0) -> dict:
        """The coarse image, sized to what the step has left after ``spent`` seconds (its light
        passes, when it rebuilt them) and after the part of the view render its size does not
        change (the full-resolution guide and resolve): its view passes get the rest, at least a
        quarter of the step budget."""
        # A new view restarts the samples: a build for the old ones is abandoned.
        self._close_build()
        request = self.request
        full = request.region_size
        available = max(self.step_budget - spent, self.step_budget / 4)
        predicted = self._predict_coarse_factor(full, scale, available)
        width, height = view_size(full, scale * self.coarse_factor)
        started = self.clock()
        target = self._ensure_target("target", full)
        view = self.backend.render_view(self.renderer, self.lights, self._seeded_settings(), width, height,
                                        request.view_matrix, request.projection_matrix,
                                        preview=(width, height) != tuple(full))
        try:
            self.backend.finish_view(view)
            passes = self.clock() - started
            guide = self.backend.guide_of(view) if (width, height) == tuple(full) else self._full_guide(request)
            self.backend.resolve(view, guide, target, None, 1.0, add=False)
            counts = view.counts  # lazy: the VPL count is read back only when the statistics are shown
        finally:
            view.free()
        self.backend.finish(target)
        seconds = self.clock() - started
        if self._seconds_per_pixel is None:
            self._seconds_per_pixel = seconds / (width * height)
        # The view passes' cost grows with the pixels, i.e. with the factor squared; the
        # full-resolution guide and resolve do not shrink with it, so they are left out of the
        # passes' share (a factor chasing them would shrink the image to nothing for no time), and
        # the factor moves by at most 2x per coarse image.
        share = COARSE_SHARE * max(available - (seconds - passes), self.step_budget / 4)
        if passes > share:
            self.coarse_factor = max(self.coarse_factor * max((share / passes) ** 0.5, 0.5), 0.05)
        elif passes < 0.5 * share and self.coarse_factor < 1.0:
            self.coarse_factor = min(self.coarse_factor * min((0.7 * share / max(passes, 1e-9)) ** 0.5, 2.0), 1.0)
        self._accumulated_for = (self.lights_version, request, scale)
        self._seeds_used = set()
        self._rows_done = 0
        self._band_seed = None
        self._row_seconds = None  # a new view, scene or setting: its rows cost what they cost
        # At scale 1 the coarse image is a full-resolution sample already (unless preview-lit).
        self.samples = 1 if (width, height) == tuple(full) and not self.lights_preview else 0
        if self.samples:
            self._seeds_used.add(self.lights_seed)
        self.has_image = True
        entry = {"level": COARSE, "size": (width, height), "view_seconds": seconds, "view_passes_seconds": passes,
                 "counts": counts,
                 "coarse_scale": scale * self.coarse_factor if (width, height) != tuple(full) else 1.0}
        if predicted is not None:
            entry["predicted_view_seconds"] = predicted
        return entry

    def _guide_key(self):
        scene = getattr(self.lights, "scene", None)
        if self._geometry is None or self._geometry[0] is not scene:
            self._geometry = (scene, geometry_key(scene))
        return self._geometry[1] if self._geometry[1] is not None else ("state", self.lights_version)

    def _guide_kept(self, request: ViewRequest) -> bool:
        """The kept guide serves `request` with the current triangles."""
        kept = self._guide_for
        return self.guide is not None and kept[0] == self._guide_key() and same_view(kept[1], request)

    def _full_guide(self, request: ViewRequest):
        """The guide G-buffer at the region's size: kept across changes of the lights, materials or
        settings, rendered again when the view or the triangles changed (geometry_key; a scene
        without geometry arrays: when the light passes were rebuilt for a new scene state)."""
        if not self._guide_kept(request):
            if self.guide is not None:
                self.guide.free()
            self.guide = None
            self.guide = self.backend.guide(self.renderer, self.lights, request.region_size[0],
                                            request.region_size[1], request.view_matrix, request.projection_matrix)
            self._guide_for = (self._guide_key(), request)
            self.guide_builds += 1
        return self.guide

    def _predict_coarse_factor(self, full, scale: float, available: float) -> float | None:
        """In Budget mode, with the backend's cost model (budget.py, the time budget's): the coarse
        factor whose view render it predicts within COARSE_SHARE of what the step has left, once per
        new settings of the light passes (not per seed, view or edit: there the measured times adjust
        it). Returns the predicted seconds. Manual mode starts at the asked scale, as before (at scale 1 the first
        image is then a full-resolution sample)."""
        plan = getattr(self.lights, "plan", None)
        settings = self.lights_settings
        if plan is None or settings.quality_mode != "budget" or settings == self._model_settings:
            return None
        if self.cost_model is None:
            load = getattr(self.backend, "cost_model", None)
            if load is None:
                return None
            self.cost_model = load()
            if self.cost_model.warning:
                self.warnings = (*self.warnings, self.cost_model.warning)
        from .budget import coarse_factor

        from .reference.vpl_culling import preview_stride

        self._model_settings = settings
        # The view passes shade the tables the light passes were built with: the preview's when it lit them.
        built = self._lights_built if self._lights_built is not None else settings
        scene = getattr(self.lights, "scene", None)
        triangles = int(scene.geometry.triangle_count) if scene is not None else 0
        # VPLs per RSM texel when the CPU knows the count (read before, for the statistics): no
        # read-back for it; else the cost model's default fraction.
        vpls = getattr(self.lights, "vpls", None)
        known = getattr(vpls, "known_count", None)
        views = sum(light.rsm_views for light in plan.lights if light.gets_rsm)
        fraction = known / (views * built.rsm_size ** 2) if known is not None and views else None
        self.coarse_factor, predicted = coarse_factor(plan, built, full, scale, COARSE_SHARE * available,
                                                      self.cost_model, triangles, fraction,
                                                      preview_stride(built.rsm_size ** 2),
                                                      guide=not self._guide_kept(self.request))
        return predicted

    def _refine(self, describe_scene, settings: VSGLSettings, started: float, max_samples: int) -> dict:
        entry: dict = {"level": SAMPLE}
        if self._rows_done == 0 and (self.lights_preview or self.lights_seed in self._seeds_used):
            # The preview's passes lit the coarse image only: the samples' are the settings' own,
            # of the same seed. Else the next sample needs light passes of a seed this accumulation
            # has not used yet.
            offset = self.lights_seed if self.lights_preview else max(self._seeds_used) + 1
            complete, entry["light_seconds"] = self._advance_lights(describe_scene, settings, offset, started)
            entry["lights_complete"] = complete
            if not complete or self.clock() - started > self.step_budget / 2:
                entry["rows"] = (0, 0, self.request.region_size[1])
                return entry
        request = self.request
        width, height = request.region_size
        sample = self._ensure_target("sample_target", (width, height))
        remaining = max(self.step_budget - (self.clock() - started), self.step_budget / 4)
        fixed = self._band_fixed_seconds or 0.0
        rows = height if not self._seconds_per_pixel else int((remaining - fixed) / (self._seconds_per_pixel * width))
        # At least one row, so a sample always progresses; not more, so that a wide viewport on a
        # slow GPU (a 1311-pixel row costs about 13 ms on llvmpipe) still keeps each step near the
        # budget: a floor of height / 64 rows made steps of 150-800 ms there.
        rows = max(rows, 1)
        first = self._rows_done
        profile = self._row_seconds
        if profile is not None and len(profile) == height and np.all(np.isfinite(profile[first:])):
            rows = max(int(np.searchsorted(np.cumsum(profile[first:]), BAND_SHARE * (remaining - fixed),
                                           side="right")), 1)
        elif self._band_times:
            # Without it a band at most doubles the last: rows differ in cost (sky above the scene
            # costs nothing), so a rate measured on cheap rows must not size one band for the rest.
            rows = min(rows, 2 * max(int(self._band_times[-1][0]) // width, 1))
        end = min(height, first + max(1, rows))
        clock = self.clock()
        view = self.backend.render_view(self.renderer, self.lights, self._seeded_settings(), width, end - first,
                                        request.view_matrix, band_projection(request.projection_matrix,
                                                                             first, end, height))
        try:
            self.backend.resolve(view, self.backend.guide_of(view), sample, (first, end), 1.0, add=False)
        finally:
            view.free()
        self.backend.finish(sample)
        seconds = self.clock() - clock
        self._fit_band_cost(width * (end - first), seconds)
        if self._row_seconds is None or len(self._row_seconds) != height:
            self._row_seconds = np.full(height, np.nan)
        self._row_seconds[first:end] = max(seconds - self._band_fixed_seconds, 0.0) / (end - first)
        self._rows_done = end
        entry["rows"] = (first, end, height)
        if end >= height:
            self.backend.accumulate(sample, self.target, 1.0, add=self.samples > 0)
            self.backend.finish(self.target)
            self.samples += 1
            self._seeds_used.add(self.lights_seed)
            self._rows_done = 0
        return entry

    def _fit_band_cost(self, pixels: int, seconds: float) -> None:
        """seconds ≈ fixed + per_pixel × pixels over the last bands (least squares; the fixed part
        within [0, 0.8 budget], zero while the bands' sizes barely differ)."""
        self._band_times.append((float(pixels), float(seconds)))
        x = np.array([p for p, _ in self._band_times])
        y = np.array([t for _, t in self._band_times])
        fixed = 0.0
        if len(x) >= 2 and x.std() > 0.2 * x.mean():
            slope = float(((x - x.mean()) * (y - y.mean())).sum() / ((x - x.mean()) ** 2).sum())
            fixed = float(np.clip(y.mean() - slope * x.mean(), 0.0, 0.8 * self.step_budget))
        # No band costs less than its fixed part; and the last band's rate, from the rows next to the
        # coming ones, is a floor: bands of cheap rows (larger, later ones when the bottom rows are
        # empty) give the fit a negative slope, whose fixed part would make every pixel free.
        fixed = min(fixed, 0.9 * float(y.min()))
        self._band_fixed_seconds = fixed
        self._seconds_per_pixel = max(float(np.mean((y - fixed) / x)), float((y[-1] - fixed) / x[-1]), 1e-12)

    # --- drawing (view_draw) ------------------------------------------------------------------
    def draw(self, view_pass: str, look: OverlayLook | None = None) -> bool:
        """Draw the average of the accumulated images into the bound framebuffer (as the overlay
        lays it over a viewport with `look`); False if there is none."""
        self.view_pass = view_pass
        if not self.has_image or self.target is None:
            return False
        self.backend.display(self.target, 1.0 / max(self.samples, 1), view_pass, look)
        return True

    def status_text(self, max_samples: int = DEFAULT_SAMPLES) -> str:
        """The header line, as Cycles': the sample count and the last step's time."""
        if self.error:
            return f"VSGL error: {self.error}"
        if not self.has_image:
            return "VSGL: computing light passes…"
        step = self.statistics.get("seconds", 0.0) * 1000.0
        if self.samples == 0:
            size = self.statistics.get("size")
            what = f"coarse {size[0]}×{size[1]}, upsampled" if size else "coarse"
            return f"VSGL {what} | {step:.0f} ms/step"
        done = " (converged)" if self.samples >= max_samples else ""
        return f"VSGL sample {self.samples}/{max_samples}{done} | {step:.0f} ms/step"

    # --- freeing -------------------------------------------------------------------------------
    def _free_lights(self) -> None:
        if self.lights is not None:
            self.lights.free()
        self.lights = None
        self.lights_version = -1
        self.lights_settings = None
        self.lights_seed = 0
        self.lights_preview = False
        self._lights_built = None

    def free(self) -> None:
        """Release every GPU resource; the next step starts from scratch."""
        self._close_build()
        self._stage_seconds.clear()
        self._free_lights()
        for attribute in ("target", "sample_target", "guide"):
            target = getattr(self, attribute)
            if target is not None:
                target.free()
            setattr(self, attribute, None)
        if self.renderer is not None:
            self.renderer.free()
        self.renderer = None
        free_backend = getattr(self.backend, "free", None)  # the point sets it keeps across builds
        if free_backend is not None:
            free_backend()
        self._accumulated_for = None
        self._guide_for = None
        self._geometry = None
        self.samples = 0
        self.has_image = False
        self.step_args = None
        self._rows_done = 0
        self._seconds_per_pixel = None
        self._band_fixed_seconds = None
        self._band_times.clear()
        self._row_seconds = None

    def gpu_resource_count(self) -> int:
        """GPU objects held (0 after free()): light passes, renderer, accumulation targets, guide."""
        backend_count = getattr(self.backend, "gpu_resource_count", None)
        return ((self.lights is not None) + (self.renderer is not None)
                + sum(getattr(self, name) is not None for name in ("target", "sample_target", "guide"))
                + (backend_count() if backend_count is not None else 0))


def has_work(pipeline) -> bool:
    """The glue has handed `pipeline` its step arguments and something is pending for them."""
    return getattr(pipeline, "step_args", None) is not None and pipeline.pending(*pipeline.step_args) is not None


def step_next(pipelines, describe_scene) -> ViewPipeline | None:
    """One step of the pipeline whose turn it is among those with work (their `step_args` set by
    the glue: settings, scale, samples): round robin by steps done, so several viewports refine
    together. Returns the pipeline stepped, or None when none had work."""
    busy = [p for p in list(pipelines) if has_work(p)]
    if not busy:
        return None
    pipeline = min(busy, key=lambda p: p.steps)
    pipeline.step(describe_scene, *pipeline.step_args)
    return pipeline


class _SharedLight:
    """A SceneLights several viewports use: freed when the last of them lets go."""

    def __init__(self, lights, release):
        self._lights, self._release, self._freed = lights, release, False

    def __getattr__(self, name):
        return getattr(self._lights, name)

    def free(self) -> None:
        if not self._freed:
            self._freed = True
            self._release()


class _SharedLightsBackend:
    """A pipeline's backend whose light passes are shared by every viewport of a ViewportSet: the
    same scene state and settings (seed included) are built once, whatever the viewport count."""

    def __init__(self, viewports: "ViewportSet", backend):
        self._viewports, self._backend = viewports, backend

    def __getattr__(self, name):
        return getattr(self._backend, name)

    def scene_lights(self, description, settings):
        return self._viewports._acquire_lights(self._backend, description, settings)

    def scene_lights_stages(self, description, settings):
        """scene_lights in the backend's stages; none when another viewport holds these passes
        already, and the passes another viewport completed meanwhile are taken instead of its own."""
        viewports = self._viewports
        key = (viewports.scene_version, settings)
        stages_of = getattr(self._backend, "scene_lights_stages", None)
        if key not in viewports._lights and stages_of is not None:
            built = yield from stages_of(description, settings)
            if key in viewports._lights:
                built.free()
            else:
                viewports._lights[key] = [built, 0]
        return viewports._acquire_lights(self._backend, description, settings, key)

    def has_lights(self, settings: VSGLSettings) -> bool:
        """Whether another viewport holds light passes of this scene state and settings."""
        return (self._viewports.scene_version, settings) in self._viewports._lights

    def free(self) -> None:
        """Nothing: the shared backend is the ViewportSet's, freed with it."""

    def gpu_resource_count(self) -> int:
        return 0  # the shared backend's are counted once, by the ViewportSet


class ViewportSet:
    """The overlay's view pipelines, one per 3D viewport (keyed by its region data's pointer), with
    the state the panels show. The viewports share their light passes (RSMs, VSGL tables) and the
    scene description; a viewport that closed is freed by :meth:`retain`."""

    def __init__(self, backend_factory=None, clock=time.perf_counter, step_budget: float | None = None):
        self._backend_factory = backend_factory
        self.step_budget = STEP_BUDGET if step_budget is None else step_budget
        self._backend = None
        self.clock = clock
        self.pipelines: dict[int, ViewPipeline] = {}
        self.last: ViewPipeline | None = None  # the pipeline stepped last (the panels' statistics)
        self.settings_error: str | None = None  # settings the passes refuse: no step until fixed
        self.scene_version = 0
        self._description = None  # (scene_version, SceneDescription)
        self._lights: dict = {}  # (scene_version, settings) -> [SceneLights, users]

    def pipeline(self, key: int) -> ViewPipeline:
        pipeline = self.pipelines.get(key)
        if pipeline is None:
            if self._backend is None:
                if self._backend_factory is not None:
                    self._backend = self._backend_factory()
                else:
                    from .view_gpu import GPUViewBackend

                    self._backend = GPUViewBackend()
            pipeline = self.pipelines[key] = ViewPipeline(_SharedLightsBackend(self, self._backend), self.clock,
                                                             self.step_budget)
        return pipeline

    def _acquire_lights(self, backend, description, settings: VSGLSettings, key=None):
        key = (self.scene_version, settings) if key is None else key
        entry = self._lights.get(key)
        if entry is None:
            entry = self._lights[key] = [backend.scene_lights(description, settings), 0]
        entry[1] += 1

        def release():
            entry[1] -= 1
            if entry[1] == 0:
                entry[0].free()
                if self._lights.get(key) is entry:
                    del self._lights[key]

        return _SharedLight(entry[0], release)

    def _describe(self, describe_scene):
        """The scene description of the current scene state, extracted once for every viewport."""
        if self._description is None or self._description[0] != self.scene_version:
            self._description = (self.scene_version, describe_scene())
        return self._description[1]

    def request_view(self, key: int, view_matrix, projection_matrix, region_size) -> bool:
        return self.pipeline(key).request_view(view_matrix, projection_matrix, region_size)

    def set_step_args(self, settings: VSGLSettings, scale: float, samples: int) -> None:
        for pipeline in self.pipelines.values():
            pipeline.step_args = (settings, scale, samples)

    def mark_scene_dirty(self) -> None:
        self.scene_version += 1
        self._description = None
        for pipeline in self.pipelines.values():
            pipeline.mark_scene_dirty()

    def retain(self, keys) -> None:
        """Free the pipelines of viewports not in `keys` (closed, or no longer 3D viewports)."""
        for key in [k for k in self.pipelines if k not in set(keys)]:
            self.forget(key)

    def forget(self, key: int) -> None:
        pipeline = self.pipelines.pop(key, None)
        if pipeline is not None:
            pipeline.free()
            if self.last is pipeline:
                self.last = None
        if not self.pipelines and self._backend is not None and hasattr(self._backend, "free"):
            self._backend.free()  # the last viewport closed: nothing is kept for the next

    def step(self, describe_scene) -> ViewPipeline | None:
        if self.settings_error:
            return None
        stepped = step_next(self.pipelines.values(), lambda: self._describe(describe_scene))
        if stepped is not None:
            self.last = stepped
        return stepped

    def busy(self) -> bool:
        return not self.settings_error and any(has_work(p) for p in self.pipelines.values())

    @property
    def error(self) -> str | None:
        """The settings' error (the glue sets `settings_error`), else the first failed pipeline's."""
        return self.settings_error or next((p.error for p in self.pipelines.values() if p.error), None)

    @property
    def warnings(self) -> tuple[str, ...]:
        return self.last.warnings if self.last is not None else ()

    @property
    def statistics(self) -> dict:
        return self.last.statistics if self.last is not None else {}

    def draw(self, key: int, view_pass: str, look: OverlayLook) -> bool:
        pipeline = self.pipelines.get(key)
        return pipeline is not None and pipeline.draw(view_pass, look)

    def free(self) -> None:
        for key in list(self.pipelines):
            self.forget(key)
        for lights, _ in list(self._lights.values()):
            lights.free()  # none is left once every pipeline let go; this is the safety net
        self._lights.clear()
        if self._backend is not None and hasattr(self._backend, "free"):
            self._backend.free()
        self._description = None
        self.last = None

    def gpu_resource_count(self) -> int:
        """GPU objects held (0 after free()): every pipeline's, and the shared light passes."""
        backend_count = getattr(self._backend, "gpu_resource_count", None)
        return (sum(p.gpu_resource_count() for p in self.pipelines.values()) + len(self._lights)
                + (backend_count() if backend_count is not None else 0))
