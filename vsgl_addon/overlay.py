# SPDX-License-Identifier: GPL-3.0-or-later
"""The live viewport overlay of the VSGL light over another engine's viewport (EEVEE, Workbench,
Cycles): the Blender glue of the view pipeline that Rendered shading uses (view_pipeline.py), so the
overlay's images are the same GPU-resident, progressive ones, with no copy of its own.

Three parts, each doing one kind of work:

* the **draw callback** (``SpaceView3D.draw_handler_add``, every 3D viewport, POST_PIXEL) only
  records the viewport's view and projection and draws its pipeline's accumulated images with the
  display shader (glsl/view/display.frag.glsl, compiled beforehand): no pass, no upload, no compilation;
* the **depsgraph handler** (``depsgraph_update_post``, ``frame_change_post``) only marks the scene
  dirty when something that changes the light changed (an object moved, a mesh, light, material,
  world or image changed); selection and overlay display settings do not, and a VSGL parameter
  change is caught by the pipelines (their settings are compared);
* the **timer** hands the scene's settings to the pipelines and does one step of one of them
  (light passes and a coarse image after a change, else a band of a full-resolution sample).

One :class:`~vsgl_addon.view_pipeline.ViewportSet` per process holds all state and GPU resources.
It is freed when the overlay is switched off, a file is loaded (``load_pre``) or the add-on is
unregistered; a closed viewport's pipeline is freed by the timer.
"""

from __future__ import annotations

import numpy as np

from .settings import OVERLAY_DISPLAYS, VSGLSettings
from .view_pipeline import COARSE, OverlayLook, ViewportSet

#: Timer intervals (seconds): work pending, idle with the overlay on, overlay off.
BUSY_INTERVAL = 0.02
IDLE_INTERVAL = 0.1
OFF_INTERVAL = 0.5

views = ViewportSet()
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


def _display(settings):
    """The OVERLAY_DISPLAYS option scene.vsgl.overlay_mode names (None for a value Blender does not know)."""
    return next((choice for choice in OVERLAY_DISPLAYS if choice.identifier == settings.overlay_mode), None)


def view_pass_and_look(display_name: str, scale: float, gamma: float) -> tuple[str, OverlayLook]:
    """The view pipeline's pass (settings.VIEWPORT_PASSES name) and how it is laid over the
    viewport, for OVERLAY_DISPLAYS option `display_name`: "added" is the indirect light added onto
    the viewport; every other option is the Rendered mode's pass of the same name, over it."""
    added = display_name == "added"
    # The viewport's framebuffer encodes linear values to sRGB itself (checked in Blender 5.2).
    return ("indirect" if added else display_name or "indirect"), OverlayLook(scale, gamma, added, False)


def draw_callback() -> None:
    """SpaceView3D POST_PIXEL callback: record this viewport's view, draw its pipeline's images."""
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
    if space is not None and space.shading.type == "RENDERED" and context.engine == "VSGL":
        return  # Rendered shading of our engine already shows this light
    key = rv3d.as_pointer()
    views.request_view(key, _matrix(rv3d.view_matrix), _matrix(rv3d.window_matrix), (region.width, region.height))
    display = _display(settings)
    view_pass, look = view_pass_and_look(display.name if display else "", *_view_transform(scene))
    views.draw(key, view_pass, look)
    _draw_label(key, settings)


def _draw_label(key: int, settings) -> None:
    """One line at the viewport's bottom left: what the overlay shows and how far it refined."""
    import blf

    display = _display(settings)
    mode = display.label if display else ""
    pipeline = views.pipelines.get(key)
    if views.error:
        state = "stopped: see the VSGL tab"
    elif pipeline is None or not pipeline.has_image:
        state = "computing…"
    else:
        state = pipeline.status_text(int(settings.viewport_samples)).removeprefix("VSGL ")
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
        views.mark_scene_dirty()
    else:
        views.free()
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
        views.mark_scene_dirty()
    # A VSGL parameter change is caught by the pipelines (settings compared); an overlay display
    # change needs only a redraw, which Blender does for a property change anyway.


@_persistent
def on_frame_change(scene, depsgraph=None) -> None:
    settings = getattr(scene, "vsgl", None)
    if settings is not None and settings.show_overlay:
        views.mark_scene_dirty()


@_persistent
def on_load_pre(*_args) -> None:
    """Another file is loading: nothing of this one's may stay on the GPU."""
    views.free()


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
    """bpy.app.timers callback: one step of one viewport's overlay, then the delay until the next call."""
    import bpy

    scene = getattr(bpy.context, "scene", None)
    settings = getattr(scene, "vsgl", None) if scene is not None else None
    if settings is None or not settings.show_overlay:
        if views.gpu_resource_count() or views.pipelines:
            views.free()
        return OFF_INTERVAL
    try:
        pass_settings = VSGLSettings.from_properties(settings)
    except ValueError as error:
        views.settings_error = str(error)
        return OFF_INTERVAL
    views.settings_error = None
    if not bpy.app.background:
        views.retain(_open_viewport_keys())
    views.set_step_args(pass_settings, float(settings.overlay_resolution_scale), int(settings.viewport_samples))
    samples = {id(p): p.samples for p in views.pipelines.values()}
    stepped = views.step(describe_context_scene)
    if stepped is not None and (stepped.error or stepped.statistics.get("level") == COARSE
                                or stepped.samples != samples.get(id(stepped))):
        _tag_redraw()
    return BUSY_INTERVAL if stepped is not None or views.busy() else IDLE_INTERVAL


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
    views.free()
    _tag_redraw()


def is_installed() -> bool:
    return _draw_handle is not None


HANDLERS = (("depsgraph_update_post", on_depsgraph_update), ("frame_change_post", on_frame_change),
            ("load_pre", on_load_pre))
TIMERS = ((timer, {"first_interval": OFF_INTERVAL, "persistent": True}),)
HOOKS = ((install, uninstall),)
