# SPDX-License-Identifier: GPL-3.0-or-later
"""The view passes' time, pass by pass, at the viewport's coarse size and at 240 × 180, against a
baseline commit in the same run (not a test).

    .venv/bin/python benchmarks/view_passes_profile.py [--scenes demo] [--baseline REV] [--repeats 4]
                                                       [--rounds 2] [--no-write]

Per scene (demo.blend or a validation scene, its saved settings), in ``--rounds`` fresh processes per
checkout, alternating (ABBA...; absolute times are noisy on this shared 2-core llvmpipe machine:
read the ratios):

* the light passes are built once as the Rendered viewport builds them (no view, its point-set cache);
* the view passes (renderer.FrameRenderer.render_view_textures with timings: each pass finished,
  GPU time included) through the camera at COARSE_SIZE (the viewport's coarse image after a change
  on the demo at VIEWPORT_REGION, scale 0.25: view_gpu.GPUViewBackend.render_view's preview VPL
  stride) and at 240 × 180 (every VPL), ``--repeats`` times after a warm-up that compiles the shaders;
* the viewport's stages after them: the guide G-buffer at VIEWPORT_REGION, the joint bilateral
  resolve of the coarse render into it (view_gpu.resolve) and the addition of that image into a
  running sum (view_gpu.accumulate, a refinement sample's), each finished;
* the windowless first step after a light moved (light_build_profile.viewport_steps: the light
  passes of the new state, then the coarse image; the coarse size adapts to the steps before).

Medians in ms, and per stage the median over rounds of the ratio of a round's two processes (run
back to back). The frame at 160 × 90 (FrameRenderer.render_view) and the resolved coarse image are
compared between the checkouts: each image's largest absolute difference over its largest value.
Writes benchmarks/results/view_passes_profile.{md,json} unless --no-write.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import checkout_ab
#: The demo's coarse image in light_build_profile.md's committed run (1311 × 786 at scale 0.25,
#: coarse factor 0.25).
COARSE_SIZE = (82, 49)
SIZES = {"coarse": COARSE_SIZE, "240x180": (240, 180)}
VIEWPORT_REGION = (1311, 786)
IMAGE_SIZE = (160, 90)
IMAGES = ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular",
          "indirect_glossy_reflectors", "indirect_caustics")


def measure(repo: Path, name: str, repeats: int, image_path: Path) -> dict:
    """One scene's view passes in this process, with the add-on imported from ``repo``."""
    bpy, settings, light = checkout_ab.open_scene(repo, name)
    import numpy as np

    from vsgl_addon import view_gpu
    from vsgl_addon.passes.gpu_util import finish, read_texture
    from vsgl_addon.reference.vpl_culling import preview_stride
    from vsgl_addon.scene import extract_scene

    from light_build_profile import viewport_steps

    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    camera = description.camera
    view, projection = camera.view_matrix(), camera.projection_matrix()
    backend = view_gpu.GPUViewBackend()
    renderer = backend.frame_renderer()
    lights = backend.scene_lights(description, settings)
    stride = preview_stride(settings.rsm_size * settings.rsm_size)
    passes: dict[str, dict[str, list]] = {label: {} for label in SIZES}
    images = {}
    target, other = view_gpu.ViewTarget(*VIEWPORT_REGION), view_gpu.ViewTarget(*VIEWPORT_REGION)
    try:
        for index in range(repeats + 1):
            for label, size in SIZES.items():
                timings = {}
                started = time.perf_counter()
                textures = renderer.render_view_textures(lights, settings, *size, view, projection, timings,
                                                         vpl_stride=stride if label == "coarse" else 1)
                total = time.perf_counter() - started
                try:
                    if label == "coarse":
                        started = time.perf_counter()
                        guide = renderer.guide(lights, *VIEWPORT_REGION, view, projection)
                        finish(guide.textures["position"])
                        timings["viewport guide G-buffer"] = time.perf_counter() - started
                        started = time.perf_counter()
                        backend.resolve(textures, guide, target, None)
                        target.finish()
                        timings["viewport resolve"] = time.perf_counter() - started
                        started = time.perf_counter()
                        view_gpu.accumulate(target, other, 0.5, add=True)
                        other.finish()
                        timings["viewport accumulate"] = time.perf_counter() - started
                        if index == repeats:
                            for key, texture in target.textures.items():
                                images[f"resolved_{key}"] = read_texture(texture, *VIEWPORT_REGION)
                            view_gpu.accumulate(target, other, 0.5, add=False)
                            images["accumulated_direct"] = read_texture(other.textures["direct"], *VIEWPORT_REGION)
                        guide.free()
                finally:
                    textures.free()
                timings["view passes"] = total
                if index:  # the first compiles the shaders
                    for key, value in timings.items():
                        passes[label].setdefault(key, []).append(value)
        frame = renderer.render_view(lights, settings, *IMAGE_SIZE, view, projection)
        images.update({key: np.asarray(getattr(frame, key)) for key in IMAGES if getattr(frame, key) is not None})
        np.savez(image_path, **images)
    finally:
        lights.free()
        renderer.free()
        backend.free()
        target.free()
        other.free()
    steps = viewport_steps(bpy, light, settings, repeats)
    return {"scene": name, "passes": passes, "viewport_steps": steps}


def _medians(children: list[dict]) -> dict:
    median = {}
    for label in SIZES:
        keys = list(dict.fromkeys(key for child in children for key in child["passes"][label]))
        median[label] = {key: statistics.median(value for child in children for value in child["passes"][label][key])
                         for key in keys}
    steps = [step for child in children for step in child["viewport_steps"]]
    median["first step"] = {
        "change → first image (step)": statistics.median(step["seconds"] for step in steps),
        "its light passes": statistics.median(step["light_seconds"] for step in steps),
        "its view part": statistics.median(step["seconds"] - step["light_seconds"] for step in steps)}
    return {"viewport_steps": steps, **median}


def _pair_ratios(before: list[dict], after: list[dict]) -> dict:
    """Per stage, the median over rounds of after / before of the two processes of one round (run
    back to back, so they share the machine's load more than the pooled medians do)."""
    ratios = {}
    for old, new in zip(before, after):
        old, new = _medians([old]), _medians([new])
        for label in (*SIZES, "first step"):
            for key, value in new[label].items():
                if old[label].get(key, 0.0) > 0:
                    ratios.setdefault(label, {}).setdefault(key, []).append(value / old[label][key])
    return {label: {key: statistics.median(values) for key, values in part.items()} for label, part in ratios.items()}


def _table(rows: list[dict], baseline: str | None) -> str:
    lines = []
    for row in rows:
        current, before = row["current"], row.get("baseline")
        lines.append(f"\n### {row['scene']}\n")
        if before is not None:
            lines.append("Largest absolute difference per image over its largest value (frame at "
                         f"{IMAGE_SIZE[0]}×{IMAGE_SIZE[1]}; `resolved_*` the coarse image resolved at "
                         f"{VIEWPORT_REGION[0]}×{VIEWPORT_REGION[1]}): "
                         + ", ".join(f"{key} {value:.2e}" for key, value in row["image_difference"].items()) + ".\n")
            lines.append("| size | stage | before (ms) | after (ms) | after / before | per round (median) |\n"
                         "|---|---|---|---|---|---|")
        else:
            lines.append("| size | stage | ms |\n|---|---|---|")
        for label in (*SIZES, "first step"):
            size = f"{SIZES[label][0]}×{SIZES[label][1]}" if label in SIZES else "first step"
            for key in dict.fromkeys([*(before or {}).get(label, {}), *current[label]]):
                now = current[label].get(key, 0.0)
                if before is not None:
                    old = before[label].get(key, 0.0)
                    ratio = f"{now / old:.2f}" if old > 0 else "—"
                    paired = row["pair_ratios"].get(label, {}).get(key)
                    lines.append(f"| {size} | {key} | {1000 * old:.1f} | {1000 * now:.1f} | {ratio} | "
                                 f"{f'{paired:.2f}' if paired is not None else '—'} |")
                else:
                    lines.append(f"| {size} | {key} | {1000 * now:.1f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    checkout_ab.add_scene_arguments(parser, ["demo"], 4, "measurements per process after the warm-up")
    arguments = parser.parse_args(argv)
    if checkout_ab.run_as_child(arguments, measure):
        return 0
    rows = checkout_ab.compare_scenes(
        Path(__file__).resolve(), arguments, _medians, lambda medians: medians["first step"],
        lambda old, new: [key for key in old.files if key in new.files], timeout=1800, nice=5,
        pair_ratios=_pair_ratios)
    print(_table(rows, arguments.baseline))
    if arguments.no_write:
        return 0
    header = ("# The view passes, pass by pass\n\n"
              "The Rendered viewport's view passes (renderer.FrameRenderer.render_view_textures, each pass "
              f"finished) through the camera at the coarse size {COARSE_SIZE[0]}×{COARSE_SIZE[1]} (preview VPL "
              "stride) and at 240×180, then the viewport's guide G-buffer, joint bilateral resolve and accumulation at "
              f"{VIEWPORT_REGION[0]}×{VIEWPORT_REGION[1]}, and the windowless first step after a light moved "
              "(light_build_profile.viewport_steps); each scene's saved settings, llvmpipe on a shared 2-core "
              f"machine; median of {arguments.rounds} processes × {arguments.repeats} measurements, each process's "
              "warm-up apart, ms; \"per round\" is the median over rounds of after / before of each round's two "
              "processes, run back to back." + checkout_ab.baseline_sentence(arguments.baseline))
    checkout_ab.write_results("view_passes_profile", rows, header + "\n" + _table(rows, arguments.baseline))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
