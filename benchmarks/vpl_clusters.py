# SPDX-License-Identifier: GPL-3.0-or-later
"""The VPL shadows' clusters made on the GPU against the CPU path they replaced, in one run (not a test).

    .venv/bin/python benchmarks/vpl_clusters.py [--scenes caustic_panel demo] [--size 240x180] [--repeats 3]
        [--rsm-size N] [--output vpl_clusters]

Per scene (the validation suite's, each with its saved settings: VPL shadows on; demo.blend), one
frame of FrameRenderer after a warm-up frame, twice in the same session:

* CPU: the light build's VPLs read back (passes/vpl_culling.py scene_vpls: each VPL RSM view's three
  extraction slots) and their clusters' map origins, minimum distances and half-spaces made in
  float64 (vpl_clusters, upload_visible_vpls), as the renderer did before;
* GPU: extract_vpls with shadows (glsl/vpl_culling/vpl_clusters.comp.glsl, vpl_cluster_sets.comp.glsl;
  nothing read back, a map per block of every view);

and the images compared (largest absolute difference of each image, and relative to its largest
value), with the bytes each frame reads back (its images, the planner's totals, the VPL count for the
frame's counts, and on the CPU path the VPLs) and uploads, and the light build's VPL step
(`vpl_extraction`, median of the repeats; wall clock on a shared 2-core llvmpipe machine: read the
ratio). ``--rsm-size``: every scene at that RSM side instead of its own (more blocks, so more
empty maps in the GPU's atlas). Writes benchmarks/results/<output>.{md,json}.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

RESULTS = REPO / "benchmarks" / "results"
IMAGES = ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular", "indirect_caustics")


def _cpu_extract(original):
    """extract_vpls as the renderer's CPU path made the shadowed VPLs (scene_vpls read back, then
    upload_visible_vpls)."""
    from vsgl_addon.passes import vpl_culling

    def extract(scene_gpu, rsm_size, caustic_roughness, shadows=None, first_map=0):
        if shadows is None:
            return original(scene_gpu, rsm_size, caustic_roughness)
        found = vpl_culling.scene_vpls(scene_gpu, rsm_size, caustic_roughness)
        return vpl_culling.upload_visible_vpls(found, scene_gpu, shadows, rsm_size, first_map)

    return extract


def measure(name: str, size, repeats: int, rsm_size: int | None = None) -> dict:
    import bpy

    from validation_suite import DEMO, open_scene
    from build_validation_scenes import scene_path
    from vsgl_addon.passes import vpl_culling
    from vsgl_addon.passes.gpu_util import RoundTrips
    from vsgl_addon.renderer import FrameRenderer
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    scene = open_scene(DEMO if name == "demo" else scene_path(name))
    settings = VSGLSettings.from_properties(scene.vsgl)
    if rsm_size is not None:
        settings = settings.overridden(rsm_size=rsm_size)
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    original = vpl_culling.extract_vpls
    paths = {"cpu": _cpu_extract(original), "gpu": original}
    frames, seconds, traffic = {}, {}, {}
    try:
        for path in ("cpu", "gpu"):
            vpl_culling.extract_vpls = paths[path]
            renderer = FrameRenderer()
            try:
                renderer.render(description, settings, *size)  # warm-up: shaders compiled
                seconds[path] = []
                for repeat in range(repeats):
                    before = (RoundTrips.read_back_bytes, RoundTrips.upload_bytes)
                    frame = renderer.render(description, settings, *size)
                    seconds[path].append(frame.timings.get(vpl_culling.EXTRACTION.name, 0.0))
                    if repeat == 0:
                        traffic[path] = (RoundTrips.read_back_bytes - before[0], RoundTrips.upload_bytes - before[1])
                        frames[path] = frame
                        vpls = frame.counts.get("vpls")
            finally:
                renderer.free()
    finally:
        vpl_culling.extract_vpls = original
    differences = {}
    for image in IMAGES:
        cpu, gpu = getattr(frames["cpu"], image), getattr(frames["gpu"], image)
        if cpu is None:
            continue
        cpu, gpu = np.asarray(cpu, np.float64)[..., :3], np.asarray(gpu, np.float64)[..., :3]
        largest = float(np.abs(gpu - cpu).max())
        differences[image] = {"max_abs": largest, "max_rel": largest / max(float(np.abs(cpu).max()), 1e-30)}
    return {"scene": name, "vpls": vpls, "size": list(size), "rsm_size": settings.rsm_size, "differences": differences,
            "cpu_read_back_bytes": traffic["cpu"][0], "gpu_read_back_bytes": traffic["gpu"][0],
            "cpu_upload_bytes": traffic["cpu"][1], "gpu_upload_bytes": traffic["gpu"][1],
            "cpu_vpl_step_ms": 1e3 * statistics.median(seconds["cpu"]),
            "gpu_vpl_step_ms": 1e3 * statistics.median(seconds["gpu"])}


def markdown(rows, command: str) -> str:
    lines = ["# VPL shadows' clusters: GPU against the CPU path it replaced", "",
             f"`{command}`: one frame per path after a warm-up frame, each scene's saved settings (VPL "
             "shadows on). Largest difference over every image (direct, "
             "indirect diffuse and specular, caustics), absolute and relative to that image's largest value.", "",
             "| scene | RSM | VPLs | max abs diff | max rel diff | read back per frame CPU → GPU (bytes, its images included) "
             "| uploaded CPU → GPU (bytes) "
             "| VPL step CPU → GPU (ms, median) |", "|---|---|---|---|---|---|---|---|"]
    for row in rows:
        worst = max(row["differences"].values(), key=lambda d: d["max_rel"])
        largest = max(d["max_abs"] for d in row["differences"].values())
        lines.append(f"| {row['scene']} | {row['rsm_size']}² | {row['vpls']} | {largest:.3g} | {worst['max_rel']:.3g} "
                     f"| {row['cpu_read_back_bytes']} → {row['gpu_read_back_bytes']} "
                     f"| {row['cpu_upload_bytes']} → {row['gpu_upload_bytes']} "
                     f"| {row['cpu_vpl_step_ms']:.0f} → {row['gpu_vpl_step_ms']:.0f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="+", default=["caustic_panel", "demo"])
    parser.add_argument("--size", default="240x180")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rsm-size", type=int, default=None)
    parser.add_argument("--output", default="vpl_clusters")
    arguments = parser.parse_args(argv)
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    register()
    size = tuple(int(v) for v in arguments.size.lower().split("x"))
    rows = [measure(name, size, arguments.repeats, arguments.rsm_size) for name in arguments.scenes]
    command = "  ".join(["benchmarks/vpl_clusters.py", *(argv if argv is not None else sys.argv[1:])]).strip()
    text = markdown(rows, f".venv/bin/python {command}")
    print(text)
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{arguments.output}.json").write_text(json.dumps(rows, indent=2))
    (RESULTS / f"{arguments.output}.md").write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
