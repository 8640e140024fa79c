# SPDX-License-Identifier: GPL-3.0-or-later
"""The `VSGL` render engine: F12 and `blender -b scene.blend -E VSGL -f 1` (Blender-facing only).

It turns the evaluated depsgraph into the plain scene description, hands it to the frame renderer
(renderer.py: the GPU passes) and writes what comes back into Blender's render result: Combined
(direct + one-bounce indirect, alpha = coverage) and the passes Direct, Indirect, Indirect Diffuse,
Indirect Specular and Indirect Glossy Reflectors (the part of Indirect Specular MRP-ASG renders),
all linear and scene-referred in Blender's units, so the compositor,
multilayer EXR and Blender's colour management treat them like Cycles' passes.
"""

from __future__ import annotations

import time

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
}

#: Timings and counts of the last frame rendered in this process (read by the render command's
#: report and the statistics panel). Render engine instances are short-lived, so they cannot hold it.
last_frame_statistics: dict = {}


class VSGLRenderEngine(bpy.types.RenderEngine):
    bl_idname = ENGINE_ID
    bl_label = "VSGL"
    bl_use_gpu_context = True
    bl_use_postprocess = True
    bl_use_preview = False

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
            resolution=[width, height], warnings=list(description.warnings))


def _rows(image: np.ndarray) -> np.ndarray:
    """(H, W, C) image, row 0 at the bottom (OpenGL and Blender alike) -> (H·W, C) float32 rows."""
    return np.ascontiguousarray(image, dtype=np.float32).reshape(-1, image.shape[-1])


CLASSES = (VSGLRenderEngine,)
