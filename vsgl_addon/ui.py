# SPDX-License-Identifier: GPL-3.0-or-later
"""Panels (Blender-facing only): a ``VSGL`` tab in the 3D viewport's sidebar, and the same settings
in Render Properties when VSGL is the render engine.

Both places draw the same sections with the same functions:

* **Light Passes**: the parameters of the passes, grouped by pass in PASS_SECTIONS. A new pass
  (e.g. VSGL visibility, the VPLs' δ, MRP-ASG's disk radius) adds its row there: a
  (heading, property names) entry, nothing else changes;
* **Viewport Overlay**: on/off, display mode, resolution, intensity, and the state of its updates;
* **Look-Dev**: the preview and render-to-file operators;
* **Statistics**: per-pass times and counts of the last overlay update and of the last render;
* warnings (materials approximated, lights skipped, a failed update) at the top, where they are seen.
"""

from __future__ import annotations

import bpy

from . import engine, overlay, passes
from .proxies import describe_proxies, describe_row
from .settings import KERNELS, QUALITY_MODES

#: (heading, scene.vsgl property names), in pipeline order. Append an entry for a new pass's controls.
PASS_SECTIONS = (
    ("Quality", ("quality_mode", "time_budget_ms")),
    ("Reflective Shadow Maps", ("rsm_size",)),
    ("VSGL Generation", ("kernel", "vsgl_count", "k", "pdf", "positional_distribution", "seed")),
    ("VSGL Visibility", ("visibility", "ism_size", "ism_points")),
    ("Glossy Reflectors (MRP-ASG)", ("glossy_reflectors", "disk_radius", "caustic_roughness", "reflector_mode")),
    ("Caustics (VPL)", ("caustics", "delta_log10", "vpl_interleave", "vpl_filter_radius", "vpl_samples",
                        "vpl_visibility")),
)
OVERLAY_PROPERTIES = ("overlay_mode", "overlay_resolution_scale", "overlay_intensity")
#: Statistics labels come from the passes' declarations (vsgl_addon.passes.STEPS), so a new pass
#: brings its own.
TIMING_LABELS = passes.TIMING_LABELS
#: The overlay's step times (ViewPipeline statistics), beside the passes' own.
OVERLAY_TIMING_LABELS = {"overlay_step": "Last step", "overlay_light_passes": "Light passes",
                         "overlay_view": "View passes (coarse image)"}
COUNT_LABELS = passes.COUNT_LABELS


def warnings() -> list[str]:
    """Every warning the panels show: overlay failure, extraction warnings, last render's."""
    lines = []
    if overlay.views.error:
        lines.append(f"Overlay stopped: {overlay.views.error}")
    lines.extend(overlay.views.warnings)
    for line in engine.last_frame_statistics.get("warnings", ()):
        if line not in lines:
            lines.append(line)
    return lines


def draw_warnings(layout) -> None:
    lines = warnings()
    if not lines:
        return
    box = layout.box()
    for line in lines:
        box.label(text=line, icon="ERROR")


def draw_pass_settings(layout, settings) -> None:
    layout.use_property_split = True
    layout.use_property_decorate = False
    for heading, names in PASS_SECTIONS:
        column = layout.column(heading=heading, align=True)
        for name in names:
            row = column.row()
            row.prop(settings, name)
            if name in KERNELS.identified(settings.kernel).ignores:
                row.enabled = False  # e.g. the two-VSGL mode has no N, K or lobe positions (003)
            # Budget mode chooses N, the RSM side, δ and the interleave; Manual has no target.
            if name in QUALITY_MODES.identified(settings.quality_mode).ignores or (
                    name == "time_budget_ms" and settings.quality_mode != "BUDGET"):
                row.enabled = False


def draw_overlay_settings(layout, settings) -> None:
    layout.use_property_split = True
    layout.use_property_decorate = False
    column = layout.column()
    column.active = settings.show_overlay
    for name in OVERLAY_PROPERTIES:
        column.prop(settings, name)
    column.prop(settings, "viewport_samples")
    last = overlay.views.last
    # The proxies' debug outlines work with the overlay off too.
    layout.prop(settings, "show_proxy_outlines")
    if settings.show_overlay:
        if overlay.views.error:
            column.label(text="Stopped (see warnings)", icon="ERROR")
        elif last is not None and last.has_image:
            column.label(text=last.status_text(int(settings.viewport_samples)).removeprefix("VSGL "), icon="TIME")
        else:
            column.label(text="Updating…", icon="TIME")


def _draw_statistics_block(layout, title: str, statistics: dict) -> None:
    box = layout.box()
    box.label(text=title)
    timings = statistics.get("timings", {})
    if not timings:
        box.label(text="None yet")
        return
    column = box.column(align=True)
    for key, seconds in timings.items():
        row = column.split(factor=0.62)
        row.label(text=TIMING_LABELS.get(key) or OVERLAY_TIMING_LABELS.get(key, key))
        row.label(text=f"{seconds * 1000:.1f} ms")
    counts = statistics.get("counts", {})
    if counts:
        column.separator()
        for key, value in counts.items():
            if value is None:  # renderer.ViewCounts: a VPL count whose light passes went unread
                continue
            row = column.split(factor=0.62)
            row.label(text=COUNT_LABELS.get(key, key))
            row.label(text=f"{value:.1f}" if isinstance(value, float) else f"{value}")
    proxies = statistics.get("proxies", ())
    if proxies:
        column.separator()
        column.label(text="Rectangle proxies (MRP-ASG):")
        for row in proxies:
            column.label(text=describe_row(row), icon="MESH_PLANE")


def overlay_statistics() -> dict:
    """The overlay's last step as a statistics block: its time per stage, its counts and the
    rectangle proxies its light passes keep."""
    state = overlay.views.statistics
    if not state:
        return {}
    timings = {"overlay_step": state.get("seconds", 0.0)}
    if state.get("light_seconds") is not None:
        timings["overlay_light_passes"] = state["light_seconds"]
    if state.get("view_seconds") is not None:
        timings["overlay_view"] = state["view_seconds"]
    lights = overlay.views.last.lights if overlay.views.last is not None else None
    proxies = describe_proxies(lights.proxies, lights.scene) if lights is not None else []
    return {"timings": timings, "counts": dict(state.get("counts", {})), "proxies": proxies}


def _draw_plan(layout, plan: dict) -> None:
    """The frame plan (planner.py): one line per decision, then one per light."""
    lines = plan.get("summary", ())
    if not lines:
        return
    box = layout.box()
    box.label(text="Frame plan")
    column = box.column(align=True)
    for line in lines:
        column.label(text=line)


def draw_statistics(layout) -> None:
    state = overlay.views.statistics
    if state:
        level = state.get("level", state.get("work", ""))
        last = overlay.views.last
        plan = getattr(last.lights, "plan", None) if last is not None and last.lights is not None else None
        _draw_plan(layout, plan.to_dict() if plan is not None else {})
        size = state.get("size")
        what = f"{level} {size[0]}×{size[1]}" if size else f"{level}, sample {state.get('samples', 0)}"
        _draw_statistics_block(layout, f"Overlay: last step ({what})", overlay_statistics())
    render = engine.last_frame_statistics
    if render:
        width, height = render.get("resolution", (0, 0))
        _draw_statistics_block(layout, f"Last render {width}×{height}", render)
        _draw_plan(layout, render.get("plan", {}))
    if not state and not render:
        layout.label(text="Turn on the overlay or render to see timings")


def draw_lookdev(layout, context) -> None:
    column = layout.column(align=True)
    column.operator("vsgl.render_preview", icon="IMAGE_DATA")
    column.operator("vsgl.render_to_file", icon="FILE_IMAGE")
    if context.scene.camera is None:
        column.label(text="Needs an active camera", icon="INFO")


# --- the 3D viewport's sidebar (N panel), tab "VSGL" ------------------------------------------

class _SidebarPanel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "VSGL"

    @classmethod
    def poll(cls, context):
        return getattr(context.scene, "vsgl", None) is not None


class VIEW3D_PT_vsgl(_SidebarPanel, bpy.types.Panel):
    bl_label = "VSGL Indirect Light"

    def draw(self, context):
        layout = self.layout
        shown = context.scene.vsgl.show_overlay
        layout.prop(context.scene.vsgl, "show_overlay", toggle=True,
                    text="Hide Indirect Light Overlay" if shown else "Show Indirect Light Overlay",
                    icon="HIDE_OFF" if shown else "HIDE_ON")
        draw_warnings(layout)


class VIEW3D_PT_vsgl_overlay(_SidebarPanel, bpy.types.Panel):
    bl_label = "Viewport Overlay"
    bl_parent_id = "VIEW3D_PT_vsgl"

    def draw(self, context):
        draw_overlay_settings(self.layout, context.scene.vsgl)


class VIEW3D_PT_vsgl_passes(_SidebarPanel, bpy.types.Panel):
    bl_label = "Light Passes"
    bl_parent_id = "VIEW3D_PT_vsgl"

    def draw(self, context):
        draw_pass_settings(self.layout, context.scene.vsgl)


class VIEW3D_PT_vsgl_lookdev(_SidebarPanel, bpy.types.Panel):
    bl_label = "Look-Dev"
    bl_parent_id = "VIEW3D_PT_vsgl"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        draw_lookdev(self.layout, context)


class VIEW3D_PT_vsgl_statistics(_SidebarPanel, bpy.types.Panel):
    bl_label = "Statistics"
    bl_parent_id = "VIEW3D_PT_vsgl"

    def draw(self, context):
        draw_statistics(self.layout)


# --- Render Properties, when VSGL is the render engine ----------------------------------------

class _RenderPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {engine.ENGINE_ID}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES and getattr(context.scene, "vsgl", None) is not None


class RENDER_PT_vsgl(_RenderPanel, bpy.types.Panel):
    bl_label = "VSGL Indirect Light"

    def draw(self, context):
        draw_warnings(self.layout)
        draw_pass_settings(self.layout, context.scene.vsgl)


class RENDER_PT_vsgl_overlay(_RenderPanel, bpy.types.Panel):
    bl_label = "Viewport Overlay"
    bl_parent_id = "RENDER_PT_vsgl"

    def draw_header(self, context):
        self.layout.prop(context.scene.vsgl, "show_overlay", text="")

    def draw(self, context):
        draw_overlay_settings(self.layout, context.scene.vsgl)


class RENDER_PT_vsgl_viewport(_RenderPanel, bpy.types.Panel):
    bl_label = "Rendered Viewport"
    bl_parent_id = "RENDER_PT_vsgl"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        settings = context.scene.vsgl
        for name in ("viewport_pass", "viewport_resolution_scale", "viewport_samples"):
            layout.prop(settings, name)


class RENDER_PT_vsgl_lookdev(_RenderPanel, bpy.types.Panel):
    bl_label = "Look-Dev"
    bl_parent_id = "RENDER_PT_vsgl"

    def draw(self, context):
        draw_lookdev(self.layout, context)


class RENDER_PT_vsgl_statistics(_RenderPanel, bpy.types.Panel):
    bl_label = "Statistics"
    bl_parent_id = "RENDER_PT_vsgl"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        draw_statistics(self.layout)


class OBJECT_PT_vsgl_proxy(bpy.types.Panel):
    """Object Properties: whether the object's planar regions become rectangle proxies (MRP-ASG)."""

    bl_label = "VSGL Glossy Reflector"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        obj = getattr(context, "object", None)
        return obj is not None and obj.type == "MESH" and hasattr(obj, "vsgl_proxy")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(context.object, "vsgl_proxy")


def draw_viewport_pass(self, context):
    """Appended to the 3D viewport's Shading popover: the pass Rendered shading shows, where
    Cycles and EEVEE put theirs."""
    shading = getattr(context.space_data, "shading", None)
    settings = getattr(context.scene, "vsgl", None)
    if shading is None or settings is None or context.engine != engine.ENGINE_ID or shading.type != "RENDERED":
        return
    self.layout.prop(settings, "viewport_pass", text="Render Pass")


def _install_viewport_pass() -> None:
    bpy.types.VIEW3D_PT_shading.append(draw_viewport_pass)


def _uninstall_viewport_pass() -> None:
    try:
        bpy.types.VIEW3D_PT_shading.remove(draw_viewport_pass)
    except (ValueError, RuntimeError):
        pass


HOOKS = ((_install_viewport_pass, _uninstall_viewport_pass),)

# Parents before children (register order); unregister goes in reverse.
CLASSES = (
    VIEW3D_PT_vsgl, VIEW3D_PT_vsgl_overlay, VIEW3D_PT_vsgl_passes, VIEW3D_PT_vsgl_lookdev,
    VIEW3D_PT_vsgl_statistics,
    RENDER_PT_vsgl, RENDER_PT_vsgl_overlay, RENDER_PT_vsgl_viewport, RENDER_PT_vsgl_lookdev, RENDER_PT_vsgl_statistics,
    OBJECT_PT_vsgl_proxy,
)
