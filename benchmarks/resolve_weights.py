# SPDX-License-Identifier: GPL-3.0-or-later
"""The viewport's resolve (view_gpu.py), piece by piece, without the window (not a test).

    .venv/bin/python benchmarks/resolve_weights.py [--baseline REV] [--scenes demo ...] [--rounds 2]
                                                   [--repeats 16] [--real-blender] [--no-write]

Per scene: its saved settings, a view_pipeline.ViewPipeline through the camera at 1311 × 786 (the
window of benchmarks/interactive.py) at scale 0.25, stepped once (light passes and coarse image);
then that coarse size's view render is upsampled into the full-resolution accumulation images
``--repeats`` times by each piece, in shuffled order, each timed alone (the GPU finished before and
after): the one-pass resolve (resolve.frag.glsl: the guides' reads, the range weights, six images
applied), the weights alone (jbu_weights.frag.glsl, what a kept guide computes once per render
size) and the resolve with kept weights (resolve_weighted.frag.glsl: what the coarse image after a
light, material or setting change costs). The kept weights' images are checked bit for bit against
the one-pass resolve's. With ``--baseline REV`` that commit's one-pass resolve is measured in the
same run, process by process in alternation, and its images compared with this checkout's. With
``--real-blender`` the processes are Blender 5.2 without its window (real-blender run -b) instead
of the bpy module. Writes benchmarks/results/resolve_weights.{md,json} (``resolve_weights_blender``
with --real-blender) unless --no-write.
"""

from __future__ import annotations

import argparse
import random
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # a child in Blender: --python adds no folder
from checkout_ab import (REAL_BLENDER, add_scene_arguments, baseline_sentence, child_arguments, compare_scenes,
                         open_scene, run_as_child, write_results)

REGION = (1311, 786)
SCALE = 0.25
SCENES = ("demo", "cornell_box", "polished_metal_floor")
PIECES = ("one_pass", "weights", "with_kept_weights")


def measure(repo: Path, scene: str, repeats: int, image: Path | None) -> dict:
    bpy, settings, _ = open_scene(repo, scene)
    import numpy as np

    from vsgl_addon import view_gpu
    from vsgl_addon.passes.gpu_util import finish, read_texture
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.view_pipeline import ViewPipeline
    from vsgl_addon.views import camera_vector

    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    view_matrix, projection = description.camera.view_matrix(), description.camera.projection_matrix()
    pipeline = ViewPipeline()
    targets, view = [], None
    try:
        pipeline.request_view(view_matrix, projection, REGION)
        pipeline.step(lambda: description, settings, SCALE, 2)
        width, height = pipeline.history[-1]["size"]
        view = pipeline.backend.render_view(pipeline.renderer, pipeline.lights, pipeline._seeded_settings(), width,
                                            height, view_matrix, projection, preview=True)
        guide = pipeline._full_guide(pipeline.request)
        camera = camera_vector(guide.view_matrix, guide.projection_matrix)
        projection_11 = float(np.asarray(guide.projection_matrix)[1, 1])
        targets = [view_gpu.ViewTarget(*REGION) for _ in range(2)]
        pieces = {"one_pass": lambda: view_gpu.resolve(view, guide.textures["position"], guide.textures["normal"],
                                                       camera, projection_11, targets[0])}
        kept = hasattr(view_gpu, "resolve_weighted")
        if kept:
            weights = view_gpu.GuideWeights(*REGION)
            targets.append(weights)
            pieces["weights"] = lambda: view_gpu.jbu_weights(view.textures["position"], view.textures["normal"],
                                                             guide.textures["position"], guide.textures["normal"],
                                                             camera, projection_11, weights)
            pieces["with_kept_weights"] = lambda: view_gpu.resolve_weighted(view, weights, targets[1])

        def finished():
            for target in targets:
                target.finish()

        times = {name: [] for name in pieces}
        for name, piece in pieces.items():  # compiles the shaders
            piece()
            finished()
        for _ in range(repeats):
            order = list(pieces.items())
            random.shuffle(order)
            for name, piece in order:
                finished()
                started = time.perf_counter()
                piece()
                finished()
                times[name].append(time.perf_counter() - started)
        images = {name: read_texture(targets[0].textures[name], *REGION) for name in view_gpu.IMAGES}
        row = {"size": [width, height], **{name: statistics.median(values) for name, values in times.items()}}
        if kept:
            row["identical"] = all(np.array_equal(images[name], read_texture(targets[1].textures[name], *REGION))
                                   for name in view_gpu.IMAGES)
        if image is not None:
            np.savez(image, **images)
        return row
    finally:
        if view is not None:
            view.free()
        for target in targets:
            target.free()
        pipeline.free()


def _medians(children) -> dict:
    row = {"size": children[0]["size"]}
    for name in PIECES:
        if name in children[0]:
            row[name] = statistics.median(child[name] for child in children)
    if "identical" in children[0]:
        row["identical"] = all(child["identical"] for child in children)
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_scene_arguments(parser, SCENES, 16, "timed runs of each piece per process")
    parser.add_argument("--real-blender", action="store_true", help="children in Blender 5.2 (real-blender run -b)")
    arguments = parser.parse_args(child_arguments(argv))
    if run_as_child(arguments, measure):
        return 0
    rows = compare_scenes(Path(__file__).resolve(), arguments, _medians,
                          lambda row: {key: round(1000 * value, 1) if isinstance(value, float) else value
                                       for key, value in row.items()},
                          lambda old, new: list(old.keys()), timeout=1800,
                          python=REAL_BLENDER if arguments.real_blender else sys.executable)
    if arguments.no_write:
        return 0
    baseline = arguments.baseline
    lines = ["# The viewport's resolve, piece by piece\n",
             f"Each scene's saved settings, its camera at {REGION[0]}×{REGION[1]}, the coarse image's render size "
             f"after one step at scale {SCALE}; medians of {arguments.rounds} processes × {arguments.repeats} timed "
             "runs per piece (benchmarks/resolve_weights.py), ms, llvmpipe, "
             + ("Blender 5.2 without its window (--real-blender)." if arguments.real_blender else "the bpy module.")
             + baseline_sentence(baseline)
             + " One pass: the guides' reads, the range weights and six images applied per pixel; weights: "
             "jbu_weights.frag.glsl alone; with kept weights: resolve_weighted.frag.glsl, the coarse image after "
             "a change that leaves the view and the triangles.\n"]
    header = "| scene | render | " + (f"one pass ({baseline}) | " if baseline else "") + \
             "one pass | weights | with kept weights | kept / one pass | bit-identical |"
    lines += [header, "|" + "---|" * (header.count("|") - 1)]
    for row in rows:
        current = row["current"]
        cells = [row["scene"], "×".join(str(v) for v in current["size"])]
        if baseline:
            cells.append(f"{1000 * row['baseline']['one_pass']:.1f}")
        cells += [f"{1000 * current[name]:.1f}" for name in PIECES]
        cells.append(f"{current['with_kept_weights'] / current['one_pass']:.2f}")
        identical = "yes" if current.get("identical") else "NO"
        if baseline:
            same = max(row["image_difference"].values()) == 0.0
            identical += ", and with the baseline's" if same else \
                f"; baseline's largest difference {max(row['image_difference'].values()):.1e}"
        cells.append(identical)
        lines.append("| " + " | ".join(cells) + " |")
    write_results("resolve_weights_blender" if arguments.real_blender else "resolve_weights", rows,
                  "\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
