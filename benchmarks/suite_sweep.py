# SPDX-License-Identifier: GPL-3.0-or-later
"""The harness of the validation-suite sweeps (not a test): one setting of the renderer changed,
value by value, per scene of benchmarks/validation_suite.py (its scenes, settings, 240x180 and cached
Cycles truths), over seeds, against the truth.

A sweep's column is visibility on at one value, the second of two frames (the first compiles the
shaders of that value): mean ours / Cycles, noise-corrected and robust relative RMSE
(validation_suite.frame_errors), each the mean over frames of the seeds with its range. The first
column, visibility off, is the same for every value. Used by benchmarks/shadow_origin_offsets.py and
benchmarks/ism_lookup_bias.py.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from build_validation_scenes import RESOLUTION  # noqa: E402
from validation_suite import frame_errors, scene_with_truth, suite  # noqa: E402

RESULTS = REPO / "benchmarks" / "results"
KEYS = ("mean_ratio", "rel", "rel_robust")
#: Prefix of the per-material mean ratios (``regions=True``), followed by the material's name.
REGION = "mean_ratio "


def over_seeds(figures: list[dict]) -> dict:
    """Each of KEYS' mean over the seeds' figures, and its range (``KEY_range``)."""
    return {key: float(np.mean([f[key] for f in figures])) for key in KEYS} | {
        f"{key}_range": float(np.ptp([f[key] for f in figures])) for key in KEYS}


def measure_scene(name: str, path: Path, width: int, height: int, seeds, values: Iterable, *, field: str,
                  key: Callable, label: Callable, apply: Callable, restore: Callable,
                  regions: bool = False) -> dict:
    """One scene's row: ``off`` (visibility off) and ``field`` {key(value): cell} after apply(value),
    each cell over_seeds of its frames; restore() after the last value, also on failure. ``seeds``:
    None or empty, the scene's saved seed. ``regions``: each cell also has the mean ratio of every
    material (``REGION + material``, the mean over the seeds, tradeoff.metrics.Errors.by_region)."""
    from vsgl_addon.renderer import FrameRenderer

    settings, truth, description = scene_with_truth(name, path, width, height)
    if regions:
        from tradeoff.bench import Bench
        from tradeoff.metrics import Errors

        bench = Bench(description, width, height)
        material_index, materials = bench.material_index, bench.materials
        bench.free()
    renderer = FrameRenderer()
    seeds = [settings.seed] if not seeds else list(seeds)
    row = {"scene": name, "settings": str(settings), "seeds": seeds, field: {}}

    def figures(visibility: bool) -> dict:
        measured = []
        for seed in seeds:
            for _ in range(2):
                frame = renderer.render(description, settings.overridden(visibility=visibility, seed=seed),
                                        width, height)
            both, ours = frame_errors(truth, frame)
            measured.append({k: both[k] for k in KEYS})
            if regions:
                by_region = Errors(truth, frame.coverage).by_region(ours, material_index, materials)
                measured[-1] |= {REGION + m: r["mean_ratio"] for m, r in by_region.items()}
        cell = over_seeds(measured)
        if regions:
            cell |= {k: float(np.mean([f[k] for f in measured])) for k in measured[0] if k.startswith(REGION)}
        return cell

    try:
        row["off"] = figures(False)
        for value in values:
            apply(value)
            row[field][key(value)] = cell = figures(True)
            print(f"{name} {label(value)}: mean {cell['mean_ratio']:.3f}, rel {cell['rel']:.3f}, "
                  f"robust {cell['rel_robust']:.3f}" + ("; " + ", ".join(
                      f"{k[len(REGION):]} {v:.3f}" for k, v in cell.items() if k.startswith(REGION))
                      if regions else ""), flush=True)
    finally:
        restore()
        renderer.free()
    return row


def several_seeds(rows: list[dict]) -> bool:
    return any(len(r["seeds"]) > 1 for r in rows)


def seeds_sentence(rows: list[dict]) -> str:
    """The sentence (with its leading space) that says the cells are means over seeds, or ''."""
    if not several_seeds(rows):
        return ""
    return (" Over seeds " + ", ".join(str(k) for k in rows[0]["seeds"])
            + ": each figure their mean, ± half its range over them.")


def table(rows: list[dict], field: str, keys: list[str], heads: list[str]) -> list[str]:
    """The markdown table's lines: a row a scene, its off cell and its ``field`` cells of ``keys``
    (headed ``heads``); a cell "mean / rel (robust)", with ± half the range over several seeds."""
    several = several_seeds(rows)
    lines = ["| scene | off | " + " | ".join(heads) + " |", "|---|---|" + "---|" * len(keys)]
    for r in rows:
        cells = [r["off"]] + [r[field][k] for k in keys]
        lines.append(f"| {r['scene']} | " + " | ".join(
            " / ".join(f"{c[k]:.3f}" + (f" ± {c[k + '_range'] / 2:.3f}" if several else "")
                       for k in KEYS[:2]) + f" ({c['rel_robust']:.3f})" for c in cells) + " |")
    return lines


def markdown(script: str, title: str, command: str, seconds: float, legend: str, rows: list[dict], field: str,
             keys: list[str], heads: list[str]) -> str:
    """The results page of benchmarks/``script``: title, the command line and run time, what a cell is
    (continued by ``legend``: the settings of the columns), the seeds sentence, the table."""
    lines = [f"# {title}", "",
             f"`{command}`; run {seconds:.0f} s. The module documentation of `benchmarks/{script}` says what is "
             "measured. Each cell: mean indirect ours / Cycles, noise-corrected relative RMSE (robust relative "
             "RMSE), the scene's saved settings" + legend + seeds_sentence(rows), "", *table(rows, field, keys, heads)]
    return "\n".join(lines) + "\n"


def add_common_arguments(parser, output: str) -> None:
    """--only, --seeds and --output (default ``output``)."""
    parser.add_argument("--only", nargs="+", help="only these scenes of the validation suite")
    parser.add_argument("--seeds", nargs="+", type=int, help="seeds to average over (default: the scene's)")
    parser.add_argument("--output", default=output, help="results file name, without suffix")


def command_line(script: str, values_flag: str, values: list[str], args) -> str:
    """The command that reproduces the run (--output left out: it names the file the command is in)."""
    command = f".venv/bin/python benchmarks/{script} " + " ".join(
        [values_flag] + list(values) + (["--only"] + args.only if args.only else [])
        + (["--seeds"] + [str(k) for k in args.seeds] if args.seeds else []))
    return command.strip()


def write(output: str, rows: list[dict], text: str) -> None:
    """benchmarks/results/OUTPUT.md and .json (an absolute ``output`` writes there instead)."""
    (RESULTS / f"{output}.md").write_text(text)
    (RESULTS / f"{output}.json").write_text(json.dumps(rows, indent=1, default=str))


def run(args, measure: Callable, page: Callable) -> int:
    """Measure every scene of the suite (``args.only`` of them) with ``measure(name, path, width,
    height, seeds)``, write ``page(rows, seconds)`` and the rows as ``args.output``, print the page."""
    started = time.perf_counter()
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    ensure_gpu_context()
    width, height = RESOLUTION
    rows = [measure(name, path, width, height, args.seeds)
            for name, path, _ in suite() if not args.only or name in args.only]
    text = page(rows, time.perf_counter() - started)
    write(args.output, rows, text)
    print(text)
    return 0
