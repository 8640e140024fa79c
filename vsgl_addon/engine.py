# SPDX-License-Identifier: GPL-3.0-or-later
"""The `VSGL` render engine: F12 and `blender -b scene.blend -E VSGL -f 1` (Blender-facing only).

It turns the evaluated depsgraph into the plain scene description, hands it to the frame renderer
(renderer.py: the GPU passes) and writes what comes back into Blender's render result: Combined
(direct + one-bounce indirect, alpha = coverage) and the passes Direct, Indirect, Indirect Diffuse,
Indirect Specular, Indirect Glossy Reflectors (the part of Indirect Specular MRP-ASG renders) and
Indirect Caustics (the part of Indirect Diffuse the glossy VPLs render),
all linear and scene-referred in Blender's units, so the compositor,
multilayer EXR and Blender's colour management treat them like Cycles' passes.
"""

from __future__ import annotations

import time
import weakref

import bpy
import numpy as np

from .scene import extract_scene
from .settings import VSGLSettings
from .views import render_size

ENGINE_ID = "VSGL"
# Pass name -> FrameImages attribute (renderer.py).
RENDER_PASSES = {
    "Direct": "direct",
    "Indirect": "indirect",
    "Indirect Diffuse": "indirect_diffuse",
    "Indirect Specular": "indirect_specular",
    # The part of Indirect Specular that MRP-ASG renders (light of sharp planar reflectors, 001).
    "Indirect Glossy Reflectors": "indirect_glossy_reflectors",
    # The part of Indirect Diffuse the glossy VPLs render (sharp reflectors' caustics, 004).
    "Indirect Caustics": "indirect_caustics",
}

#: Timings and counts of the last frame rendered in this process (read by the render command's
#: report and the statistics panel). Render engine instances are short-lived, so they cannot hold it.
last_frame_statistics: dict = {}


#: The view pipelines of the Rendered viewports open now (one engine instance per viewport), so
#: unregister and tests can reach them.
live_pipelines: "weakref.WeakSet" = weakref.WeakSet()


def _matrix(m) -> np.ndarray:
    return np.array([list(row) for row in m], np.float64)


class VSGLRenderEngine(bpy.types.RenderEngine):
    """F12 (render) and the 3D viewport's Rendered shading (view_update / view_draw)."""

    bl_idname = ENGINE_ID
    bl_label = "VSGL"
    bl_use_gpu_context = True
    bl_use_postprocess = True
    bl_use_preview = False
    # Material Preview keeps EEVEE (look-dev with HDRIs); Rendered shows our light.
    bl_use_eevee_viewport = True

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._pipeline = None

    def __del__(self):
        # Leaving Rendered shading (or closing the viewport) destroys the instance.
        pipeline = getattr(self, "_pipeline", None)
        if pipeline is not None:
            pipeline.free()
            self._pipeline = None

    def _view_pipeline(self):
        if self._pipeline is None:
            from .view_pipeline import ViewPipeline

            self._pipeline = ViewPipeline()
            live_pipelines.add(self._pipeline)
        return self._pipeline

    def view_update(self, context, depsgraph):
        """Scene changes of a Rendered viewport: the light passes rerun when something that changes
        the light changed (overlay._light_changed's rule) or the pass settings did.

        That step (light passes and coarse image) runs here, before Blender redraws the window for
        the change, rather than in refine_timer after it: the redraw of the old image with Blender's
        overlays costs about 100 ms on llvmpipe (benchmarks/results/latency.md), and the coarse image
        then waited for it and for the next timer call. view_update runs on the main thread outside
        any draw, as the timer does, and its depsgraph is the evaluated one of this change (Cycles
        syncs from it here too)."""
        from .overlay import _light_changed
        from .scene import extract_scene
        from .view_pipeline import LIGHTS

        pipeline = self._view_pipeline()
        if pipeline.lights is None or _light_changed(depsgraph):
            pipeline.mark_scene_dirty()
        if pipeline.step_args is not None and pipeline.has_image:
            args = _step_args(pipeline, depsgraph.scene.vsgl)
            if args is not None and pipeline.pending(*args) == LIGHTS:
                pipeline.step_args = args
                pipeline.step(lambda: extract_scene(depsgraph), *args)
        self.tag_redraw()

    def view_draw(self, context, depsgraph):
        """The viewport's progressive image so far (refine_timer adds to it), linear in Blender's
        units: Blender's colour management follows, as for F12."""
        import gpu

        from .settings import VIEWPORT_PASSES

        pipeline = self._view_pipeline()
        scene = depsgraph.scene
        region, rv3d = context.region, context.region_data
        properties = scene.vsgl
        pipeline.request_view(_matrix(rv3d.view_matrix), _matrix(rv3d.window_matrix),
                              (region.width, region.height))
        identifier = getattr(properties, "viewport_pass", "COMBINED")
        view_pass = next((c.name for c in VIEWPORT_PASSES if c.identifier == identifier), "combined")
        # The timer (and view_update) do the steps, in the window's GPU context: framebuffers belong
        # to the context that made them, and view_draw runs in the viewport's own.
        pipeline.step_args = _step_args(pipeline, properties)
        samples = int(getattr(properties, "viewport_samples", 16))
        gpu.state.blend_set("ALPHA_PREMULT")
        self.bind_display_space_shader(scene)
        pipeline.draw(view_pass)
        self.unbind_display_space_shader()
        gpu.state.blend_set("NONE")
        self.update_stats("", pipeline.status_text(samples))

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        for name in RENDER_PASSES:
            self.register_pass(scene, renderlayer, name, 3, "RGB", "COLOR")

    def render(self, depsgraph):
        from .renderer import FrameRenderer

        scene = depsgraph.scene
        width, height = render_size(scene.render)
        started = time.perf_counter()
        settings = VSGLSettings.from_properties(scene.vsgl)
        description = extract_scene(depsgraph)
        extraction_seconds = time.perf_counter() - started
        for line in description.warnings:
            self.report({"WARNING"}, line)
        if description.camera is None:
            self.report({"ERROR"}, "VSGL: the scene has no camera")
            return
        self.update_stats("VSGL", "Rendering one-bounce indirect light")
        renderer = FrameRenderer()
        try:
            if settings.quality_mode == "budget":
                images = self._render_budgeted(renderer, description, settings, width, height)
            else:
                images = renderer.render(description, settings, width, height)
        finally:
            renderer.free()
        for name in RENDER_PASSES:
            self.add_pass(name, 3, "RGB", layer=depsgraph.view_layer.name)
        result = self.begin_result(0, 0, width, height, layer=depsgraph.view_layer.name)
        layer = result.layers[0]
        combined = np.concatenate([images.combined, images.coverage[..., None]], axis=-1)
        layer.passes["Combined"].rect = _rows(combined)
        for name, attribute in RENDER_PASSES.items():
            layer.passes[name].rect = _rows(getattr(images, attribute))
        self.end_result(result)
        last_frame_statistics.clear()
        last_frame_statistics.update(
            timings={"scene_extraction": extraction_seconds, **images.timings},
            counts=dict(images.counts), settings=settings.__dict__.copy(),
            resolution=[width, height], warnings=list(description.warnings), proxies=list(images.proxies),
            plan=images.plan.to_dict() if images.plan is not None else {})


    def _render_budgeted(self, renderer, description, settings, width, height):
        """Budget mode (budget.py): this GPU's cost model (calibrated on this scene when the user's
        cache has none), the frame at the chosen settings, the model refitted with it and saved."""
        import gpu

        from .budget import save_model
        from .budget_render import model_for, render_budgeted

        key = gpu.platform.renderer_get()
        model = model_for(renderer, description, settings, width, height, key,
                          log=lambda line: self.report({"INFO"}, line))
        if model.warning:
            self.report({"WARNING"}, model.warning)
        images, _, model = render_budgeted(renderer, description, settings, width, height, model)
        save_model(key, model)
        return images


def _step_args(pipeline, properties):
    """(settings, resolution scale, samples) of a viewport's steps from scene.vsgl; None (and the
    pipeline's error set) when the settings are refused."""
    scale = float(getattr(properties, "viewport_resolution_scale", 0.25))
    samples = int(getattr(properties, "viewport_samples", 16))
    try:
        settings = VSGLSettings.from_properties(properties)
    except ValueError as error:
        pipeline.error = str(error)
        return None
    return settings, scale, samples


def _rows(image: np.ndarray) -> np.ndarray:
    """(H, W, C) image, row 0 at the bottom (OpenGL and Blender alike) -> (H·W, C) float32 rows."""
    return np.ascontiguousarray(image, dtype=np.float32).reshape(-1, image.shape[-1])


#: Timer intervals (seconds) while a Rendered viewport refines, and while none does (short: a
#: change's first image waits for the timer).
BUSY_INTERVAL = 0.01
IDLE_INTERVAL = 0.02


def _tag_rendered_viewports() -> None:
    for window in getattr(bpy.context.window_manager, "windows", ()):
        for area in window.screen.areas:
            if area.type == "VIEW_3D" and area.spaces.active.shading.type == "RENDERED":
                area.tag_redraw()


def refine_timer() -> float:
    """bpy.app.timers callback: one step of one Rendered viewport (the next in turn: light passes
    and coarse image after a change, else a band of a sample), and a redraw when its image changed.
    Working here rather than in view_draw spares a redraw of the whole viewport per band."""
    from .overlay import describe_context_scene
    from .view_pipeline import COARSE, step_next

    samples = {id(p): p.samples for p in list(live_pipelines)}
    pipeline = step_next(live_pipelines, describe_context_scene)
    if pipeline is None:
        return IDLE_INTERVAL
    if pipeline.samples != samples.get(id(pipeline)) or pipeline.error or pipeline.statistics.get("level") == COARSE:
        _tag_rendered_viewports()
    return BUSY_INTERVAL


def free_view_pipelines() -> None:
    """Release the GPU resources of every Rendered viewport (unregister)."""
    for pipeline in list(live_pipelines):
        pipeline.free()


def _uninstall() -> None:
    from .view_gpu import free_shaders

    free_view_pipelines()
    free_shaders()


CLASSES = (VSGLRenderEngine,)
HOOKS = ((lambda: None, _uninstall),)
TIMERS = ((refine_timer, {"first_interval": IDLE_INTERVAL, "persistent": True}),)
