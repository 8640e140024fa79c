# SPDX-License-Identifier: GPL-3.0-or-later
"""The speed/accuracy trade across techniques, per scene of the validation suite (not a test).

    .venv/bin/python benchmarks/tradeoff_suite.py [--quick] [--only NAME ...] [--results-dir DIR]
        [--budgets F ...] [--repeats R] [--eevee] [--cache DIR]

Per scene of the validation suite (benchmarks/scenes/*.blend and demo.blend, 240x180, against each
scene's cached Cycles one-bounce truth in benchmarks/reference; validation_suite.py's metric: the
noise-corrected relative RMSE of the indirect light over the covered pixels of the Auto frame):

* **Manual** technique combinations, each at N = 64, 256, 1024 (RSM 128², the rest at the add-on's
  defaults): VSGLs only (visibility, MRP-ASG and the VPL pass off), + visibility, + VPLs, + MRP-ASG
  (everything on). A combination whose plan runs the same passes as the one before it on this scene
  (its cell is empty: no sharp reflector, no proxy) is not rendered again; the table says so.
  Their points make the measured Pareto front: front(t) = the lowest error of a manual setting
  measured at most t.
* **Auto**: the scene's saved settings (the add-on's defaults) in Auto quality mode: the planner
  decides the passes, and leaves out the VPL pass or MRP-ASG where its cell's share of the bounce is
  small for its predicted cost (planner.AUTO_SHARE_PER_COST); measured first and again last (its
  time: the median of both visits' frames). The manual rows and Budget keep the saved quality mode.
* **Budget** (vsgl_addon/budget.py) at targets of F × Auto's measured time (default F = 0.5, 1, 2):
  this machine's cost model, from a cache of the benchmark's own (``--cache``, a fresh temporary
  directory by default: the first scene calibrates it, as a first use does), one budgeted frame of the
  scene first (its recent frame: the scene's correction), then the measured ones.
* **Cycles** at increasing samples, from the truth's own noise: its two seeds' difference gives the
  noise of s samples, relative RMSE ν·√(2S/s) (S samples per seed, ν the mean's relative noise), and
  its recorded render time per sample; "Cycles time to equal error" is the time at the s where that
  equals our error (Cycles' bias against its own truth is nil). Its per-render overhead (scene sync,
  BVH build) is spread over the truth's samples, so at a few samples the time is a lower bound.
* **EEVEE** with ``--eevee`` (it renders headless here with llvmpipe, about a minute per 240x180 frame
  at 64 samples; off by default for that reason): its indirect = Combined − Combined with every
  indirect source off (tradeoff/baselines.eevee_runs), as saved and with ray tracing.

Times are the sum of the frame's timed passes (FrameImages.timings, GPU finished; Budget's upscale
included), the median of ``--repeats`` frames after a warm-up; this machine is shared, so they are
noisy (compare within one run).

Targets (per scene): Budget's measured frame time within 25 % of the target; its error at most 1.15 ×
front(its measured time); Auto's error at most 1.10 × front(its time), or its time at most 1.10 × the
fastest manual setting as accurate.

Writes ``benchmarks/results/tradeoff_suite.{md,json,png}`` (``_quick`` with --quick: one scene, N = 64
and 256, one budget, one repeat: the smoke test) and prints the markdown.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))

from validation_suite import open_scene, scene_with_truth, suite  # noqa: E402  (sets the paths)
from tradeoff.demo import RESULTS_DIR, log  # noqa: E402
from tradeoff.metrics import Errors  # noqa: E402

RESOLUTION = (240, 180)
COMBINATIONS = (
    ("VSGL only", {"visibility": False, "glossy_reflectors": False, "caustics": False}),
    ("+ visibility", {"visibility": True, "glossy_reflectors": False, "caustics": False}),
    ("+ VPLs", {"visibility": True, "glossy_reflectors": False, "caustics": True}),
    ("+ MRP-ASG", {"visibility": True, "glossy_reflectors": True, "caustics": True}),
)
COUNTS = (64, 256, 1024)
BUDGETS = (0.5, 1.0, 2.0)
QUICK_SCENE = "occluder"
# The targets' tolerances.
BUDGET_TIME_TOLERANCE = 0.25
BUDGET_ERROR_TOLERANCE = 0.15
AUTO_TOLERANCE = 0.10
CYCLES_SAMPLES = (1, 4, 16, 64, 256, 1024, 4096, 16384)


def _frame_seconds(images) -> float:
    return float(sum(images.timings.values()))


def _measure(render, repeats: int):
    """(median frame seconds, last FrameImages) of ``repeats`` calls of ``render``."""
    times, images = [], None
    for _ in range(repeats):
        images = render()
        times.append(_frame_seconds(images))
    return float(np.median(times)), images, times


def _row(label, settings, seconds, images, check, times, **extra) -> dict:
    figures = check(images.indirect_diffuse, images.indirect_specular)
    return {"label": label, "vsgl_count": settings.vsgl_count, "rsm_size": settings.rsm_size,
            "delta": settings.delta, "vpl_interleave": settings.vpl_interleave,
            "visibility": settings.visibility, "glossy_reflectors": settings.glossy_reflectors,
            "caustics": settings.caustics, "seconds": seconds, "times": times, "rel": figures["rel"],
            "mean_ratio": figures["mean_ratio"], "finite": figures["finite"],
            "passes": {name: decision.run for name, decision in images.plan.decisions.items()}, **extra}


def front_error(manual: list[dict], seconds: float) -> float:
    """The lowest error of a manual setting measured at most ``seconds`` (inf: none that fast)."""
    errors = [row["rel"] for row in manual if row["seconds"] <= seconds]
    return min(errors) if errors else math.inf


def front_time(manual: list[dict], error: float) -> float:
    """The shortest time of a manual setting at most ``error`` (inf: none that accurate)."""
    times = [row["seconds"] for row in manual if row["rel"] <= error]
    return min(times) if times else math.inf


def on_front(manual: list[dict], seconds: float, error: float) -> bool:
    return not any(row["seconds"] < seconds and row["rel"] < error for row in manual)


def cycles_curve(truth: dict) -> dict:
    """Cycles' error and time at increasing samples, from its truth's own noise and render time."""
    per_seed = int(truth["samples_per_seed"])
    noise = float(truth["noise_relative"])  # of the mean of two seeds: 2 × per_seed samples
    seconds_per_sample = float(np.mean(truth["seconds_per_seed"])) / per_seed
    rows = [{"samples": s, "rel": noise * math.sqrt(2 * per_seed / s), "seconds": s * seconds_per_sample}
            for s in CYCLES_SAMPLES]
    return {"samples_per_seed": per_seed, "noise_relative": noise, "seconds_per_sample": seconds_per_sample,
            "rows": rows}


def cycles_time_to(curve: dict, error: float) -> float:
    """Seconds Cycles needs for a relative RMSE of ``error`` (its noise alone, 1/√samples)."""
    if not error > 0.0:
        return math.inf
    samples = 2 * curve["samples_per_seed"] * (curve["noise_relative"] / error) ** 2
    return max(samples, 1.0) * curve["seconds_per_sample"]


def measure_scene(name, path, counts, budgets, repeats, eevee, gpu, cache):

    from vsgl_addon import budget as B
    from vsgl_addon.budget_render import model_for, render_budgeted
    from vsgl_addon.planner import plan_frame
    from vsgl_addon.renderer import FrameRenderer

    width, height = RESOLUTION
    saved, truth, description = scene_with_truth(name, path, width, height)
    auto_settings = saved.overridden(quality_mode="auto") if saved.quality_mode == "manual" else saved
    camera = description.camera
    view_projection = camera.projection_matrix() @ camera.view_matrix()
    renderer = FrameRenderer()
    started = time.perf_counter()
    try:
        renderer.render(description, auto_settings, width, height)  # warm-up: shaders, llvmpipe
        auto_seconds, auto, auto_times = _measure(lambda: renderer.render(description, auto_settings, width, height),
                                                  repeats)
        check = Errors(truth, auto.coverage)  # one set of pixels for every row of the scene
        auto_row = _row("Auto", auto_settings, auto_seconds, auto, check, auto_times)
        log(f"{name}: Auto {auto_seconds * 1e3:.0f} ms, rel RMSE {auto_row['rel']:.3f}")
        manual, skipped = [], []
        previous = None
        for label, values in COMBINATIONS:
            base = saved.overridden(**values)
            passes = {k: d.run for k, d in plan_frame(description, base, None, view_projection).decisions.items()}
            if passes == previous:
                skipped.append(label)
                continue
            previous = passes
            for count in counts:
                settings = base.overridden(vsgl_count=count, rsm_size=128)
                seconds, images, times = _measure(lambda: renderer.render(description, settings, width, height),
                                                  repeats)
                manual.append(_row(label, settings, seconds, images, check, times))
                log(f"{name}: {label}, N = {count}: {seconds * 1e3:.0f} ms, rel RMSE {manual[-1]['rel']:.3f}")
        budget_rows = []
        os.environ["XDG_CACHE_HOME"] = str(cache)
        model = model_for(renderer, description, saved, width, height, gpu, log=log)
        for factor in budgets:
            target = factor * auto_seconds * 1e3
            settings = saved.overridden(quality_mode="budget", time_budget_ms=min(max(target, 1.0), 6e5))
            images, choice, model = render_budgeted(renderer, description, settings, width, height, model)
            first = {"predicted_ms": choice.predicted_seconds * 1e3, "measured_ms": choice.measured_seconds * 1e3}
            times, predicted = [], []
            for _ in range(repeats):
                images, choice, model = render_budgeted(renderer, description, settings, width, height, model)
                times.append(choice.measured_seconds)
                predicted.append(choice.predicted_seconds)
            seconds = float(np.median(times))
            row = _row(f"Budget {factor:g}× Auto", choice.settings, seconds, images, check, times,
                       target_ms=target, predicted_ms=float(np.median(predicted)) * 1e3,
                       scale=choice.candidate.scale, rendered_size=list(choice.size), first_frame=first,
                       fits=choice.fits)
            budget_rows.append(row)
            log(f"{name}: {row['label']} (target {target:.0f} ms): predicted {row['predicted_ms']:.0f} ms, "
                f"measured {seconds * 1e3:.0f} ms, rel RMSE {row['rel']:.3f} ({choice.line()})")
        B.save_model(gpu, model)
        # Auto again at the end: the machine is shared, so its time is the median of both visits.
        _, auto, again = _measure(lambda: renderer.render(description, auto_settings, width, height), repeats)
        auto_row = _row("Auto", auto_settings, float(np.median(auto_times + again)), auto, check, auto_times + again)
        eevee_figures = None
        if eevee:
            from tradeoff.baselines import eevee_runs

            scene = open_scene(path)
            eevee_figures = eevee_runs(scene, width, height, check, with_raytracing=True)
    finally:
        renderer.free()
    curve = cycles_curve(truth)
    for row in [auto_row, *manual, *budget_rows]:
        row["cycles_seconds_to_equal_error"] = cycles_time_to(curve, row["rel"])
        row["on_front"] = on_front(manual, row["seconds"], row["rel"])
    return {"scene": name, "auto": auto_row, "manual": manual, "skipped": skipped, "budget": budget_rows,
            "cycles": curve, "eevee": eevee_figures, "seconds": time.perf_counter() - started,
            "mean_truth": check.mean, "covered_pixels": int(check.mask.sum())}


def verdicts(result: dict) -> dict:
    """The targets' figures of one scene."""
    manual = result["manual"]
    auto = result["auto"]
    best_at_auto = front_error(manual, auto["seconds"])
    fastest_as_good = front_time(manual, auto["rel"])
    out = {"auto": {"rel": auto["rel"], "seconds": auto["seconds"], "front_error": best_at_auto,
                    "error_ratio": auto["rel"] / best_at_auto if math.isfinite(best_at_auto) else None,
                    "front_time": fastest_as_good,
                    "time_ratio": auto["seconds"] / fastest_as_good if math.isfinite(fastest_as_good) else None}}
    out["auto"]["met"] = bool((out["auto"]["error_ratio"] is None or out["auto"]["error_ratio"] <= 1 + AUTO_TOLERANCE)
                              or (out["auto"]["time_ratio"] is not None
                                  and out["auto"]["time_ratio"] <= 1 + AUTO_TOLERANCE))
    out["budget"] = []
    for row in result["budget"]:
        front = front_error(manual, row["seconds"])
        time_error = row["seconds"] * 1e3 / row["target_ms"] - 1.0
        error_ratio = row["rel"] / front if math.isfinite(front) else None
        out["budget"].append({"label": row["label"], "target_ms": row["target_ms"], "measured_ms": row["seconds"] * 1e3,
                              "predicted_ms": row["predicted_ms"], "time_error": time_error,
                              "time_met": abs(time_error) <= BUDGET_TIME_TOLERANCE, "front_error": front,
                              "error_ratio": error_ratio,
                              "error_met": error_ratio is None or error_ratio <= 1 + BUDGET_ERROR_TOLERANCE})
    return out


def _ms(seconds) -> str:
    return "—" if not math.isfinite(seconds) else f"{seconds * 1e3:.0f}"


def _s(seconds) -> str:
    return "—" if not math.isfinite(seconds) else f"{seconds:.1f}"


def markdown(results: list[dict], renderer: str, quick: bool, run_seconds: float, eevee: bool,
             command: str | None = None) -> str:
    command = command or f"benchmarks/tradeoff_suite.py{' --quick' if quick else ''}"
    kind = "quick run" if quick else ("full run" if len(results) == len(suite()) else f"{len(results)} scenes")
    lines = [f"# Speed against accuracy across techniques, per scene ({kind})", "",
             f"`{command}`, {time.strftime('%Y-%m-%d %H:%M')}, GPU "
             f"`{renderer}`, {os.cpu_count()} CPUs (load average {os.getloadavg()[0]:.1f}), {RESOLUTION[0]}x"
             f"{RESOLUTION[1]}; run time {run_seconds / 60:.1f} min. Error: noise-corrected relative RMSE of the "
             "indirect light against the scene's Cycles one-bounce truth (validation_suite.py's). Time: the frame's "
             "timed passes (GPU finished), median of the repeats; a shared machine, so compare within this run. "
             "Cycles: its time to the same error from its truth's noise (1/√samples) and render time per sample. "
             + ("" if eevee else "EEVEE: not run (it renders headless here, about a minute per frame; `--eevee`)."),
             ""]
    summary = ["## Summary, one line per scene", ""]
    targets = {"budget_time": [], "budget_error": [], "auto": []}
    for result in results:
        name = result["scene"]
        v = verdicts(result)
        result["verdicts"] = v
        auto = result["auto"]
        lines += [f"## {name}", "",
                  "| configuration | N | RSM | δ | interleave | scale | frame (ms) | rel RMSE | mean / Cycles | "
                  "on the front | Cycles to equal error (s) |", "|---|---|---|---|---|---|---|---|---|---|---|"]
        for row in [*result["manual"], auto, *result["budget"]]:
            label = row["label"] + (f" (target {row['target_ms']:.0f} ms, predicted {row['predicted_ms']:.0f})"
                                    if "target_ms" in row else "")
            lines.append(f"| {label} | {row['vsgl_count']} | {row['rsm_size']}² | {row['delta']:g} | "
                         f"{row['vpl_interleave']} | {row.get('scale', 1.0):g} | {_ms(row['seconds'])} | "
                         f"{row['rel']:.3f} | {row['mean_ratio']:.3f} | {'yes' if row['on_front'] else 'no'} | "
                         f"{_s(row['cycles_seconds_to_equal_error'])} |")
        if result["skipped"]:
            lines.append(f"\nNot rendered (the plan runs the same passes as the combination before: the cell is "
                         f"empty here): {', '.join(result['skipped'])}.")
        if result.get("eevee"):
            e = result["eevee"]
            lines.append(f"\nEEVEE ({e['samples']} samples): as saved {e['seconds'] * 1e3:.0f} ms, rel RMSE "
                         f"{e['default']['rel']:.3f}; ray tracing + fast GI {e['rt_seconds'] * 1e3:.0f} ms, rel RMSE "
                         f"{e['raytraced']['rel']:.3f}.")
        lines.append("")
        a = v["auto"]
        targets["auto"].append(a["met"])
        budget_text = []
        for b in v["budget"]:
            targets["budget_time"].append(b["time_met"])
            targets["budget_error"].append(b["error_met"])
            ratio = "no manual setting that fast" if b["error_ratio"] is None else f"{b['error_ratio']:.2f}× the front"
            budget_text.append(f"{b['target_ms']:.0f} → {b['measured_ms']:.0f} ms ({100 * b['time_error']:+.0f} %, "
                               f"error {ratio})")
        cycles = auto["cycles_seconds_to_equal_error"]
        error_ratio = "—" if a["error_ratio"] is None else f"{a['error_ratio']:.2f}"
        summary.append(
            f"- **{name}**: Auto {auto['rel']:.3f} at {auto['seconds'] * 1e3:.0f} ms (front {a['front_error']:.3f} at "
            f"that time: {error_ratio}×; {'on' if a['met'] else 'OFF'} the front within 10 %); Budget "
            + "; ".join(budget_text)
            + f"; Cycles needs {_s(cycles)} s for Auto's error ({cycles / auto['seconds']:.0f}× Auto's time).")
    counts = {key: (sum(values), len(values)) for key, values in targets.items()}
    lines += summary + ["", "## Targets", "", "| target | met | figures |", "|---|---|---|",
                        f"| Budget: measured frame time within 25 % of the target | {counts['budget_time'][0]} of "
                        f"{counts['budget_time'][1]} | per scene above |",
                        f"| Budget: error within 15 % of the best manual setting on the front at its time | "
                        f"{counts['budget_error'][0]} of {counts['budget_error'][1]} | per scene above |",
                        f"| Auto on the Pareto front within 10 % | {counts['auto'][0]} of {counts['auto'][1]} scenes | "
                        "per scene above |", ""]
    return "\n".join(lines)


def plot(results: list[dict], path: Path) -> None:
    """One panel per scene: frame time against relative RMSE (log-log) of every configuration, the
    measured front, Auto, Budget and Cycles' curve."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = min(len(results), 5)
    rows = math.ceil(len(results) / columns)
    fig, axes = plt.subplots(rows, columns, figsize=(3.6 * columns, 3.2 * rows), squeeze=False)
    colours = dict(zip([label for label, _ in COMBINATIONS], ("#999999", "#2b6cb0", "#dd6b20", "#38a169")))
    for axis, result in zip(axes.flat, results):
        for label, colour in colours.items():
            points = sorted((r["seconds"], r["rel"]) for r in result["manual"] if r["label"] == label)
            if points:
                axis.plot(*zip(*[(t * 1e3, e) for t, e in points]), "o-", color=colour, label=label, markersize=4)
        front = sorted((r["seconds"], r["rel"]) for r in result["manual"] if r["on_front"])
        if front:
            axis.step(*zip(*[(t * 1e3, e) for t, e in front]), where="post", color="black", linewidth=0.8,
                      linestyle=":", label="front")
        axis.plot(result["auto"]["seconds"] * 1e3, result["auto"]["rel"], "*", color="#e53e3e", markersize=12,
                  label="Auto")
        for row in result["budget"]:
            axis.plot(row["seconds"] * 1e3, row["rel"], "s", color="#805ad5", markersize=6,
                      label="Budget" if row is result["budget"][0] else None)
            axis.axvline(row["target_ms"], color="#805ad5", linewidth=0.5, alpha=0.5)
        cycles = [(r["seconds"] * 1e3, r["rel"]) for r in result["cycles"]["rows"]]
        axis.plot(*zip(*cycles), "--", color="#718096", label="Cycles (noise)")
        ours = [r["seconds"] * 1e3 for r in [result["auto"], *result["manual"], *result["budget"]]]
        errors = [r["rel"] for r in [result["auto"], *result["manual"], *result["budget"]]]
        axis.set_xscale("log")
        axis.set_yscale("log")
        axis.set_xlim(min(ours) / 2, max(ours) * 30)
        axis.set_ylim(min(errors) / 1.5, max(errors) * 1.5)
        axis.set_title(result["scene"], fontsize=9)
        axis.set_xlabel("frame time (ms)", fontsize=8)
        axis.set_ylabel("rel RMSE", fontsize=8)
        axis.tick_params(labelsize=7)
    for axis in list(axes.flat)[len(results):]:
        axis.axis("off")
    handles = {}
    for axis in axes.flat:  # every panel's labels once (a scene without VPLs has no "+ VPLs")
        for handle, label in zip(*axis.get_legend_handles_labels()):
            handles.setdefault(label, handle)
    fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _finite(value):
    """JSON has no infinity: None instead (a front with no manual setting that fast)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(item) for item in value]
    return value


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--only", nargs="+", metavar="NAME")
    parser.add_argument("--results-dir", type=Path, default=RESULTS_DIR)
    parser.add_argument("--budgets", type=float, nargs="+", metavar="F", help="targets as F × Auto's time")
    parser.add_argument("--repeats", type=int)
    parser.add_argument("--eevee", action="store_true")
    parser.add_argument("--cache", type=Path, help="the cost model's cache directory (default: a fresh one)")
    parser.add_argument("--name", help="the results files' name (default: tradeoff_suite, _quick with --quick)")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    gpu = ensure_gpu_context()
    chosen = args.only or ([QUICK_SCENE] if args.quick else None)
    scenes = [s for s in suite() if chosen is None or s[0] in chosen]
    counts = (64, 256) if args.quick else COUNTS
    budgets = tuple(args.budgets or ((1.0,) if args.quick else BUDGETS))
    repeats = args.repeats or (1 if args.quick else 2)
    with tempfile.TemporaryDirectory(prefix="vsgl-cost-model-") as fresh:
        cache = args.cache or Path(fresh)
        results = [measure_scene(name, path, counts, budgets, repeats, args.eevee, gpu, cache)
                   for name, path, _ in scenes]
    stem = args.name or ("tradeoff_suite_quick" if args.quick else "tradeoff_suite")
    out = args.results_dir
    out.mkdir(parents=True, exist_ok=True)
    command = " ".join([".venv/bin/python", "benchmarks/tradeoff_suite.py", *(argv if argv is not None else sys.argv[1:])])
    text = markdown(results, gpu, args.quick, time.perf_counter() - started, args.eevee, command)
    plot(results, out / f"{stem}.png")
    text += f"Plot (a panel per scene): `{stem}.png`.\n"
    (out / f"{stem}.md").write_text(text)
    (out / f"{stem}.json").write_text(json.dumps(_finite(
        {"renderer": gpu, "quick": args.quick, "resolution": list(RESOLUTION), "counts": list(counts),
         "budgets": list(budgets), "repeats": repeats, "scenes": results}), indent=1, default=str))
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
