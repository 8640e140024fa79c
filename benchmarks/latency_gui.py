# SPDX-License-Identifier: GPL-3.0-or-later
"""Run inside the Blender 5.2 application with its window, by benchmarks/latency.py (not a test).

    real-blender gui demo.blend --python benchmarks/latency_gui.py
    (BLENDER_VSGL_BENCH_OUT=<result.json>, BLENDER_VSGL_BENCH_MOVES, BLENDER_VSGL_BENCH_STEPS)

Where the time between a light move and the first coarse image on screen goes, in Rendered shading
(VSGL engine) through the scene's camera, resolution scale 0.25, Manual quality mode. Every event is
stamped with time.perf_counter by wrapping the Rendered viewport's pipeline's methods on the
instance (so an older checkout is measured the same way) and by handlers of this script:

* ``change``: the script moves the first light by 0.05 (and tags the 3D viewport for redraw, as
  benchmarks/interactive_gui.py does);
* ``depsgraph``: bpy.app.handlers.depsgraph_update_post (Blender evaluated the change);
* ``dirty``: pipeline.mark_scene_dirty (the engine's view_update saw a light change);
* ``draw_begin`` / ``draw_end``: pipeline.request_view and pipeline.draw (the first and the last call
  of the engine's view_draw);
* ``post_pixel``: a POST_PIXEL draw handler of the 3D viewport, the properties editor and the
  outliner (which regions Blender redraws, and when);
* ``step``: pipeline.step's start and end, with its history entry.

After each move the pipeline is stepped for STEPS steps (the coarse image, then the samples'
light passes and bands: the refinement steps), then made idle by setting its sample count to the
maximum, which is the state of a converged viewport (the timer polls at its idle interval), so that
the next move starts from where benchmarks/interactive_gui.py's moves start without waiting the
minute a full-resolution sample takes here.
"""

import importlib
import json
import os
import time
import traceback

import bpy

MODULE = "bl_ext.user_default.vsgl"
OUT = os.environ["BLENDER_VSGL_BENCH_OUT"]
MOVES = int(os.environ.get("BLENDER_VSGL_BENCH_MOVES", "8"))
STEPS = int(os.environ.get("BLENDER_VSGL_BENCH_STEPS", "8"))
SAMPLES = 8
SCALE = 0.25
POLL = 0.005
IDLE_WAIT = 0.5
TIMEOUT = 600.0
result = {"moves": [], "errors": [], "warmup": None}
events = []


def stamp(kind, **extra):
    events.append((kind, time.perf_counter(), extra))


def addon(name):
    return importlib.import_module(f"{MODULE}.vsgl_addon.{name}")


def viewport():
    for area in bpy.context.window_manager.windows[0].screen.areas:
        if area.type == "VIEW_3D":
            return area, next(r for r in area.regions if r.type == "WINDOW"), area.spaces.active
    raise RuntimeError("no 3D viewport")


def the_pipeline():
    live = list(addon("engine").live_pipelines)
    return live[0] if live else None


def instrument(pipeline):
    """Wrap the pipeline's methods on the instance: each call is stamped."""
    def wrap(name, before=None, after=None):
        method = getattr(pipeline, name)

        def wrapped(*args, **kwargs):
            if before:
                stamp(before)
            value = method(*args, **kwargs)
            if after:
                stamp(after, **({"entry": {k: v for k, v in pipeline.statistics.items()
                                           if k not in ("counts", "traceback")}} if name == "step" else {}))
            return value

        setattr(pipeline, name, wrapped)

    wrap("mark_scene_dirty", before="dirty")
    wrap("request_view", before="draw_begin")
    wrap("draw", after="draw_end")
    wrap("step", before="step_begin", after="step_end")


def on_depsgraph(scene, depsgraph):
    stamp("depsgraph")


def post_pixel(name):
    return lambda: stamp("post_pixel", space=name)


def idle(pipeline):
    """The converged state: nothing pending (see the module documentation)."""
    pipeline.samples = max(pipeline.samples, SAMPLES)


def steps_after(pipeline, first, count):
    started = time.perf_counter()
    while pipeline.steps < first + count:
        if pipeline.error:
            raise RuntimeError(pipeline.error)
        if time.perf_counter() - started > TIMEOUT:
            raise RuntimeError("no progress")
        yield POLL


def tick_generator():
    scene = bpy.context.scene
    area, region, space = viewport()
    scene.render.engine = "VSGL"
    scene.vsgl.viewport_samples = SAMPLES
    scene.vsgl.viewport_resolution_scale = SCALE
    for obj in scene.objects:
        obj.select_set(False)
    space.region_3d.view_perspective = "CAMERA"
    space.shading.type = "RENDERED"
    area.tag_redraw()
    result["region"] = [region.width, region.height]
    started = time.perf_counter()
    while the_pipeline() is None:
        if time.perf_counter() - started > TIMEOUT:
            raise RuntimeError("no pipeline")
        yield POLL
    pipeline = the_pipeline()
    instrument(pipeline)
    bpy.app.handlers.depsgraph_update_post.append(on_depsgraph)
    handles = [(space_type, space_type.draw_handler_add(post_pixel(name), (), "WINDOW", "POST_PIXEL"))
               for name, space_type in (("view3d", bpy.types.SpaceView3D),
                                        ("properties", bpy.types.SpaceProperties),
                                        ("outliner", bpy.types.SpaceOutliner))]
    # Warm-up: shaders compiled by the first coarse image and the first samples' light passes.
    yield from steps_after(pipeline, 0, STEPS + 2)
    result["warmup"] = time.perf_counter() - started
    light = next(o for o in scene.objects if o.type == "LIGHT")
    for move in range(MOVES):
        idle(pipeline)
        yield IDLE_WAIT
        events.clear()
        first = pipeline.steps
        stamp("change")
        light.location.x += 0.05 * (1 if move % 2 == 0 else -1)
        area.tag_redraw()
        yield from steps_after(pipeline, first, STEPS)
        # The coarse image is on screen at the first view_draw after its step.
        while not any(kind == "draw_end" and t > next(t2 for k2, t2, _ in events if k2 == "step_end")
                      for kind, t, _ in events):
            yield POLL
        result["moves"].append([(kind, t, extra) for kind, t, extra in events])
    for space_type, handle in handles:
        space_type.draw_handler_remove(handle, "WINDOW")
    bpy.app.handlers.depsgraph_update_post.remove(on_depsgraph)


generator = tick_generator()


def finish():
    with open(OUT, "w") as f:
        json.dump(result, f, default=float)
    open(os.environ["REAL_BLENDER_SHOT_NOW"], "w").close()


def tick():
    try:
        return next(generator)
    except StopIteration:
        finish()
        return None
    except Exception:
        result["errors"].append(traceback.format_exc())
        finish()
        return None


bpy.app.timers.register(tick, first_interval=0.5)
