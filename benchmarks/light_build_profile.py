# SPDX-License-Identifier: GPL-3.0-or-later
"""Where one light build's time goes, as the viewport makes it after a light moved (not a test).

    .venv/bin/python benchmarks/light_build_profile.py [--scenes demo occluder cornell_box caustic_panel]
                                                       [--repeats 5] [--baseline REV] [--no-write]

Per scene (demo.blend and validation scenes, each with its saved settings, as the Rendered viewport
builds them: no view, the viewport's PointTextureCache kept across builds), the first light is moved
and renderer.SceneLights.build is run, ``--repeats`` times after one warm-up build (which compiles the
shaders, timed apart as "cold"), in ``--rounds`` fresh processes per checkout. Stages, GPU finished, median over the repeats, in ms:

* the scene description (scene.extract_scene, per change in the viewport) and the planner (plan_frame);
* each VSGL set's RSM views and VSGL tables (pipeline.render_scene_vsgls) and its imperfect shadow
  maps (pipeline.build_visibility), per receiver set of the plan;
* the VPL extraction and clusters, the mirror maps (MRP-ASG visibility), SceneLights' own timings;
* every compute shader's dispatch time summed per (pass, shader): llvmpipe runs a dispatch before
  gpu.compute.dispatch returns, so that is the shader's GPU time (draws are deferred: they are not
  counted there).

``--baseline REV``: the same measurement of an export of commit REV (``git archive``) in the same run,
round by round in alternation with this checkout (absolute times are noisy on this shared 2-core
llvmpipe machine: read the ratios), and the frame each build lights (FrameRenderer.render_view
through the scene's camera at 160 × 90) compared between the two: each image's largest absolute
difference over its largest value. Writes benchmarks/results/light_build_profile.{md,json} unless --no-write.
"""

from __future__ import annotations

import argparse
import collections
import statistics
import time
from pathlib import Path

import checkout_ab
SCENES = ("demo", "occluder", "cornell_box", "caustic_panel")
IMAGE_SIZE = (160, 90)
# The window of benchmarks/interactive.py (its 1600 × 900 screen's 3D viewport), its preview scale, samples.
VIEWPORT_REGION = (1311, 786)
VIEWPORT_SCALE = 0.25
VIEWPORT_SAMPLES = 2
IMAGES = ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular",
          "indirect_glossy_reflectors", "indirect_caustics")


def measure(repo: Path, name: str, repeats: int, image_path: Path | None) -> dict:
    """One scene's builds in this process, with the add-on imported from ``repo``."""
    bpy, settings, light = checkout_ab.open_scene(repo, name)
    import gpu
    import numpy as np

    import vsgl_addon.renderer as renderer
    from vsgl_addon.passes import contract
    from vsgl_addon.passes.gpu_util import finish
    from vsgl_addon.passes.scene_gpu import PointTextureCache
    from vsgl_addon.scene import extract_scene

    stages: dict[str, float] = collections.defaultdict(float)
    shaders: dict[str, float] = collections.defaultdict(float)
    names = {}
    shader_of = contract.GPUPass.shader

    def named_shader(self, key=None):
        shader = shader_of(self, key)
        names[id(shader)] = f"{self.name}.{key or self.name}"
        return shader

    dispatch = gpu.compute.dispatch

    def timed_dispatch(shader, *groups):
        started = time.perf_counter()
        dispatch(shader, *groups)
        shaders[names.get(id(shader), "other")] += time.perf_counter() - started

    def wrap(function, label, texture_of):
        def wrapped(*args, **kwargs):
            started = time.perf_counter()
            result = function(*args, **kwargs)
            texture = texture_of(args, result)
            if texture is not None:
                finish(texture)
            stages[label(args)] += time.perf_counter() - started
            return result
        return wrapped

    sets = []

    def vsgls_label(args):
        lobe = args[2] if len(args) > 2 else "all"
        sets.append(lobe)
        return f"rsm_vsgl[{lobe}]"

    originals = renderer.render_scene_vsgls, renderer.build_visibility, renderer.plan_frame
    contract.GPUPass.shader = named_shader
    gpu.compute.dispatch = timed_dispatch
    renderer.render_scene_vsgls = wrap(
        renderer.render_scene_vsgls, vsgls_label,
        lambda args, result: result.generations[-1][2].table if result.generations else None)
    renderer.build_visibility = wrap(
        renderer.build_visibility, lambda args: f"ism[{sets[len([k for k in stages if k.startswith('ism[')])]}]",
        lambda args, result: args[1].isms[-1].texture if args[1].isms else None)
    renderer.plan_frame = wrap(renderer.plan_frame, lambda args: "planner", lambda args, result: None)

    cache = PointTextureCache()
    runs = []
    image = None
    try:
        for index in range(repeats + 1):
            light.location.x += 0.05 * (1 if index % 2 == 0 else -1)
            bpy.context.view_layer.update()
            stages.clear()
            shaders.clear()
            sets.clear()
            started = time.perf_counter()
            description = extract_scene(bpy.context.evaluated_depsgraph_get())
            stages["scene_description"] = time.perf_counter() - started
            started = time.perf_counter()
            lights = renderer.SceneLights.build(description, settings, point_cache=cache)
            stages["build"] = time.perf_counter() - started
            stages.update({f"timings.{key}": value for key, value in lights.timings.items()})
            runs.append({"stages": dict(stages), "shaders": dict(shaders)})
            if index == repeats and image_path is not None:
                camera = description.camera
                frame = renderer.FrameRenderer()
                try:
                    images = frame.render_view(lights, settings, *IMAGE_SIZE, camera.view_matrix(),
                                               camera.projection_matrix())
                finally:
                    frame.free()
                image = {key: getattr(images, key) for key in IMAGES}
                np.savez(image_path, **image)
            lights.free()
    finally:
        cache.free()
        contract.GPUPass.shader, gpu.compute.dispatch = shader_of, dispatch
        renderer.render_scene_vsgls, renderer.build_visibility, renderer.plan_frame = originals
    return {"scene": name, "plan_sets": list(dict.fromkeys(sets)), "cold_build": runs[0]["stages"]["build"],
            "runs": runs[1:], "viewport": viewport_steps(bpy, light, settings, repeats)}


def viewport_steps(bpy, light, settings, repeats: int) -> list[dict]:
    """The Rendered viewport's first step after a light moved, without the window: a
    view_pipeline.ViewPipeline on the real passes through the camera at VIEWPORT_REGION, scale 0.25,
    stepped once per move (the light passes of the new state, then the coarse image): the step's
    seconds and its light passes' (what benchmarks/interactive.py's "first step" column times in
    the window)."""
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.view_pipeline import ViewPipeline

    def describe():
        return extract_scene(bpy.context.evaluated_depsgraph_get())

    camera = describe().camera
    pipeline = ViewPipeline()
    steps = []
    try:
        pipeline.request_view(camera.view_matrix(), camera.projection_matrix(), VIEWPORT_REGION)
        for index in range(repeats + 1):
            light.location.x += 0.05 * (1 if index % 2 == 0 else -1)
            bpy.context.view_layer.update()
            pipeline.mark_scene_dirty()
            pipeline.step(describe, settings, VIEWPORT_SCALE, VIEWPORT_SAMPLES)
            entry = pipeline.history[-1]
            if "error" in entry:
                raise RuntimeError(entry["error"])
            if index:  # the first one compiles the view passes' shaders
                steps.append({"seconds": entry["seconds"], "light_seconds": entry.get("light_seconds", 0.0),
                              "level": entry.get("level"), "size": list(entry.get("size") or ())})
    finally:
        pipeline.free()
    return steps


def _medians(children: list[dict]) -> dict:
    """The children's builds pooled: each stage's median, the cold builds' median."""
    runs = [run for child in children for run in child["runs"]]
    median = {}
    for part in ("stages", "shaders"):
        keys = sorted({key for run in runs for key in run[part]})
        median[part] = {key: statistics.median(run[part].get(key, 0.0) for run in runs) for key in keys}
    steps = [step for child in children for step in child["viewport"]]
    median["stages"]["viewport: change → first image (step)"] = statistics.median(step["seconds"] for step in steps)
    median["stages"]["viewport: its light passes"] = statistics.median(step["light_seconds"] for step in steps)
    return {"plan_sets": children[0]["plan_sets"], "builds": len(runs), "viewport_steps": steps,
            "cold_build": statistics.median(child["cold_build"] for child in children), **median}


def _ms(value) -> str:
    return f"{1000 * value:.0f}"


def _table(rows: list[dict], baseline: bool) -> str:
    lines = []
    for row in rows:
        current = row["current"]
        before = row.get("baseline")
        lines.append(f"\n### {row['scene']} (receiver sets {', '.join(current['plan_sets'])})\n")
        if before is not None:
            lines.append(f"Cold first build (shaders compiled): {_ms(before['cold_build'])} → "
                         f"{_ms(current['cold_build'])} ms. Frame at {IMAGE_SIZE[0]}×{IMAGE_SIZE[1]}, "
                         "largest absolute difference per image over its largest value: "
                         + ", ".join(f"{key} {value:.2e}" for key, value in row["image_difference"].items()) + ".\n")
            lines.append("| stage | before (ms) | after (ms) | after / before |\n|---|---|---|---|")
        else:
            lines.append(f"Cold first build: {_ms(current['cold_build'])} ms.\n")
            lines.append("| stage | ms |\n|---|---|")
        for part in ("stages", "shaders"):
            keys = list(dict.fromkeys([*(before or {}).get(part, {}), *current[part]]))
            if part == "shaders":
                keys.sort(key=lambda key: -current[part].get(key, 0.0))
            for key in keys:
                label = f"shader {key}" if part == "shaders" else key
                now = current[part].get(key, 0.0)
                if before is not None:
                    old = before[part].get(key, 0.0)
                    ratio = f"{now / old:.2f}" if old > 0 else "—"
                    lines.append(f"| {label} | {_ms(old)} | {_ms(now)} | {ratio} |")
                else:
                    lines.append(f"| {label} | {_ms(now)} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    checkout_ab.add_scene_arguments(parser, SCENES, 5, "builds per process after the warm-up")
    arguments = parser.parse_args(argv)
    if checkout_ab.run_as_child(arguments, measure):
        return 0
    rows = checkout_ab.compare_scenes(Path(__file__).resolve(), arguments, _medians,
                                      lambda medians: medians["stages"].get("build"), lambda old, new: IMAGES,
                                      timeout=3600)
    if arguments.no_write:
        return 0
    header = ("# One light build, stage by stage\n\n"
              "As the Rendered viewport builds the light passes after a light moved (renderer.SceneLights.build, "
              "no view, the viewport's point-set cache), each scene's saved settings, llvmpipe on a shared 2-core "
              f"machine; median of {arguments.rounds} processes × {arguments.repeats} builds, each process's warm-up build "
              "apart (\"cold\"), GPU finished, ms. "
              "`timings.*` are SceneLights' own; `shader pass.key` the compute dispatches' summed time "
              "(llvmpipe runs them synchronously)." + checkout_ab.baseline_sentence(arguments.baseline))
    checkout_ab.write_results("light_build_profile", rows,
                              header + "\n" + _table(rows, arguments.baseline is not None))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
