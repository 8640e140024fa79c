# SPDX-License-Identifier: GPL-3.0-or-later
"""The indirect specular layer's error against Cycles under a few setting levers (not a test).

    .venv/bin/python benchmarks/specular_levers.py [--only NAME ...] [--counts N ...]

Per scene (default: demo, polished_metal_floor, occluded_reflector), with the scene's saved
settings, one frame at 240x180 after a warm-up frame for each VSGL count N (the frame's budget per
VSGL set): indirect specular and total relative RMSE against Cycles (tradeoff.metrics.Errors, as
benchmarks/mrp_asg_suite.py) and per material the mean ours / Cycles and share of the error; the
VSGL shading time. Writes benchmarks/results/specular_levers.{md,json}.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from mrp_asg_suite import HEIGHT, WIDTH, _material_index  # noqa: E402
from tradeoff.demo import RESULTS_DIR, log  # noqa: E402
from tradeoff.metrics import Errors  # noqa: E402
from validation_suite import scene_with_truth, suite  # noqa: E402

SCENES = ("demo", "polished_metal_floor", "occluded_reflector")


def measure(name, path, counts) -> dict:
    from vsgl_addon.renderer import FrameRenderer

    settings, truth, description = scene_with_truth(name, path, WIDTH, HEIGHT)
    material_index, materials = _material_index(description)
    renderer = FrameRenderer()
    rows = []
    try:
        renderer.render(description, settings, WIDTH, HEIGHT)
        for count in counts:
            frame = renderer.render(description, settings.overridden(vsgl_count=count), WIDTH, HEIGHT)
            errors = Errors(truth, frame.coverage)
            figures = errors(frame.indirect_diffuse, frame.indirect_specular)
            regions = errors.by_region((frame.indirect_diffuse + frame.indirect_specular).astype(np.float64),
                                       material_index, materials)
            rows.append({"vsgl_count": count, "rel": figures["rel"], "rel_specular": figures["rel_specular"],
                         "vsgls": int(frame.counts["vsgls"]), "vsgl_shading_seconds": float(frame.timings["vsgl_shading"]),
                         "regions": {k: {"mean_ratio": v["mean_ratio"], "error_share": v["error_share"]}
                                     for k, v in regions.items()}})
            log(f"{name} N={count}: specular {figures['rel_specular']:.3f}, total {figures['rel']:.3f}")
    finally:
        renderer.free()
    return {"scene": name, "rows": rows}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=list(SCENES))
    parser.add_argument("--counts", nargs="+", type=int, default=[256, 1024, 4096])
    args = parser.parse_args(argv)
    from vsgl_addon import register, unregister
    from vsgl_addon.gpu_context import ensure_gpu_context

    paths = {name: path for name, path, _ in suite()}
    register()
    ensure_gpu_context()
    try:
        results = [measure(name, paths[name], args.counts) for name in args.only]
    finally:
        unregister()
    command = "benchmarks/specular_levers.py " + " ".join(sys.argv[1:] if argv is None else argv)
    lines = ["# The indirect specular layer against Cycles by VSGL count", "", f"`{command.strip()}` "
             "(the module's documentation; 240x180, the scenes' saved settings otherwise).", "",
             "| scene | N per set | VSGLs in all | indirect specular rel. RMSE | total rel. RMSE | VSGL shading (s) | per material: mean ours/Cycles (error share) |",
             "|---|---|---|---|---|---|---|"]
    for r in results:
        for row in r["rows"]:
            regions = ", ".join(f"{k} {v['mean_ratio']:.3f} ({v['error_share']:.2f})" for k, v in row["regions"].items())
            lines.append(f"| {r['scene']} | {row['vsgl_count']} | {row['vsgls']} | {row['rel_specular']:.3f} | "
                         f"{row['rel']:.3f} | {row['vsgl_shading_seconds']:.2f} | {regions} |")
    text = "\n".join(lines) + "\n"
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    (RESULTS_DIR / "specular_levers.md").write_text(text, encoding="utf-8")
    (RESULTS_DIR / "specular_levers.json").write_text(json.dumps({"command": command.strip(), "results": results},
                                                                indent=1), encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
