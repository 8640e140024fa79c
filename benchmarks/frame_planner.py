# SPDX-License-Identifier: GPL-3.0-or-later
"""Many lights under the frame planner: VSGLs in total and frame time against one light's (not a test).

    .venv/bin/python benchmarks/frame_planner.py [--rounds R] [--resolution WxH] [--results-dir DIR]

The planner (vsgl_addon/planner.py) makes N the frame's VSGL budget, shared among the lights by
bounce power. On benchmarks/scenes/many_lights.blend (24 point lights; tools/build_validation_scenes.py)
and on a 32-light variant of it (8 more point lights in a row at mid height, built here in memory),
this renders the scene's saved settings (N = 256, visibility on) and the same scene with only one of
its lights (the same N), each variant in turn for ``--rounds`` rounds after a warm-up frame, and
reports per variant the VSGLs in total, the median frame time (the sum of the timed passes, GPU
finished) and its ratio to the one-light frame's in the same run. Targets: VSGLs ≤ N, and the
ratio ≤ 3. Then the 24-light scene's accuracy against its cached Cycles truth
(benchmarks/reference/many_lights_indirect_240x180.npz, as benchmarks/validation_suite.py measures
it) at each N of ``--accuracy-counts``: what the frame budget costs in error, and which N matches
the error of N VSGLs per light (the add-on before the planner: 24 × 256 = 6144 VSGLs, mean ratio
0.718, relative RMSE 0.320 with visibility in the committed suite results). Writes
``frame_planner.{md,json}`` to the results folder and prints the markdown.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tools", REPO / "tests", REPO / "benchmarks"):
    sys.path.insert(0, str(folder))

SCENE = REPO / "benchmarks" / "scenes" / "many_lights.blend"
RESULTS_DIR = REPO / "benchmarks" / "results"
ONE_LIGHT = "Point 07"  # a light in the middle of the grid, 2.5 m up
TARGET_RATIO = 3.0


def _extra_lights(scene, count: int = 8) -> None:
    """``count`` more small point lights, one row at 1.2 m across the room (between the grid's rows)."""
    import bpy

    palette = [(1.0, 0.85, 0.7), (0.7, 0.8, 1.0), (1.0, 0.7, 0.7), (0.75, 1.0, 0.75)]
    for index in range(count):
        data = bpy.data.lights.new(f"Extra {index:02d}", type="POINT")
        data.energy = 12.0
        data.color = palette[index % len(palette)]
        data.shadow_soft_size = 0.0
        light = bpy.data.objects.new(f"Extra {index:02d}", data)
        scene.collection.objects.link(light)
        light.location = (-3.5 + 1.0 * index, -1.4, 1.2)


def descriptions() -> tuple[dict, object]:
    """{variant name: SceneDescription}, and the scene's saved settings."""
    import bpy

    from vsgl_addon import register
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    register()
    bpy.ops.wm.open_mainfile(filepath=str(SCENE), load_ui=False)
    scene = bpy.context.scene
    settings = VSGLSettings.from_properties(scene.vsgl)
    result = {"24 lights": extract_scene(bpy.context.evaluated_depsgraph_get())}
    _extra_lights(scene)
    result["32 lights"] = extract_scene(bpy.context.evaluated_depsgraph_get())
    for obj in list(scene.objects):
        if obj.type == "LIGHT" and obj.name != ONE_LIGHT:
            bpy.data.objects.remove(obj)
    result["1 light"] = extract_scene(bpy.context.evaluated_depsgraph_get())
    return result, settings


def measure(rounds: int, width: int, height: int) -> dict:
    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.renderer import FrameRenderer

    variants, settings = descriptions()
    renderer_name = ensure_gpu_context()
    renderer = FrameRenderer()
    rows = {name: {"frames": [], "walls": []} for name in variants}
    try:
        for name, description in variants.items():  # warm-up: shaders compiled, llvmpipe warm
            renderer.render(description, settings, width, height)
        for _ in range(rounds):
            for name, description in variants.items():
                start = time.perf_counter()
                frame = renderer.render(description, settings, width, height)
                rows[name]["walls"].append(time.perf_counter() - start)
                rows[name]["frames"].append(float(sum(frame.timings.values())))
                rows[name].update(lights=len(description.lights), counts=dict(frame.counts),
                                  timings={k: float(v) for k, v in frame.timings.items()},
                                  plan=frame.plan.to_dict())
    finally:
        renderer.free()
    one = statistics.median(rows["1 light"]["frames"])
    for row in rows.values():
        row["frame_seconds"] = statistics.median(row["frames"])
        row["ratio_to_one_light"] = row["frame_seconds"] / one
        row["vsgls"] = row["counts"]["vsgls"]
    return {"renderer": renderer_name, "resolution": [width, height], "rounds": rounds,
            "settings": settings.__dict__.copy(), "variants": rows}


def accuracy(counts, width: int, height: int) -> list[dict]:
    """Mean ratio and noise-corrected relative RMSE of many_lights' indirect light against Cycles
    at each N (visibility on, the scene's other settings), with the frame's VSGLs and time."""
    import bpy
    import numpy as np

    from tradeoff.metrics import Errors
    from tradeoff.truth import load_reference
    from validation_suite import TRUTH_SAMPLES
    from vsgl_addon.renderer import FrameRenderer
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    bpy.ops.wm.open_mainfile(filepath=str(SCENE), load_ui=False)
    scene = bpy.context.scene
    settings = VSGLSettings.from_properties(scene.vsgl)
    truth = load_reference(scene, width, height, TRUTH_SAMPLES["many_lights"], False, name="many_lights",
                           source=SCENE, dtype=np.float16)
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    renderer = FrameRenderer()
    rows = []
    try:
        for count in counts:
            for shadowed in (False, True):
                frame = renderer.render(description, settings.overridden(vsgl_count=count, visibility=shadowed),
                                        width, height)
                errors = Errors(truth, frame.coverage)(frame.indirect_diffuse, frame.indirect_specular)
                rows.append({"vsgl_count": count, "visibility": shadowed, "vsgls": frame.counts["vsgls"],
                             "mean_ratio": errors["mean_ratio"], "rel": errors["rel"],
                             "frame_seconds": float(sum(frame.timings.values()))})
    finally:
        renderer.free()
    return rows


def markdown(results: dict) -> str:
    width, height = results["resolution"]
    n = results["settings"]["vsgl_count"]
    lines = ["# Frame planner: many lights against one", "",
             f"`.venv/bin/python benchmarks/frame_planner.py --rounds {results['rounds']}`; many_lights.blend's "
             f"saved settings (N = {n}, RSM {results['settings']['rsm_size']}², visibility "
             f"{'on' if results['settings']['visibility'] else 'off'}), {width}×{height}, GPU: {results['renderer']}. "
             f"Frame: median over {results['rounds']} rounds of the timed passes' sum; the variants alternate "
             "within each round, so the machine's load hits them alike. Targets: VSGLs ≤ N, frame ≤ "
             f"{TARGET_RATIO:g}× the one-light frame's.", "",
             "| variant | lights | RSM views | VSGLs | VSGLs ≤ N | frame ms | × one light | target met | "
             "RSM + generation ms | ISM ms | direct ms | shading ms |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, row in results["variants"].items():
        t = row["timings"]
        lines.append(f"| {name} | {row['lights']} | {row['counts'].get('rsm_views', 0)} | {row['vsgls']} | "
                     f"{'yes' if row['vsgls'] <= n else 'no'} | {row['frame_seconds'] * 1e3:.0f} | "
                     f"{row['ratio_to_one_light']:.2f} | {'yes' if row['ratio_to_one_light'] <= TARGET_RATIO else 'no'} | "
                     f"{t.get('rsm_and_vsgl_generation', 0) * 1e3:.0f} | {t.get('ism', 0) * 1e3:.0f} | "
                     f"{t.get('direct_light', 0) * 1e3:.0f} | {t.get('vsgl_shading', 0) * 1e3:.0f} |")
    if results.get("accuracy"):
        lines += ["", "many_lights (24 lights) against its Cycles truth at each frame budget N (noise-corrected "
                  "relative RMSE; frame time informative, the machine is shared). Before the planner (N per "
                  "light, 6144 VSGLs): mean 0.799 / 0.718 and rel RMSE 0.238 / 0.320 with visibility off / on "
                  "(benchmarks/results/validation_suite.json).", "",
                  "| N | visibility | VSGLs | mean ours / Cycles | rel RMSE | frame ms |", "|---|---|---|---|---|---|"]
        for row in results["accuracy"]:
            lines.append(f"| {row['vsgl_count']} | {'on' if row['visibility'] else 'off'} | {row['vsgls']} | "
                         f"{row['mean_ratio']:.3f} | {row['rel']:.3f} | {row['frame_seconds'] * 1e3:.0f} |")
    plan = results["variants"]["32 lights"]["plan"]
    lines += ["", "The 32-light frame's plan (its summary lines):", ""]
    lines += [f"    {line}" for line in plan["summary"]]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--resolution", default="240x180", help="WxH (default: the suite's 240x180)")
    parser.add_argument("--results-dir", type=Path, default=RESULTS_DIR)
    parser.add_argument("--accuracy-counts", type=int, nargs="*", default=[256, 1024, 4096],
                        help="frame budgets N at which many_lights is compared with Cycles (none: skip)")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.resolution.lower().split("x"))
    results = measure(args.rounds, width, height)
    if args.accuracy_counts:
        results["accuracy"] = accuracy(args.accuracy_counts, width, height)
    text = markdown(results)
    args.results_dir.mkdir(parents=True, exist_ok=True)
    (args.results_dir / "frame_planner.md").write_text(text, encoding="utf-8")
    (args.results_dir / "frame_planner.json").write_text(json.dumps(results, indent=2, sort_keys=True),
                                                          encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
