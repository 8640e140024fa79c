# SPDX-License-Identifier: GPL-3.0-or-later
"""What the maps that keep their surfaces cost when every light's maps do (not a test): the maps'
build (pipeline.build_visibility) with pipeline.SURFACE_LIGHT_TYPES and the surface splats' cap
(reference.ism.SURFACE_SPLAT_MAX_RADIUS) per VARIANTS, alternating in one run.

    .venv/bin/python benchmarks/ism_surface_types_cost.py [--only NAME ...] [--repeats R]

Per scene of the validation suite (its settings, visibility on, one RSM view's VSGLs): the median
over ``repeats`` builds (after a warm-up each) of the process CPU time (llvmpipe's threads are the
process's: the work, which the shared machine's load does not inflate as it does the wall clock)
and of the wall time of the stages (timed: the GPU waited for after each), per variant. Writes
``benchmarks/results/ism_surface_types_cost.md`` and prints it.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from validation_suite import scene_with_truth, suite  # noqa: E402
from build_validation_scenes import RESOLUTION  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402

#: label: (pipeline.SURFACE_LIGHT_TYPES, reference.ism.SURFACE_SPLAT_MAX_RADIUS).
VARIANTS = {"sun only, cap 8 (before)": (("SUN",), 8), "every light, cap 8": (("POINT", "SPOT", "SUN", "AREA"), 8),
            "every light, cap 12": (("POINT", "SPOT", "SUN", "AREA"), 12)}


def measure(name, path, repeats):
    from vsgl_addon import pipeline
    from vsgl_addon.reference import ism

    saved_types, saved_cap = pipeline.SURFACE_LIGHT_TYPES, ism.SURFACE_SPLAT_MAX_RADIUS
    saved, _, description = scene_with_truth(name, path, *RESOLUTION)
    settings = saved.overridden(visibility=True)
    bench = Bench(description, *RESOLUTION)
    cpu = {key: [] for key in VARIANTS}
    stages = {key: [] for key in VARIANTS}
    try:
        vsgls, _ = bench.vsgls(settings)
        try:
            for k in range(repeats + 1):
                for key, (types, cap) in VARIANTS.items():
                    pipeline.SURFACE_LIGHT_TYPES, ism.SURFACE_SPLAT_MAX_RADIUS = types, cap
                    for atlas in vsgls.isms:
                        atlas.free()
                    vsgls.isms.clear()
                    clock = time.process_time()
                    pipeline.build_visibility(bench.scene_gpu, vsgls, settings, timed=True)
                    seconds = time.process_time() - clock
                    if k:  # the first built the point sets and compiled
                        cpu[key].append(seconds)
                        split = {}
                        for atlas in vsgls.isms:
                            for stage, value in atlas.seconds.items():
                                split[stage] = split.get(stage, 0.0) + value
                        stages[key].append(split)
        finally:
            vsgls.free()
            pipeline.SURFACE_LIGHT_TYPES, ism.SURFACE_SPLAT_MAX_RADIUS = saved_types, saved_cap
    finally:
        bench.free()
    return {key: {"cpu": statistics.median(cpu[key]),
                  "stages": {s: statistics.median(x[s] for x in stages[key]) for s in stages[key][0]}}
            for key in VARIANTS}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["many_lights", "demo"])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    ensure_gpu_context()
    command = ".venv/bin/python benchmarks/ism_surface_types_cost.py " + " ".join(sys.argv[1:] if argv is None else argv)
    scenes = {n: p for n, p, _ in suite()}
    lines = ["# The maps' build with every light's maps keeping their surfaces", "", f"`{command}`", "",
             "The module documentation of `benchmarks/ism_surface_types_cost.py` defines every figure "
             "(medians; machine shared with other jobs: the CPU-time ratio is the figure).", "",
             "| scene | variant | CPU s | / before | splat ms | close ms | pull-push ms |", "|---|---|---|---|---|---|---|"]
    for name in args.only:
        rows = measure(name, scenes[name], args.repeats)
        base = rows["sun only, cap 8 (before)"]["cpu"]
        for key, row in rows.items():
            s = row["stages"]
            lines.append(f"| {name} | {key} | {row['cpu']:.3f} | {row['cpu'] / base:.3f} | "
                         f"{1e3 * s.get('splat', 0):.0f} | {1e3 * s.get('close', 0):.0f} | {1e3 * s.get('pull_push', 0):.0f} |")
    text = "\n".join(lines) + "\n"
    (REPO / "benchmarks" / "results" / "ism_surface_types_cost.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
