# SPDX-License-Identifier: GPL-3.0-or-later
"""Look-dev operators (Blender-facing only; the frame comes from renderer.py).

* ``vsgl.render_preview``: the active camera's view at preview resolution into an Image datablock
  named for its settings (e.g. ``VSGL N256 K1 Modified RSM128 Combined``), so renders with other
  settings sit side by side and can be flipped through (A/B) in an Image Editor. Rendering the same
  settings again replaces that image's pixels.
* ``vsgl.render_to_file``: the active camera's view at the render resolution into a file the user
  picks (OpenEXR, linear; or PNG, sRGB-encoded), with a progress bar and a report.

Neither changes the scene: the preview image is the operator's own product, the file operator
removes its temporary image datablock.
"""

from __future__ import annotations

import os
import time

import bpy
import numpy as np
from bpy.props import EnumProperty, IntProperty, StringProperty

from .engine import render_size
from .settings import KERNELS, LOOKDEV_PASSES, VSGLSettings

# The operators' "Pass" choice (settings.LOOKDEV_PASSES); an operator property, not stored in scenes.
PREVIEW_PASSES = tuple((choice.identifier, choice.label, choice.description) for choice in LOOKDEV_PASSES)


def settings_image_name(settings: VSGLSettings, pass_name: str = "COMBINED") -> str:
    """The image name of a preview: its parameters, so that A/B images are told apart."""
    return (f"VSGL N{settings.vsgl_count} K{settings.k:g} {KERNELS.named(settings.kernel).tag} "
            f"RSM{settings.rsm_size} Seed{settings.seed} {LOOKDEV_PASSES.identified(pass_name).label}")


def _ensure_gpu() -> None:
    if bpy.app.background:
        from .gpu_context import ensure_gpu_context

        ensure_gpu_context()


def render_camera(scene, depsgraph, width: int, height: int):
    """(FrameImages, VSGLSettings, warnings) of the scene's active camera at width × height."""
    from .renderer import FrameRenderer
    from .scene import extract_scene

    _ensure_gpu()
    settings = VSGLSettings.from_properties(scene.vsgl)
    description = extract_scene(depsgraph)
    if description.camera is None:
        raise ValueError("the scene has no active camera")
    renderer = FrameRenderer()
    try:
        images = renderer.render(description, settings, width, height)
    finally:
        renderer.free()
    return images, settings, list(description.warnings)


def _rgba(images, pass_name: str) -> np.ndarray:
    rgb = getattr(images, LOOKDEV_PASSES.identified(pass_name).name)
    return np.concatenate([rgb, images.coverage[..., None]], axis=-1).astype(np.float32)


def _fill_image(image, rgba: np.ndarray) -> None:
    image.pixels.foreach_set(np.ascontiguousarray(rgba, np.float32).reshape(-1))
    image.update()


class VSGL_OT_render_preview(bpy.types.Operator):
    """Render the active camera with VSGL at preview resolution into an image named for its settings (for A/B in an Image Editor)"""

    bl_idname = "vsgl.render_preview"
    bl_label = "Render Preview"
    bl_options = {"REGISTER"}

    percentage: IntProperty(
        name="Resolution %", description="Preview size as a percentage of the render resolution "
        "(time grows with the square)", default=25, min=1, max=100, subtype="PERCENTAGE")
    pass_name: EnumProperty(name="Pass", items=PREVIEW_PASSES, default="COMBINED",
                            description="Which light the preview image holds")

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.camera is not None

    def execute(self, context):
        scene = context.scene
        width, height = render_size(scene.render)
        width = max(1, width * self.percentage // 100)
        height = max(1, height * self.percentage // 100)
        started = time.perf_counter()
        try:
            images, settings, warnings = render_camera(scene, context.evaluated_depsgraph_get(), width, height)
        except Exception as error:  # noqa: BLE001 - reported to the user
            self.report({"ERROR"}, f"VSGL preview failed: {error}")
            return {"CANCELLED"}
        name = settings_image_name(settings, self.pass_name)
        image = bpy.data.images.get(name)
        if image is not None and tuple(image.size) != (width, height):
            image.scale(width, height)
        if image is None:
            image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
        _fill_image(image, _rgba(images, self.pass_name))
        for area in getattr(context.screen, "areas", ()):
            if area.type == "IMAGE_EDITOR":
                area.tag_redraw()
        for line in warnings:
            self.report({"WARNING"}, line)
        self.report({"INFO"}, f"VSGL preview '{name}' ({width}×{height}) in {time.perf_counter() - started:.2f} s")
        return {"FINISHED"}


class VSGL_OT_render_to_file(bpy.types.Operator):
    """Render the active camera with VSGL at the render resolution into a file (OpenEXR linear, or PNG)"""

    bl_idname = "vsgl.render_to_file"
    bl_label = "Render to File"
    bl_options = {"REGISTER"}

    filepath: StringProperty(name="File", subtype="FILE_PATH", default="//vsgl_render.exr")
    file_format: EnumProperty(
        name="Format", default="OPEN_EXR",
        items=(("OPEN_EXR", "OpenEXR", "32-bit float, linear scene-referred radiance (for compositing)"),
               ("PNG", "PNG", "8-bit, sRGB-encoded (for a quick look; bright light clips)")))
    pass_name: EnumProperty(name="Pass", items=PREVIEW_PASSES, default="COMBINED",
                            description="Which light the file holds")
    percentage: IntProperty(name="Resolution %", default=100, min=1, max=100, subtype="PERCENTAGE",
                            description="Percentage of the render resolution")
    filter_glob: StringProperty(default="*.exr;*.png", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.camera is not None

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        scene = context.scene
        path = bpy.path.abspath(self.filepath)
        extension = ".exr" if self.file_format == "OPEN_EXR" else ".png"
        if not path.lower().endswith(extension):
            path = os.path.splitext(path)[0] + extension
        width, height = render_size(scene.render)
        width = max(1, width * self.percentage // 100)
        height = max(1, height * self.percentage // 100)
        wm = context.window_manager
        wm.progress_begin(0, 3)
        started = time.perf_counter()
        image = None
        try:
            wm.progress_update(1)
            images, settings, warnings = render_camera(scene, context.evaluated_depsgraph_get(), width, height)
            wm.progress_update(2)
            directory = os.path.dirname(path)
            if directory:
                os.makedirs(directory, exist_ok=True)
            image = bpy.data.images.new("VSGL render to file", width, height, alpha=True, float_buffer=True)
            _fill_image(image, _rgba(images, self.pass_name))
            image.filepath_raw = path
            image.file_format = self.file_format
            image.save()
            wm.progress_update(3)
        except Exception as error:  # noqa: BLE001 - reported to the user
            self.report({"ERROR"}, f"VSGL render to {path} failed: {error}")
            return {"CANCELLED"}
        finally:
            if image is not None:
                bpy.data.images.remove(image)
            wm.progress_end()
        for line in warnings:
            self.report({"WARNING"}, line)
        self.report({"INFO"}, f"VSGL: wrote {path} ({width}×{height}, {settings_image_name(settings, self.pass_name)}) "
                              f"in {time.perf_counter() - started:.2f} s")
        return {"FINISHED"}


CLASSES = (VSGL_OT_render_preview, VSGL_OT_render_to_file)
