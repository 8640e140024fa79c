# SPDX-License-Identifier: GPL-3.0-or-later
"""The CPU round trips of one change in the viewport's pipeline, without the window (not a test).

    .venv/bin/python benchmarks/round_trips.py [--region 328x196] [--samples 2] [--repo PATH]

On demo.blend with its saved settings, the Rendered viewport's pipeline (view_pipeline.ViewPipeline
on the real passes, bpy module, llvmpipe) is stepped until its samples converged, then the scene's
first light is moved and it is stepped until they converged again: what benchmarks/interactive.py
measures per change in the window, counted by passes.gpu_util.RoundTrips (textures read back and
arrays uploaded, in bytes), with the light builds (one per sample's seed) and renders of the change.
The bytes do not depend on the machine's speed except for the view renders' few hundred bytes each
(their number follows the bands' sizes). ``--repo``: import the add-on from another checkout (e.g.
an export of an earlier commit, `git archive <commit> | tar -x -C DIR`), to compare in one session.
Writes benchmarks/results/round_trips.{md,json} unless --repo is given.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "benchmarks" / "results"


def measure(repo: Path, region, samples: int) -> dict:
    sys.path.insert(0, str(repo))
    import bpy

    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.passes.gpu_util import RoundTrips
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings
    from vsgl_addon.view_pipeline import ViewPipeline

    ensure_gpu_context()
    register()
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"), load_ui=False)
    settings = VSGLSettings.from_properties(bpy.context.scene.vsgl)
    light = next(o for o in bpy.context.scene.objects if o.type == "LIGHT")

    def describe():
        return extract_scene(bpy.context.evaluated_depsgraph_get())

    camera = describe().camera
    pipeline = ViewPipeline()
    pipeline.request_view(camera.view_matrix(), camera.projection_matrix(), region)

    def converge():
        builds = renders = 0
        while True:
            work = pipeline.step(describe, settings, 0.25, samples)
            if work is None:
                return builds, renders
            entry = pipeline.history[-1]
            builds += work == "lights" or bool(entry.get("lights_complete", "light_seconds" in entry))
            renders += bool(entry.get("level"))

    try:
        converge()
        light.location.x += 0.1
        bpy.context.view_layer.update()
        pipeline.mark_scene_dirty()
        keys = ("read_backs", "read_back_bytes", "uploads", "upload_bytes")
        before = {key: getattr(RoundTrips, key) for key in keys}
        builds, renders = converge()
        row = {key: getattr(RoundTrips, key) - before[key] for key in keys}
    finally:
        pipeline.free()
    return dict(row, light_builds=builds, renders=renders, region=list(region), samples=samples)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--region", default="328x196")
    parser.add_argument("--samples", type=int, default=2)
    parser.add_argument("--repo", type=Path, default=None)
    arguments = parser.parse_args(argv)
    region = tuple(int(v) for v in arguments.region.lower().split("x"))
    row = measure(arguments.repo or REPO, region, arguments.samples)
    print(json.dumps(row))
    if arguments.repo is None:
        RESULTS.mkdir(parents=True, exist_ok=True)
        (RESULTS / "round_trips.json").write_text(json.dumps(row, indent=2))
        (RESULTS / "round_trips.md").write_text(
            "# CPU round trips of one change in the viewport's pipeline\n\n"
            f"demo.blend, its saved settings, a light moved, {row['samples']} samples at "
            f"{region[0]}×{region[1]} (scale 0.25 coarse image first); passes.gpu_util.RoundTrips.\n\n"
            "| light builds | renders | read back (textures / bytes) | uploaded (arrays / bytes) |\n|---|---|---|---|\n"
            f"| {row['light_builds']} | {row['renders']} | {row['read_backs']} / {row['read_back_bytes']} "
            f"| {row['uploads']} / {row['upload_bytes']} |\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
