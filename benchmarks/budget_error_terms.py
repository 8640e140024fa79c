# SPDX-License-Identifier: GPL-3.0-or-later
"""The error terms Budget mode trades against time (vsgl_addon/budget.py ERROR_WEIGHTS), measured
per scene of the validation suite and fitted across it (not a test).

    .venv/bin/python benchmarks/budget_error_terms.py [--only NAME ...] [--results-dir DIR]

Budget's path (budget.path) raises, step by step, the parameter with the largest fall of predicted
error per predicted second; only the terms' ratios matter to it. Per scene (240x180, its cached
Cycles one-bounce truth, validation_suite.py's noise-corrected relative RMSE over the base frame's
covered pixels), with the passes Budget runs there (the scene's plan in Budget mode, held fixed over
the grid), one parameter at a time is moved from a base (N = 256, RSM 128², δ = 10⁻³, interleave
2×2, scale 1): N 64 / 128 / 512 / 1024, RSM 32² / 64² / 256², scale 0.5 / 0.75 and, where the VPL
pass runs, δ 10⁻² / 10⁻⁴ and interleave 1 / 4. Each scene's errors are divided by its base error
(its terms' ratios are what its path compares), and per term its slope is fitted through the base
over the points where only that term moved:

    error / base error − 1 = w · (f(point) − f(base)),
    f: 1/√N, 1/R, I/√(listed(δ)/listed(10⁻³)), 1/scale − 1

Each term's weight is the median of the scenes' slopes (robust to the few scenes where a term is
all that matters), in budget.py's units (its VSGL weight 4 over the median VSGL slope). The RSM
slope is also split by what the texels are to the frame: scenes with an orthographic (sun) RSM
view ("rsm_orthographic"), scenes running the VPL pass without one ("rsm_vpls"), and the rest
("rsm_local"); "rsm" is every scene's, budget.py's one RSM weight. Writes
``benchmarks/results/budget_error_terms.{md,json}``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from build_validation_scenes import RESOLUTION  # noqa: E402
from checkout_ab import write_results  # noqa: E402
from validation_suite import budget_scene, measure_suite  # noqa: E402
from tradeoff.demo import log  # noqa: E402
from tradeoff.metrics import Errors  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
BASE = {"vsgl_count": 256, "rsm_size": 128, "delta": 1e-3, "vpl_interleave": "2", "scale": 1.0}
GRID = {"vsgl_count": (64, 128, 512, 1024), "rsm_size": (32, 64, 256), "scale": (0.5, 0.75)}
VPL_GRID = {"delta": (1e-2, 1e-4), "vpl_interleave": ("1", "4")}
TERMS = ("vsgls", "rsm", "vpls", "scale")


def features(point: dict, vpl_pass: bool) -> list[float]:
    from vsgl_addon.budget import delta_listed

    vpls = (int(point["vpl_interleave"]) / math.sqrt(delta_listed(point["delta"]) / delta_listed(1e-3))
            if vpl_pass else 0.0)
    return [1.0 / math.sqrt(point["vsgl_count"]), 1.0 / point["rsm_size"], vpls, 1.0 / point["scale"] - 1.0]


def measure_scene(name, path) -> dict:
    from vsgl_addon.budget import Candidate, scaled_size
    from vsgl_addon.budget_render import _render
    from vsgl_addon.renderer import FrameRenderer

    width, height = RESOLUTION
    # The passes Budget runs here, held fixed over the grid.
    _, truth, description, plan, fixed = budget_scene(name, path)
    vpl_pass = plan.runs("vpl_pass")
    points = [dict(BASE)]
    for grid in (GRID, VPL_GRID) if vpl_pass else (GRID,):
        for key, values in grid.items():
            points += [dict(BASE, **{key: value}) for value in values]
    renderer = FrameRenderer()
    rows = []
    try:
        check = None
        for index, point in enumerate([points[0], *points]):  # the first frame warms up
            candidate = Candidate(**point)
            images = _render(renderer, description, candidate.apply(fixed), scaled_size(width, height, point["scale"]),
                             (width, height), None)
            if check is None:
                check = Errors(truth, images.coverage)
            if index == 0:
                continue
            rel = float(check(images.indirect_diffuse, images.indirect_specular)["rel"])
            rows.append({**point, "rel": rel})
            log(f"{name}: {point} rel {rel:.3f}")
    finally:
        renderer.free()
    orthographic = any(not spec.perspective for light in plan.lights if light.gets_rsm for spec in light.view_specs)
    return {"scene": name, "vpl_pass": vpl_pass, "orthographic": orthographic,
            "passes": {k: d.run for k, d in plan.decisions.items()},
            "rows": rows}


def rsm_kind(result: dict) -> str:
    """Which part of the RSM slopes a scene's belongs to (module documentation)."""
    return "rsm_orthographic" if result["orthographic"] else "rsm_vpls" if result["vpl_pass"] else "rsm_local"


def slopes(result: dict) -> dict:
    """term -> the scene's slope (module documentation); the RSM's also under rsm_kind."""
    base = result["rows"][0]
    at_base = np.asarray(features(base, result["vpl_pass"]))
    out = {}
    for k, term in enumerate(TERMS):
        moved = [(np.asarray(features(row, result["vpl_pass"])) - at_base, row["rel"] / base["rel"] - 1.0)
                 for row in result["rows"][1:]]
        moved = [(d[k], y) for d, y in moved if d[k] != 0.0 and np.count_nonzero(d) == 1]
        if moved:
            x, y = np.array([m[0] for m in moved]), np.array([m[1] for m in moved])
            out[term] = float(x @ y / (x @ x))
            if term == "rsm":
                out[rsm_kind(result)] = out[term]
    return out


def fit(results: list[dict]) -> dict:
    """weight name -> {"scenes": scene -> slope, "median": slope, "weight": in budget.py's units}."""
    per_scene = {result["scene"]: slopes(result) for result in results}
    names = ("vsgls", "rsm", "rsm_local", "rsm_orthographic", "rsm_vpls", "vpls", "scale")
    fitted = {name: {"scenes": {scene: s[name] for scene, s in per_scene.items() if name in s}} for name in names}
    for entry in fitted.values():
        entry["median"] = float(np.median(list(entry["scenes"].values()))) if entry["scenes"] else None
    from vsgl_addon.budget import ERROR_WEIGHTS

    unit = ERROR_WEIGHTS["vsgls"] / fitted["vsgls"]["median"]
    for entry in fitted.values():
        entry["weight"] = None if entry["median"] is None else max(entry["median"], 0.0) * unit
    return fitted


def markdown(results, weights, command, seconds) -> str:
    from vsgl_addon.budget import ERROR_WEIGHTS

    lines = ["# Budget's error terms, measured across the validation suite", "",
             f"`{command}`; 240x180; run {seconds:.0f} s. The module documentation of "
             "`benchmarks/budget_error_terms.py` defines the grid and the fit. Noise-corrected relative RMSE "
             "against each scene's Cycles truth; one parameter moved from the base at a time.", ""]
    columns = [("vsgl_count", v) for v in (64, 128, 256, 512, 1024)] + [
        ("rsm_size", v) for v in (32, 64, 256)] + [("scale", v) for v in (0.5, 0.75)] + [
        ("delta", v) for v in (1e-2, 1e-4)] + [("vpl_interleave", v) for v in ("1", "4")]
    heads = [f"N {v}" for v in (64, 128, 256, 512, 1024)] + [f"RSM {v}²" for v in (32, 64, 256)] + [
        f"scale {v}" for v in (0.5, 0.75)] + ["δ 1e-2", "δ 1e-4", "interleave 1", "interleave 4"]
    lines += ["| scene | VPL pass | " + " | ".join(heads) + " |", "|---|---|" + "---|" * len(heads)]
    for result in results:
        cells = []
        for key, value in columns:
            match = [r["rel"] for r in result["rows"] if r[key] == value
                     and all(r[k] == BASE[k] for k in BASE if k != key)]
            cells.append(f"{match[0]:.3f}" if match else "")
        lines.append(f"| {result['scene']} | {'yes' if result['vpl_pass'] else 'no'} | " + " | ".join(cells) + " |")
    lines += ["", "Slopes per scene (error over the scene's base error, per unit of the term's feature), their "
              "median, and that median in budget.py's units (× its VSGL weight over the VSGL median), against "
              "budget.py's ERROR_WEIGHTS when this ran:", "",
              "| weight | slopes per scene | median | → budget.py's units | budget.py |", "|---|---|---|---|---|"]
    for name, entry in weights.items():
        scenes = ", ".join(f"{scene} {slope:.3g}" for scene, slope in entry["scenes"].items())
        median = "" if entry["median"] is None else f"{entry['median']:.3g}"
        weight = "" if entry["weight"] is None else f"{entry['weight']:.3g}"
        lines.append(f"| {name} | {scenes} | {median} | {weight} | {ERROR_WEIGHTS.get(name, '')} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+")
    parser.add_argument("--results-dir", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    started = time.perf_counter()
    results = measure_suite(measure_scene, args.only)
    weights = fit(results)
    command = "benchmarks/budget_error_terms.py" + (f" --only {' '.join(args.only)}" if args.only else "")
    text = markdown(results, weights, f".venv/bin/python {command}", time.perf_counter() - started)
    write_results("budget_error_terms", {"results": results, "weights": weights}, text, args.results_dir)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
