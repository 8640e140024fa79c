# SPDX-License-Identifier: GPL-3.0-or-later
"""The glossy VPLs' extraction from the RSM on the GPU against the read-back path it replaced, in one
run (not a test).

    .venv/bin/python benchmarks/vpl_extraction.py [--sizes 64 128 256 512] [--repeats 5]

For the demo scene (demo.blend: a spot light, a polished floor whose texels are glossy VPLs), per RSM
size: the extraction step as the light passes run it (the RSM views seen by diffuse rays rendered,
then turned into the culling table), GPU finished, median of the repeats:

* CPU: passes/vpl_culling.py scene_vpls (the views' three slots read back, the float64 twin
  reference.vpl_culling.extract_glossy_vpls) and upload_vpls (the table uploaded);
* GPU: extract_vpls (the compaction of glsl/vpl_culling/vpl_extract*.comp.glsl, nothing read back);

and the same without the RSM rendering both share (the extraction stage alone, one view), with the
bytes each path reads back and uploads. Times are wall-clock on a shared 2-core llvmpipe machine:
read the ratios, measured in the same run. Writes benchmarks/results/vpl_extraction.{md,json}.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

RESULTS = REPO / "benchmarks" / "results"


def _timed(function, repeats):
    seconds = []
    for _ in range(repeats):
        started = time.perf_counter()
        function()
        seconds.append(time.perf_counter() - started)
    return statistics.median(seconds)


def _bytes(function):
    from vsgl_addon.passes.gpu_util import RoundTrips

    read, uploaded = RoundTrips.read_back_bytes, RoundTrips.upload_bytes
    function()
    return RoundTrips.read_back_bytes - read, RoundTrips.upload_bytes - uploaded


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="*", default=[64, 128, 256, 512])
    parser.add_argument("--repeats", type=int, default=5)
    arguments = parser.parse_args(argv)

    import bpy

    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.passes import vpl_culling
    from vsgl_addon.passes.gpu_util import finish, read_texture
    from vsgl_addon.passes.rsm import render_rsm_views
    from vsgl_addon.passes.scene_gpu import SceneGPU
    from vsgl_addon.reference import vpl_culling as reference
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    ensure_gpu_context()
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"), load_ui=False)
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    alpha_c = VSGLSettings().caustic_roughness
    scene_gpu = SceneGPU(description)
    light_index = next(i for i, light in enumerate(description.lights)
                       if render_rsm_views(scene_gpu, i, 1, "diffuse"))
    light = description.lights[light_index]
    rows = []
    try:
        for size in arguments.sizes:
            def cpu():
                vpl_set = vpl_culling.upload_vpls(vpl_culling.scene_vpls(scene_gpu, size, alpha_c))
                finish(vpl_set.table)
                return vpl_set

            def gpu():
                vpl_set = vpl_culling.extract_vpls(scene_gpu, size, alpha_c)
                finish(vpl_set.table)
                return vpl_set

            view = render_rsm_views(scene_gpu, light_index, size, "diffuse")[0]
            finish(view.textures["position"])

            def cpu_stage():
                slots = [read_texture(view.textures[name], size, size) for name in vpl_culling.EXTRACTION_SLOTS]
                records, _ = reference.extract_glossy_vpls(*slots, reference.light_vector(light), alpha_c)
                vpl_set = vpl_culling.upload_vpls(vpl_culling._records_to_vpls(records))
                finish(vpl_set.table)

            def gpu_stage():
                vpl_set = vpl_culling.empty_vpl_set(size * size)
                vpl_culling.extract_view(vpl_set, view.textures, size, reference.light_vector(light), alpha_c)
                finish(vpl_set.table)

            count = gpu().count  # warm-up: shaders compiled
            cpu()
            row = {"rsm_size": size, "vpls": count, "cpu_seconds": _timed(cpu, arguments.repeats),
                   "gpu_seconds": _timed(gpu, arguments.repeats),
                   "cpu_stage_seconds": _timed(cpu_stage, arguments.repeats),
                   "gpu_stage_seconds": _timed(gpu_stage, arguments.repeats)}
            row["cpu_read_back_bytes"], row["cpu_upload_bytes"] = _bytes(cpu)
            row["gpu_read_back_bytes"], row["gpu_upload_bytes"] = _bytes(gpu)
            view.free()
            rows.append(row)
            print(row, flush=True)
    finally:
        scene_gpu.free()

    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "vpl_extraction.json").write_text(json.dumps(rows, indent=2))
    lines = ["# Glossy VPL extraction: GPU against read-back", "",
             f"demo.blend, α_c {alpha_c:g}, llvmpipe (shared 2-core machine), median of {arguments.repeats}; "
             "times in ms, GPU finished. Step: RSM views rendered + VPL table made (what the light passes "
             "run); stage: the table from one rendered view. Bytes: read back / uploaded by the step.", "",
             "| RSM | VPLs | step CPU | step GPU | GPU / CPU | stage CPU | stage GPU | GPU / CPU "
             "| CPU read back / uploaded | GPU read back / uploaded |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['rsm_size']}² | {r['vpls']} | {r['cpu_seconds'] * 1e3:.1f} | {r['gpu_seconds'] * 1e3:.1f} "
            f"| {r['gpu_seconds'] / r['cpu_seconds']:.2f} | {r['cpu_stage_seconds'] * 1e3:.1f} "
            f"| {r['gpu_stage_seconds'] * 1e3:.1f} | {r['gpu_stage_seconds'] / r['cpu_stage_seconds']:.2f} "
            f"| {r['cpu_read_back_bytes']} / {r['cpu_upload_bytes']} | {r['gpu_read_back_bytes']} / {r['gpu_upload_bytes']} |")
    (RESULTS / "vpl_extraction.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
