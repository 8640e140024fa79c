# SPDX-License-Identifier: GPL-3.0-or-later
"""Run inside the Blender 5.2 application with its window (tests/test_overlay_real_blender.py).

    real-blender gui demo.blend --python gui_overlay_script.py   (VSGL_SHOTS=<folder> in BLENDER_VSGL_SHOTS)

Drives the interface from a timer, as an artist would through the sidebar: shows the VSGL tab,
looks through the camera, switches the overlay on and changes its settings, waiting each time
until the overlay's refined image is drawn, and takes a screenshot of the whole screen with
ImageMagick's `import` (the same X server the tool's own screenshot uses). Writes result.json in
the folder: screenshots (file names in the folder), the 3D viewport's region, where sample points of
the walls and floor fall on the screen, and the measured update times. Touches
$REAL_BLENDER_SHOT_NOW when done.

No step waits a fixed time: each waits for a condition (the refined overlay, then two redraws of
the viewport, its sidebar and the properties editor after the change), so a slow, loaded machine
takes longer but takes the same screenshots. TIMEOUT only turns a hang into an error.
"""

import json
import os
import subprocess
import time
import traceback

import bpy
from bpy_extras.view3d_utils import location_3d_to_region_2d

OUT = os.environ["BLENDER_VSGL_SHOTS"]
MODULE = "bl_ext.user_default.vsgl"
# Points of demo.blend (world space): the white walls where the red floor's bounce falls, and a
# wall point far up where little of it does.
SAMPLES = {"back_wall_low": (-2.2, 2.99, 1.4), "left_wall_low": (-2.99, 0.6, 0.5),
           "back_wall_high": (-2.0, 2.99, 5.0)}
result = {"shots": {}, "timings": {}, "errors": [], "log": []}
# Full-resolution samples the overlay accumulates before a screenshot (a whole viewport's sample
# takes seconds on llvmpipe).
SAMPLES_PER_VIEW = 1


def log(text):
    result["log"].append(f"{time.perf_counter():.2f} {text}")


def overlay_module():
    import importlib

    return importlib.import_module(MODULE + ".vsgl_addon.overlay")


def viewport():
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                region = next(r for r in area.regions if r.type == "WINDOW")
                return window, area, region, area.spaces.active
    raise RuntimeError("no 3D viewport")


def screenshot(name):
    path = os.path.join(OUT, name + ".png")
    subprocess.run(["import", "-window", "root", path], check=True, timeout=120)
    result["shots"][name] = os.path.basename(path)
    log(f"shot {name}")


# Draws of the regions the screenshots show, counted by draw callbacks: a step's screenshot is
# taken once each has been drawn twice since the step's change (the first of those frames is then
# on the X server, whatever the machine's load).
draws = {"viewport": 0, "sidebar": 0, "properties": 0}


def _counter(name):
    def count():
        draws[name] += 1
    return count


_draw_handles = [(space, space.draw_handler_add(_counter(name), (), region, "POST_PIXEL"), region)
                 for name, space, region in (("viewport", bpy.types.SpaceView3D, "WINDOW"),
                                             ("sidebar", bpy.types.SpaceView3D, "UI"),
                                             ("properties", bpy.types.SpaceProperties, "WINDOW"))]
REDRAWS = 2


def redraw_everything():
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            area.tag_redraw()


def settings_module():
    import importlib

    return importlib.import_module(MODULE + ".vsgl_addon.settings")


def viewport_pipeline():
    _window, _area, _region, space = viewport()
    return overlay_module().views.pipelines.get(space.region_3d.as_pointer())


def lit_and_drawn():
    """The overlay's view pipeline of the viewport, once it has an image of the current settings'
    light passes (its coarse image after the change; its samples may be still to come); else None."""
    views = overlay_module().views
    if views.error:
        raise RuntimeError(views.error)
    pipeline = viewport_pipeline()
    if pipeline is None or pipeline.step_args is None or not pipeline.has_image:
        return None
    current = settings_module().VSGLSettings.from_properties(bpy.context.scene.vsgl)
    return pipeline if pipeline.lights_settings == current else None


def refined_and_drawn():
    """The overlay's view pipeline of the viewport has all its samples for the current view,
    scene state and settings."""
    pipeline = lit_and_drawn()
    return pipeline is not None and pipeline.pending(*pipeline.step_args) is None


def setup():
    window, area, region, space = viewport()
    space.shading.type = "SOLID"
    space.region_3d.view_perspective = "CAMERA"
    space.show_region_ui = True
    area.tag_redraw()


def vsgl_tab():
    """The sidebar's tab can be chosen once the sidebar has been drawn (before, it is read-only)."""
    window, area, region, space = viewport()
    ui = next(r for r in area.regions if r.type == "UI")
    ui.active_panel_category = "VSGL"
    area.tag_redraw()
    result["sidebar"] = {"category": ui.active_panel_category, "rect": [ui.x, ui.y, ui.width, ui.height]}
    # Through the camera by now (the view matrices are updated when the viewport has redrawn).
    points = {}
    for name, point in SAMPLES.items():
        xy = location_3d_to_region_2d(region, space.region_3d, point)
        # Screen coordinates, origin at the bottom left of the window (the screenshot's is at the top).
        points[name] = None if xy is None else [region.x + float(xy[0]), region.y + float(xy[1])]
    result["region"] = [region.x, region.y, region.width, region.height]
    result["window"] = [window.width, window.height]
    result["points"] = points


def overlay_on():
    bpy.context.scene.vsgl.overlay_mode = "INDIRECT"
    bpy.context.scene.vsgl.viewport_samples = SAMPLES_PER_VIEW
    bpy.context.scene.vsgl.show_overlay = True


def mode_added():
    bpy.context.scene.vsgl.overlay_mode = "ADDED"


def fewer_vsgls():
    bpy.context.scene.vsgl.overlay_mode = "INDIRECT"
    bpy.context.scene.vsgl.vsgl_count = 1


def restore_vsgls():
    bpy.context.scene.vsgl.overlay_mode = "ADDED"
    bpy.context.scene.vsgl.vsgl_count = 256


def orbit():
    """A view-only change: must not rerun the light passes."""
    result["scene_version_before_orbit"] = overlay_module().views.scene_version
    import math

    from mathutils import Quaternion

    _window, _area, _region, space = viewport()
    rv3d = space.region_3d
    rv3d.view_perspective = "PERSP"
    rv3d.view_location = (-0.5, 0.8, 1.2)
    rv3d.view_distance = 7.5
    rotation = bpy.context.scene.camera.matrix_world.to_quaternion()
    rv3d.view_rotation = Quaternion((0.0, 0.0, 1.0), math.radians(-20.0)) @ rotation


def after_orbit():
    result["scene_version_after_orbit"] = overlay_module().views.scene_version


def move_light():
    result["scene_version_before_move"] = overlay_module().views.scene_version
    bpy.data.objects["Spot"].location.x += 0.3


def after_move():
    result["scene_version_after_move"] = overlay_module().views.scene_version


def overlay_off():
    bpy.context.scene.vsgl.show_overlay = False


def resources_after_off():
    result["gpu_resources_after_off"] = overlay_module().views.gpu_resource_count()


def render_properties_and_preview():
    """VSGL as the render engine: its panels in Render Properties; the look-dev preview operator."""
    scene = bpy.context.scene
    scene.render.engine = "VSGL"
    window, area, region, space = viewport()
    properties = next(a for a in window.screen.areas if a.type == "PROPERTIES")
    properties.spaces.active.context = "RENDER"
    properties.tag_redraw()
    with bpy.context.temp_override(window=window, area=area, region=region):
        outcome = bpy.ops.vsgl.render_preview(percentage=25)
    result["preview"] = {"outcome": sorted(outcome),
                         "images": sorted(image.name for image in bpy.data.images if image.name.startswith("VSGL "))}
    result["properties_rect"] = [properties.x, properties.y, properties.width, properties.height]


# (action, wait: False, True (the refined overlay) or "lit" (lit_and_drawn), screenshot name or None,
# timing label or None)
STEPS = [
    (setup, False, None, None),
    (vsgl_tab, False, None, None),
    (None, False, "01_sidebar_overlay_off", None),
    (overlay_on, True, "02_overlay_on_indirect_only", "first"),
    (mode_added, True, "03_overlay_added_to_solid", None),
    (fewer_vsgls, True, "04_vsgl_count_1", "parameter_change"),
    (restore_vsgls, "lit", None, None),
    (orbit, True, "05_after_orbit_view_only", "view_change"),
    (after_orbit, False, None, None),
    (move_light, True, "06_after_moving_the_spot", "scene_change"),
    (after_move, False, None, None),
    (overlay_off, False, "07_overlay_switched_off", None),
    (resources_after_off, False, None, None),
    (render_properties_and_preview, False, "08_render_properties", None),
]
state = {"step": 0, "phase": "start", "since": time.perf_counter(), "first_update": 0, "draws": {}}
# A hang guard per wait, not a speed requirement (a refined overlay takes about 3 s here).
TIMEOUT = 120.0
POLL = 0.05


def finish():
    for space, handle, region in _draw_handles:
        space.draw_handler_remove(handle, region)
    with open(os.path.join(OUT, "result.json"), "w") as f:
        json.dump(result, f, indent=1, default=str)
    open(os.environ["REAL_BLENDER_SHOT_NOW"], "w").close()


def _check_timeout(what):
    if time.perf_counter() - state["since"] > TIMEOUT:
        raise RuntimeError(f"{what} not after {TIMEOUT} s at step {state['step']}: draws {draws}")


def start_redraw():
    """Every draw from now on (after this timer call returns) shows the step's change so far."""
    state.update(phase="redraw", since=time.perf_counter(), draws=dict(draws))
    redraw_everything()


def tick():
    try:
        if state["step"] >= len(STEPS):
            finish()
            return None
        action, wait, shot, label = STEPS[state["step"]]
        if state["phase"] == "start":  # the window is up and its viewport draws
            if draws["viewport"] < REDRAWS:
                _check_timeout("no viewport drawn")
                return POLL
            state["phase"] = "act"
        pipeline = viewport_pipeline()
        if state["phase"] == "act":
            state.update(first_update=pipeline.steps if pipeline is not None else 0)
            if action is not None:
                action()
                log(f"did {action.__name__}")
            start_redraw()
            if wait:
                state.update(phase="refine", wait=wait)
            return POLL
        if state["phase"] == "refine":
            # The overlay learns the viewport's new view when the viewport draws: before that, the
            # cache can still call the old view refined.
            ready = (lambda: lit_and_drawn() is not None) if state["wait"] == "lit" else refined_and_drawn
            if draws["viewport"] == state["draws"]["viewport"] or not ready():
                _check_timeout("no refined overlay")
                return POLL
            if label:
                result["timings"][label] = {
                    "updates": [{key: value for key, value in entry.items() if key != "traceback"}
                                for entry in viewport_pipeline().history if entry["index"] >= state["first_update"]],
                    "until_refined_seconds": time.perf_counter() - state["since"]}
            start_redraw()
            return POLL
        if state["phase"] == "redraw":
            behind = [name for name, count in draws.items() if count - state["draws"][name] < REDRAWS]
            if behind:
                _check_timeout(f"{behind} not redrawn")
                redraw_everything()
                return POLL
            state["phase"] = "shoot"
        if shot:
            screenshot(shot)
        state.update(step=state["step"] + 1, phase="act")
        return POLL
    except Exception:
        result["errors"].append(traceback.format_exc())
        finish()
        return None


bpy.app.timers.register(tick, first_interval=POLL)
