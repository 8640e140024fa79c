# SPDX-License-Identifier: GPL-3.0-or-later
"""Run inside the Blender 5.2 application with its window, by benchmarks/interactive.py (one scene).

    real-blender gui SCENE.blend --python benchmarks/interactive_gui.py
    (BLENDER_VSGL_BENCH_OUT=<result.json>, BLENDER_VSGL_BENCH_SAMPLES, BLENDER_VSGL_BENCH_REPEATS)

Through the scene's camera, in the 3D viewport of the default layout:

1. Rendered shading (VSGL engine), in Manual quality mode (the scene's settings): after a warm-up,
   the first light is moved REPEATS + 1 times; for each move, the viewport's step log
   (view_pipeline.ViewPipeline.history) gives the time from the change to the first coarse image,
   the time of each refinement step and of the whole convergence. On the first move the displayed
   average image is also read back (outside the steps' timing) whenever a step changed it (a coarse
   image, or one more full-resolution sample: the steps between only fill the next sample's bands),
   to find the work time after which it is within 10 % / 5 % relative RMSE of the converged image.
   Only those few images are kept (one per sample count), not one per step.
2. The same in Budget quality mode (target frame time BUDGET_MS, BLENDER_VSGL_BENCH_BUDGET_MS): the
   switch's first coarse image is the one whose size the cost model predicts (budget.coarse_factor);
   its converged image must equal Manual's at the same light position.
3. The overlay over Solid shading, "Combined", at the same resolution scale and samples, in the same
   session: it draws through the same view pipeline (overlay.py on view_pipeline.ViewportSet), so
   the same moves must give the same step times, its converged image must equal the Rendered one,
   and neither path may read images back or upload them per update (the CPU round trips, bytes read
   back and uploaded, are counted for both).
"""

import importlib
import json
import os
import time
import traceback

import bpy
import numpy as np

MODULE = "bl_ext.user_default.vsgl"
OUT = os.environ["BLENDER_VSGL_BENCH_OUT"]
SAMPLES = int(os.environ.get("BLENDER_VSGL_BENCH_SAMPLES", "8"))
REPEATS = int(os.environ.get("BLENDER_VSGL_BENCH_REPEATS", "3"))
BUDGET_MS = float(os.environ.get("BLENDER_VSGL_BENCH_BUDGET_MS", "60"))
SCALE = 0.25
POLL = 0.01
TIMEOUT = 900.0
result = {"rendered": [], "rendered_budget": [], "overlay": [], "errors": [], "budget_ms": BUDGET_MS}
#: The light's offset from its start, in moves (+1 / -1 each): converged images are compared at equal offsets.
offset = 0


def addon(name):
    return importlib.import_module(f"{MODULE}.vsgl_addon.{name}")


def viewport():
    for area in bpy.context.window.screen.areas if bpy.context.window else bpy.context.window_manager.windows[0].screen.areas:
        if area.type == "VIEW_3D":
            return area, next(r for r in area.regions if r.type == "WINDOW"), area.spaces.active
    raise RuntimeError("no 3D viewport")


def the_pipeline():
    live = list(addon("engine").live_pipelines)
    return live[0] if live else None


def round_trips():
    counter = addon("passes.gpu_util").RoundTrips
    return {"read_backs": counter.read_backs, "read_back_bytes": counter.read_back_bytes,
            "uploads": counter.uploads, "upload_bytes": counter.upload_bytes, "syncs": counter.syncs}


def light_object():
    return next(o for o in bpy.context.scene.objects if o.type == "LIGHT")


def average_image(pipeline):
    """The pipeline's displayed combined image (direct + indirect, sum / samples): a read-back for
    the benchmark's error curve only."""
    read = addon("passes.gpu_util").read_texture
    target = pipeline.target
    width, height = target.size
    total = sum(read(target.textures[name], width, height)[..., :3]
                for name in ("direct", "indirect_diffuse", "indirect_specular"))
    return total / max(pipeline.samples, 1)


def rmse(image, reference):
    return float(np.sqrt(np.mean((image - reference) ** 2)) / max(np.sqrt(np.mean(reference ** 2)), 1e-30))


def snapshotting(pipeline, store):
    """Wrap pipeline.step so that, after each step's own timing, the step is logged with the image it
    left on screen: read back only when the step changed it (a coarse image, or a sample completed;
    a band of the next sample does not touch the displayed average), else None (the last one's)."""
    step = pipeline.step
    last = {"samples": None}

    def wrapped(*args, **kwargs):
        work = step(*args, **kwargs)
        if work is not None and pipeline.has_image:
            changed = (pipeline.statistics.get("level") == "coarse" or pipeline.samples != last["samples"])
            last["samples"] = pipeline.samples
            store.append((pipeline.statistics["index"], pipeline.samples,
                          average_image(pipeline) if changed else None))
        return work

    pipeline.step = wrapped
    return lambda: pipeline.__dict__.pop("step", None)


def error_curve(snapshots, entries, converged_image):
    """Per logged step: its samples, the work seconds so far and the relative RMSE of the image it
    left on screen against the converged one (computed once per distinct image)."""
    seconds = {e["index"]: e["seconds"] for e in entries}
    curve, error, work = [], None, 0.0
    for index, samples, image in snapshots:
        if image is not None:
            error = rmse(image, converged_image)
        work = sum(s for i, s in seconds.items() if i <= index)
        curve.append({"index": index, "samples": samples, "work_seconds": work, "relative_rmse": error})
    return curve


def rendered_converged():
    pipeline = the_pipeline()
    if pipeline is not None and pipeline.error:
        raise RuntimeError(pipeline.error)
    return pipeline is not None and pipeline.converged(SAMPLES)


def overlay_pipeline():
    _area, _region, space = viewport()
    views = addon("overlay").views
    if views.error:
        raise RuntimeError(views.error)
    return views.pipelines.get(space.region_3d.as_pointer())


def overlay_converged():
    pipeline = overlay_pipeline()
    return pipeline is not None and pipeline.converged(SAMPLES)


def move_light(sign):
    global offset
    light = light_object()
    light.location.x += 0.05 * sign
    offset += sign


def wait_rendered(first_index, what):
    """Yield until the Rendered pipeline stepped past `first_index` and converged."""
    started = time.perf_counter()
    while not (the_pipeline() is not None and the_pipeline().steps > first_index and rendered_converged()):
        if time.perf_counter() - started > TIMEOUT:
            raise RuntimeError(f"no convergence {what}")
        yield POLL


def rendered_moves(records, area):
    """REPEATS + 1 light moves in Rendered shading, each to convergence; the first with the error
    curve. Returns (converged image of the first move, the light offset it was at)."""
    converged = None
    for repeat in range(REPEATS + 1):
        pipeline = the_pipeline()
        first_index = pipeline.steps
        snapshots = []
        undo = snapshotting(pipeline, snapshots) if repeat == 0 else None
        trips = round_trips()
        change = time.perf_counter()
        move_light(1 if repeat % 2 == 0 else -1)
        area.tag_redraw()
        yield from wait_rendered(first_index, "after a change")
        done = time.perf_counter()
        if undo is not None:
            undo()
        entries = [dict(e) for e in pipeline.history if e["index"] >= first_index]
        after = round_trips()
        record = {"repeat": repeat, "entries": [{k: v for k, v in e.items() if k not in ("counts", "traceback")}
                                                for e in entries],
                  "first_image_wall": entries[0]["ended"] - change, "first_step_seconds": entries[0]["seconds"],
                  "converged_wall": done - change, "round_trips": {k: after[k] - trips[k] for k in after}}
        if snapshots:
            converged = (average_image(pipeline), offset)
            record["error_curve"] = error_curve(snapshots, entries, converged[0])
            record["images_kept"] = sum(image is not None for _, _, image in snapshots)
            snapshots.clear()
        records.append(record)
    return converged


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
    while not rendered_converged():  # warm-up: shaders compiled, first convergence
        if time.perf_counter() - started > TIMEOUT:
            raise RuntimeError("no convergence")
        yield POLL
    manual = yield from rendered_moves(result["rendered"], area)
    # --- Budget quality mode: the viewport's coarse step sized by the cost model ---
    pipeline = the_pipeline()
    first_index = pipeline.steps
    change = time.perf_counter()
    scene.vsgl.time_budget_ms = BUDGET_MS
    scene.vsgl.quality_mode = "BUDGET"
    area.tag_redraw()
    yield from wait_rendered(first_index, "in Budget mode")
    entries = [{k: v for k, v in e.items() if k not in ("counts", "traceback")}
               for e in pipeline.history if e["index"] >= first_index]
    model = pipeline.cost_model
    result["budget_switch"] = {"first_image_wall": entries[0]["ended"] - change, "first_entry": entries[0],
                               "converged_wall": time.perf_counter() - change,
                               "cost_model": None if model is None else model.source,
                               "cost_model_warning": None if model is None else model.warning}
    budget = yield from rendered_moves(result["rendered_budget"], area)
    if manual is not None and budget is not None and manual[1] == budget[1]:
        result["budget_converged_relative_rmse_manual"] = rmse(budget[0], manual[0])
    converged_image = manual
    # --- the overlay over Solid shading: the same view pipeline ---
    space.shading.type = "SOLID"
    scene.vsgl.quality_mode = "MANUAL"  # the overlay as before: the scene's settings
    scene.vsgl.overlay_mode = "COMBINED"
    scene.vsgl.overlay_resolution_scale = SCALE
    scene.vsgl.show_overlay = True
    area.tag_redraw()
    started = time.perf_counter()
    while not overlay_converged():
        if time.perf_counter() - started > TIMEOUT:
            raise RuntimeError("no converged overlay")
        yield POLL
    for repeat in range(REPEATS):
        pipeline = overlay_pipeline()
        first_index = pipeline.steps
        trips = round_trips()
        change = time.perf_counter()
        move_light(1 if repeat % 2 == 0 else -1)
        area.tag_redraw()
        while not (pipeline.steps > first_index and overlay_converged()):
            if time.perf_counter() - change > TIMEOUT:
                raise RuntimeError("no converged overlay after a change")
            yield POLL
        done = time.perf_counter()
        after = round_trips()
        entries = [dict(e) for e in pipeline.history if e["index"] >= first_index]
        result["overlay"].append({
            "repeat": repeat, "first_image_wall": entries[0]["ended"] - change, "refined_wall": done - change,
            "updates": [{"level": e.get("level"), "work": e["work"], "seconds": e["seconds"], "size": e.get("size")}
                        for e in entries],
            "round_trips": {k: after[k] - trips[k] for k in after}})
    if converged_image is not None and converged_image[1] == offset:
        # Moves alternate +, -, +, ...: with REPEATS odd, after the Rendered repeats and the
        # overlay's the light is where it was for the first Rendered repeat, whose image this is.
        result["overlay_final_relative_rmse_nearest"] = rmse(average_image(overlay_pipeline()), converged_image[0])
    scene.vsgl.show_overlay = False


generator = tick_generator()


def finish():
    with open(OUT, "w") as f:
        json.dump(result, f, indent=1, default=float)
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
