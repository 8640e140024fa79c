# SPDX-License-Identifier: GPL-3.0-or-later
"""Run inside the Blender 5.2 application with its window (tests/test_rendered_real_blender.py).

    real-blender gui demo.blend --python gui_rendered_script.py   (BLENDER_VSGL_SHOTS=<folder>)

Drives Rendered shading with VSGL as the render engine, as an artist would: through the camera,
F12 of the same view, a moved light, Solid -> Rendered -> Solid under a GPU resource tracker, two
viewports, and the add-on disabled and enabled again with a Rendered viewport open. Each step waits
for a condition (the viewports' progressive images converged, then two redraws), never a fixed time.
Writes result.json (screenshots, the camera frame on screen, the viewport steps' statistics,
resource counts) in the folder and touches $REAL_BLENDER_SHOT_NOW when done.
"""

import gc
import importlib
import json
import os
import subprocess
import sys
import time
import traceback

import bpy
from bpy_extras.view3d_utils import location_3d_to_region_2d

OUT = os.environ["BLENDER_VSGL_SHOTS"]
MODULE = "bl_ext.user_default.vsgl"
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # tests/: the GPU resource tracker
# Samples a viewport accumulates before a screenshot: each full-resolution sample of the 1600 x 900
# window's viewport takes about 20 s on llvmpipe; two show the accumulation and keep the session short.
SAMPLES = 2
result = {"shots": {}, "errors": [], "log": [], "steps": {}, "samples": SAMPLES}


def log(text):
    result["log"].append(f"{time.perf_counter():.2f} {text}")


def engine_module():
    return importlib.import_module(MODULE + ".vsgl_addon.engine")


def pipelines():
    return list(engine_module().live_pipelines)


def viewports():
    found = []
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                region = next(r for r in area.regions if r.type == "WINDOW")
                found.append((window, area, region, area.spaces.active))
    found.sort(key=lambda v: v[2].x)
    return found


def viewport():
    return viewports()[0]


def screenshot(name):
    path = os.path.join(OUT, name + ".png")
    subprocess.run(["import", "-window", "root", path], check=True, timeout=120)
    result["shots"][name] = os.path.basename(path)
    log(f"shot {name}")


draws = {"viewport": 0}
_handle = bpy.types.SpaceView3D.draw_handler_add(lambda: draws.__setitem__("viewport", draws["viewport"] + 1),
                                                 (), "WINDOW", "POST_PIXEL")


def redraw_everything():
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            area.tag_redraw()


def converged(count=1):
    """`count` Rendered viewports, each with its converged progressive image."""
    live = pipelines()
    for pipeline in live:
        if pipeline.error:
            raise RuntimeError(pipeline.error)
    samples = bpy.context.scene.vsgl.viewport_samples
    return len(live) >= count and sum(p.converged(samples) for p in live) >= count


def set_shading(kind, which=None):
    for _window, area, _region, space in (viewports() if which is None else [viewports()[which]]):
        space.shading.type = kind
        area.tag_redraw()


def camera_frame(region, rv3d):
    """The camera frame's corners on screen (window pixels, origin bottom left)."""
    scene = bpy.context.scene
    camera = scene.camera
    corners = [camera.matrix_world @ v for v in camera.data.view_frame(scene=scene)]
    xy = [location_3d_to_region_2d(region, rv3d, c) for c in corners]
    return [[region.x + float(p[0]), region.y + float(p[1])] for p in xy]


def setup():
    scene = bpy.context.scene
    scene.render.engine = "VSGL"
    scene.vsgl.viewport_samples = SAMPLES
    scene.vsgl.viewport_resolution_scale = 0.25
    # The viewport's mechanics, not the caustics: the demo's VPL pass (thousands of glossy VPLs)
    # would triple each full-resolution sample on llvmpipe; F12 below renders with the same setting,
    # and the pass reaches the viewport through the same renderer (tests/test_view_pipeline_gpu.py).
    scene.vsgl.caustics = False
    for obj in scene.objects:  # no selection outline over the comparison with F12
        obj.select_set(False)
    _window, area, _region, space = viewport()
    space.region_3d.view_perspective = "CAMERA"
    space.shading.type = "RENDERED"
    area.tag_redraw()


def record(label):
    def action():
        live = pipelines()
        result["steps"][label] = [[dict(entry) for entry in p.history] for p in live]
        _window, _area, region, space = viewport()
        result["region"] = [region.x, region.y, region.width, region.height]
        result[label + "_status"] = [p.status_text(bpy.context.scene.vsgl.viewport_samples) for p in live]
    action.__name__ = f"record_{label}"
    return action


def frame_and_f12():
    scene = bpy.context.scene
    _window, _area, region, space = viewport()
    result["camera_frame"] = camera_frame(region, space.region_3d)
    bpy.ops.render.render()
    path = os.path.join(OUT, "f12.png")
    bpy.data.images["Render Result"].save_render(path)
    result["f12"] = os.path.basename(path)
    result["f12_size"] = [scene.render.resolution_x, scene.render.resolution_y]


def move_light():
    live = pipelines()
    result["steps_before_move"] = live[0].steps
    result["lights_before_move"] = live[0].scene_version
    bpy.data.objects["Spot"].location.x += 0.6
    bpy.data.objects["Spot"].location.y -= 0.4


def after_move():
    pipeline = pipelines()[0]
    first = next(e for e in pipeline.history if e["index"] >= result["steps_before_move"])
    result["first_step_after_move"] = dict(first)
    result["lights_after_move"] = pipeline.scene_version


tracker_box = {}


def start_tracker():
    from scene_generator import GPUResourceTracker

    set_shading("SOLID")
    gc.collect()
    result["pipelines_in_solid_before"] = len(pipelines())
    tracker = GPUResourceTracker()
    tracker.__enter__()
    tracker_box["tracker"] = tracker


def stop_tracker():
    tracker = tracker_box.pop("tracker")
    tracker.__exit__(None, None, None)
    gc.collect()
    result["pipelines_in_solid_after"] = len(pipelines())
    result["gpu_objects_left"] = tracker.alive()
    result["gpu_objects_made"] = tracker_box.get("made", None)


def count_made():
    tracker_box["made"] = len(tracker_box["tracker"].made)


def split():
    bpy.context.scene.vsgl.viewport_samples = 2  # two viewports of ~600 x 700 pixels each on llvmpipe
    window, area, region, _space = viewport()
    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.screen.area_split(direction="VERTICAL", factor=0.5)
    # The second viewport looks at the scene from its own, perspective view.
    second = viewports()[1][3].region_3d
    second.view_perspective = "PERSP"
    second.view_distance = 9.0
    set_shading("RENDERED")


def disable():
    bpy.ops.preferences.addon_disable(module=MODULE)
    result["engine_after_disable"] = bpy.context.scene.render.engine


def enable():
    bpy.ops.preferences.addon_enable(module=MODULE)
    bpy.context.scene.render.engine = "VSGL"
    set_shading("RENDERED")


def resources_at_end():
    result["resources_at_end"] = [p.gpu_resource_count() for p in pipelines()]


# (action, wait: None, "converged" / ("converged", n) / "redraw", screenshot)
STEPS = [
    (setup, ("converged", 1), "01_rendered_camera"),
    (record("first"), None, None),
    (frame_and_f12, "redraw", None),
    (move_light, ("converged", 1), "02_rendered_after_moving_the_spot"),
    (after_move, None, None),
    (record("after_move"), None, None),
    (start_tracker, "redraw", "03_solid"),
    (lambda: set_shading("RENDERED"), ("converged", 1), "04_rendered_again"),
    (count_made, None, None),
    (lambda: set_shading("SOLID"), "redraw", "05_solid_again"),
    (stop_tracker, None, None),
    (split, ("converged", 2), "06_two_rendered_viewports"),
    (record("two_viewports"), None, None),
    (disable, "redraw", "07_addon_disabled"),
    (enable, ("converged", 2), "08_addon_enabled_again"),
    (resources_at_end, None, None),
]
TIMEOUT = 600.0
POLL = 0.05
state = {"step": 0, "phase": "start", "since": time.perf_counter(), "draws": 0}


def finish():
    try:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, "WINDOW")
    except Exception:  # noqa: BLE001
        pass
    with open(os.path.join(OUT, "result.json"), "w") as f:
        json.dump(result, f, indent=1, default=str)
    open(os.environ["REAL_BLENDER_SHOT_NOW"], "w").close()


def _check_timeout(what):
    if time.perf_counter() - state["since"] > TIMEOUT:
        raise RuntimeError(f"{what} not after {TIMEOUT} s at step {state['step']}")


def tick():
    try:
        if state["step"] >= len(STEPS):
            finish()
            return None
        action, wait, shot = STEPS[state["step"]]
        if state["phase"] == "start":
            if draws["viewport"] < 2:
                _check_timeout("no viewport drawn")
                return POLL
            state["phase"] = "act"
        if state["phase"] == "act":
            if action is not None:
                action()
                log(f"did {getattr(action, '__name__', 'action')}")
            state.update(phase="wait", since=time.perf_counter(), draws=draws["viewport"])
            redraw_everything()
            return POLL
        if state["phase"] == "wait":
            if isinstance(wait, tuple) and not converged(wait[1]):
                _check_timeout("not converged")
                return POLL
            if wait is not None:
                state.update(phase="redraw", draws=draws["viewport"])
                redraw_everything()
                return POLL
            state["phase"] = "shoot"
        if state["phase"] == "redraw":
            if draws["viewport"] - state["draws"] < 2:
                _check_timeout("not redrawn")
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
