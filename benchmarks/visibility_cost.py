# SPDX-License-Identifier: GPL-3.0-or-later
"""What VSGL visibility costs (not a test): frame time with imperfect shadow maps off and on, and the
split between splat, gap closing, pull-push and lookups, as ratios within one run.

    .venv/bin/python benchmarks/visibility_cost.py [--scene NAME] [--n N ...] [--repeats R]

At 480x360, RSM 128² (the cost target's setting) and each N: the median over ``repeats`` frames
(after a warm-up; off and on alternating) of the frame's passes with visibility off and on
(FrameRenderer timings); then
the maps alone again with the GPU waited for after each stage (build_visibility(timed=True)), and
the lookups as shading on − shading off. The frames' process CPU time too (llvmpipe's threads are
the process's: the work done, which a shared machine's load does not inflate as it does the wall
clock), whose on / off ratio − 1 is the CPU-time extra. Writes ``benchmarks/results/visibility_cost.{md,json}``
(or ``--results-dir``); ``validation_suite.py`` runs it too.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from tradeoff.demo import DEMO, RESULTS_DIR, log  # noqa: E402

SIZE = (480, 360)


def measure(path: Path, counts, repeats: int = 3, rsm_size: int = 128) -> list[dict]:
    import bpy
    from vsgl_addon.pipeline import build_visibility, render_scene_vsgls
    from vsgl_addon.passes.rsm import SceneGPU
    from vsgl_addon.renderer import FrameRenderer
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    # VSGL visibility's cost alone: without the glossy VPL pass the demo's sharp floor calls for.
    base = VSGLSettings.from_properties(bpy.context.scene.vsgl).overridden(rsm_size=rsm_size, caustics=False)
    rows = []
    renderer = FrameRenderer()
    try:
        for n in counts:
            times, frames, cpu = {}, {False: [], True: []}, {False: [], True: []}
            for visibility in (False, True):  # warm-up: shaders, llvmpipe
                renderer.render(description, base.overridden(vsgl_count=n, visibility=visibility), *SIZE)
            # Off and on alternate, so that a change of the (shared) machine's load falls on both.
            for _ in range(repeats):
                for visibility in (False, True):
                    settings = base.overridden(vsgl_count=n, visibility=visibility)
                    clock = time.process_time()
                    frames[visibility].append(renderer.render(description, settings, *SIZE).timings)
                    cpu[visibility].append(time.process_time() - clock)
            for visibility, timings in frames.items():
                times[visibility] = {name: statistics.median(f.get(name, 0.0) for f in timings)
                                     for name in timings[0]}
                times[visibility]["frame"] = statistics.median(sum(f.values()) for f in timings)
            settings = base.overridden(vsgl_count=n, visibility=True)
            scene_gpu = SceneGPU(description)
            stages = []
            try:
                vsgls = render_scene_vsgls(scene_gpu, settings)
                try:
                    for _ in range(repeats + 1):
                        for atlas in vsgls.isms:
                            atlas.free()
                        vsgls.isms.clear()
                        build_visibility(scene_gpu, vsgls, settings, timed=True)
                        split = {}
                        for atlas in vsgls.isms:
                            for name, seconds in atlas.seconds.items():
                                split[name] = split.get(name, 0.0) + seconds
                        stages.append(split)
                finally:
                    vsgls.free()
            finally:
                scene_gpu.free()
            stages = stages[1:]  # the first built the point sets and compiled
            split = {name: statistics.median(s[name] for s in stages) for name in stages[0]}
            off, on = times[False], times[True]
            lookups = on["vsgl_shading"] - off["vsgl_shading"]
            row = {"n": n, "frame_off": off["frame"], "frame_on": on["frame"], "ratio": on["frame"] / off["frame"],
                   "extra": (on["ism"] + lookups) / off["frame"], "ism": on["ism"], "lookups": lookups,
                   "shading_off": off["vsgl_shading"], "shading_on": on["vsgl_shading"], "stages": split,
                   "timings_off": off, "timings_on": on, "cpu_off": statistics.median(cpu[False]),
                   "cpu_on": statistics.median(cpu[True])}
            row["extra_cpu"] = row["cpu_on"] / row["cpu_off"] - 1.0
            total = sum(split.values()) + max(lookups, 0.0)
            row["shares"] = {**{name: value / total for name, value in split.items()},
                             "lookups": max(lookups, 0.0) / total}
            log(f"N={n}: frame {off['frame'] * 1e3:.0f} -> {on['frame'] * 1e3:.0f} ms ({row['ratio']:.2f}x; "
                f"ISM + lookups {100 * row['extra']:.0f} % extra; CPU time {100 * row['extra_cpu']:.0f} %), split " +
                ", ".join(f"{k} {100 * v:.0f} %" for k, v in row["shares"].items()))
            rows.append(row)
    finally:
        renderer.free()
    return rows


def markdown(rows, scene: str, renderer: str) -> str:
    lines = [f"## Cost of VSGL visibility ({scene}, {SIZE[0]}x{SIZE[1]}, RSM 128², GPU: {renderer})", "",
             "Median frame (sum of passes) with visibility off and on, in one run; extra = (ISM pass + "
             "lookups) / frame off, lookups = shading on − shading off; CPU-time extra = the frames' process CPU "
             "time on / off − 1 (the work, not inflated by the shared machine's load); split of the visibility "
             "work (stages timed with the GPU waited for after each).", "",
             "| N | frame off ms | frame on ms | on / off | extra | CPU-time extra | ISM ms | lookups ms | splat | "
             "close | pull-push | lookups |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        s = r["shares"]
        lines.append(f"| {r['n']} | {r['frame_off'] * 1e3:.0f} | {r['frame_on'] * 1e3:.0f} | {r['ratio']:.2f} | "
                     f"{100 * r['extra']:.0f} % | {100 * r['extra_cpu']:.0f} % | {r['ism'] * 1e3:.0f} | "
                     f"{r['lookups'] * 1e3:.0f} | "
                     f"{100 * s.get('splat', 0):.0f} % | {100 * s.get('close', 0):.0f} % | "
                     f"{100 * s.get('pull_push', 0):.0f} % | {100 * s['lookups']:.0f} % |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", type=Path, default=DEMO)
    parser.add_argument("--n", type=int, nargs="+", default=[64, 256, 1024])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--results-dir", type=Path, default=RESULTS_DIR)
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    from vsgl_addon.gpu_context import ensure_gpu_context

    renderer = ensure_gpu_context()
    rows = measure(args.scene, args.n, args.repeats)
    text = markdown(rows, args.scene.name, renderer)
    args.results_dir.mkdir(parents=True, exist_ok=True)
    (args.results_dir / "visibility_cost.md").write_text(text)
    (args.results_dir / "visibility_cost.json").write_text(json.dumps(
        {"renderer": renderer, "scene": args.scene.name, "size": SIZE, "rows": rows}, indent=1, default=str))
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
