# SPDX-License-Identifier: GPL-3.0-or-later
"""Interactive speed of the Rendered viewport and of the overlay, in Blender 5.2's window.

For each scene (demo.blend and validation scenes) the extension is installed into a clean profile
and `real-blender gui` opens the scene with benchmarks/interactive_gui.py, which moves the scene's
first light and measures, through the camera at resolution scale 0.25 in the default 1600 × 900
window's viewport:

* the time from the change to the first (coarse) image, and that step's own time;
* the time of each refinement step (the budget is one frame, about 60 ms here);
* the work time until the image is within 10 % / 5 % relative RMSE of the converged one (8 samples);
* the CPU round trips per update (bytes read back and uploaded);
* the same in Budget quality mode (target frame time ``--budget-ms``, 60 ms: one frame), whose
  coarse step's size the cost model predicts (budget.coarse_factor), against Manual (the scene's
  settings) in the same session: the quality cost is the coarse image's error against the converged
  image, which both modes share;
* the same change with the overlay over Solid shading ("Combined"), in the same session: it draws
  through the same view pipeline, so its steps and converged image must match the Rendered mode's.
  The overlay before it shared the pipeline (its own CPU cache, images read back and uploaded per
  update) is measured in benchmarks/results/interactive_cpu_overlay.md, the last run of that code.

Times are wall-clock on a shared 2-core llvmpipe machine: compare the two paths within one run.
Writes benchmarks/results/interactive.{md,json} (``--quick``: demo only, one repeat, *_quick.*).

    .venv/bin/python benchmarks/interactive.py [--quick] [--samples 8] [--budget-ms 60] [--scenes demo ...]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests"))

from helpers_blender import REAL_BLENDER, blender_environment, run_blender  # noqa: E402

SCENES = ("demo", "cornell_box", "glossy_floor_object", "occluder")


def scene_path(name: str) -> Path:
    return REPO / "demo.blend" if name == "demo" else REPO / "benchmarks" / "scenes" / f"{name}.blend"


def run_scene(name: str, user: Path, folder: Path, samples: int, repeats: int, budget_ms: float) -> dict:
    out = folder / f"{name}.json"
    env = {"BLENDER_USER_RESOURCES": str(user), "BLENDER_VSGL_BENCH_OUT": str(out),
           "BLENDER_VSGL_BENCH_SAMPLES": str(samples), "BLENDER_VSGL_BENCH_REPEATS": str(repeats),
           "BLENDER_VSGL_BENCH_BUDGET_MS": str(budget_ms)}
    proc = subprocess.run([str(REAL_BLENDER), "gui", "--size", "1600x900", "--wait", "1800",
                           "--shot", str(folder / f"{name}.png"), str(scene_path(name)), "--python",
                           str(REPO / "benchmarks" / "interactive_gui.py")],
                          cwd=REPO, env=blender_environment(env), capture_output=True, text=True, timeout=2400)
    if not out.is_file():
        raise RuntimeError(f"{name}: no result\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    result = json.loads(out.read_text())
    if result["errors"]:
        raise RuntimeError(f"{name}: " + "\n".join(result["errors"]))
    return result


def _ms(seconds) -> str:
    return "–" if seconds is None else f"{seconds * 1000:.0f}"


def rendered_summary(runs: list, prefix: str) -> dict:
    """A quality mode's Rendered figures: its repeats after the first (which also reads images back
    for the error curve), that first repeat's error curve."""
    timed = runs[1:] or runs
    steps = [e["seconds"] for r in timed for e in r["entries"][1:] if e["work"] == "sample"]
    curve = runs[0].get("error_curve", [])

    def time_to(error):
        seconds = next((p["work_seconds"] for p in curve if p["relative_rmse"] <= error), None)
        return None if seconds is None else seconds * 1000

    first = [r["entries"][0] for r in timed]
    per_update = lambda key: statistics.median(r["round_trips"][key] for r in timed)  # noqa: E731
    return {
        f"{prefix}_first_image_ms": statistics.median(r["first_image_wall"] for r in timed) * 1000,
        f"{prefix}_first_step_ms": statistics.median(r["first_step_seconds"] for r in timed) * 1000,
        f"{prefix}_first_light_ms": statistics.median(e.get("light_seconds", 0.0) for e in first) * 1000,
        f"{prefix}_first_view_ms": statistics.median(e.get("view_seconds", 0.0) for e in first) * 1000,
        f"{prefix}_coarse_size": first[0].get("size"),
        f"{prefix}_step_median_ms": statistics.median(steps) * 1000 if steps else None,
        f"{prefix}_step_max_ms": max(steps) * 1000 if steps else None,
        f"{prefix}_steps_over_budget": sum(s > 0.06 for s in steps) / len(steps) if steps else None,
        f"{prefix}_converged_ms": statistics.median(r["converged_wall"] for r in timed) * 1000,
        f"{prefix}_coarse_error": curve[0]["relative_rmse"] if curve else None,
        f"{prefix}_time_to_10pc_ms": time_to(0.10),
        f"{prefix}_time_to_5pc_ms": time_to(0.05),
        f"{prefix}_read_back_bytes": per_update("read_back_bytes"),
        f"{prefix}_upload_bytes": per_update("upload_bytes"),
    }


def summarise(name: str, result: dict) -> dict:
    overlay_steps = [u["seconds"] for r in result["overlay"] for u in r["updates"][1:] if u["work"] == "sample"]
    per_update = lambda runs, key: statistics.median(r["round_trips"][key] for r in runs)  # noqa: E731
    row = {"scene": name, "region": result["region"], **rendered_summary(result["rendered"], "rendered")}
    if result.get("rendered_budget"):
        switch = result["budget_switch"]
        row.update(rendered_summary(result["rendered_budget"], "budget"))
        row.update({
            "budget_ms": result["budget_ms"],
            "budget_switch_first_image_ms": switch["first_image_wall"] * 1000,
            "budget_switch_first_step_ms": switch["first_entry"]["seconds"] * 1000,
            "budget_switch_coarse_size": switch["first_entry"].get("size"),
            "budget_switch_predicted_view_ms": (switch["first_entry"].get("predicted_view_seconds") or 0.0) * 1000
            if "predicted_view_seconds" in switch["first_entry"] else None,
            "budget_switch_view_ms": switch["first_entry"].get("view_seconds", 0.0) * 1000,
            "budget_cost_model": switch["cost_model"],
            "budget_converged_error_against_manual": result.get("budget_converged_relative_rmse_manual"),
        })
    row.update({
        "overlay_first_image_ms": statistics.median(r["first_image_wall"] for r in result["overlay"]) * 1000,
        "overlay_refined_ms": statistics.median(r["refined_wall"] for r in result["overlay"]) * 1000,
        "overlay_step_median_ms": statistics.median(overlay_steps) * 1000 if overlay_steps else None,
        "overlay_step_max_ms": max(overlay_steps) * 1000 if overlay_steps else None,
        "overlay_final_error": result.get("overlay_final_relative_rmse_nearest"),
        "overlay_read_back_bytes": per_update(result["overlay"], "read_back_bytes"),
        "overlay_upload_bytes": per_update(result["overlay"], "upload_bytes"),
    })
    return row


def compact(result: dict) -> dict:
    """The raw result without each step's log entry: per repeat, the steps' work and seconds only."""
    out = dict(result)
    for key in ("rendered", "rendered_budget"):
        out[key] = [{**{k: v for k, v in r.items() if k != "entries"}, "first_entry": r["entries"][0],
                     "steps": [[e["work"], round(e["seconds"], 4)] for e in r["entries"]]}
                    for r in result.get(key, [])]
    return out


def table(rows, samples) -> str:
    lines = [f"Rendered viewport (VSGL engine) and the overlay over Solid (the same view pipeline), Blender 5.2 window, "
             f"llvmpipe, through the camera, resolution scale 0.25, {samples} samples; a light moved. "
             "Medians over the repeats; times in ms; errors are relative RMSE against the converged "
             "Rendered image; round trips per update in bytes.", "",
             "| scene | viewport px | Rendered: change → first image | first step | refinement step median / max "
             "| to 10 % / 5 % error (work) | coarse error | converged | read back / uploaded "
             "| Overlay: change → first image | → converged | step median / max | error against Rendered "
             "| read back / uploaded |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['scene']} | {r['region'][0]}×{r['region'][1]} | {r['rendered_first_image_ms']:.0f} "
            f"| {r['rendered_first_step_ms']:.0f} "
            f"| {_ms(r['rendered_step_median_ms'] and r['rendered_step_median_ms'] / 1000)} / "
            f"{_ms(r['rendered_step_max_ms'] and r['rendered_step_max_ms'] / 1000)} "
            f"| {_ms(r['rendered_time_to_10pc_ms'] and r['rendered_time_to_10pc_ms'] / 1000)} / "
            f"{_ms(r['rendered_time_to_5pc_ms'] and r['rendered_time_to_5pc_ms'] / 1000)} "
            f"| {r['rendered_coarse_error']:.3f} | {r['rendered_converged_ms']:.0f} "
            f"| {r['rendered_read_back_bytes']:.0f} / {r['rendered_upload_bytes']:.0f} "
            f"| {r['overlay_first_image_ms']:.0f} | {r['overlay_refined_ms']:.0f} "
            f"| {_ms(r['overlay_step_median_ms'] and r['overlay_step_median_ms'] / 1000)} / "
            f"{_ms(r['overlay_step_max_ms'] and r['overlay_step_max_ms'] / 1000)} "
            f"| {r['overlay_final_error']:.3f} "
            f"| {r['overlay_read_back_bytes']:.0f} / {r['overlay_upload_bytes']:.0f} |")
    if any("budget_first_image_ms" in r for r in rows):
        lines += ["", f"Rendered shading, Manual (the scene's settings) against Budget quality mode (target "
                  f"{rows[0]['budget_ms']:.0f} ms; the viewport's coarse step sized by the cost model), the same "
                  "session and moves. Target (one frame, about 60 ms here): change → first coarse image and "
                  "every refinement step within it. \"switch\": Manual → Budget, the step the cost model sized "
                  "(its predicted view time); errors against each mode's own converged image.", "",
                  "| scene | mode | change → first image | first step (light passes + view) | coarse px "
                  "| refinement step median / max (share > 60 ms) | coarse error | to 10 % / 5 % error (work) "
                  "| converged |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for r in rows:
            if "budget_first_image_ms" not in r:
                continue
            for mode, prefix in (("Manual", "rendered"), ("Budget", "budget")):
                size = r[f"{prefix}_coarse_size"]
                lines.append(
                    f"| {r['scene']} | {mode} | {r[f'{prefix}_first_image_ms']:.0f} "
                    f"| {r[f'{prefix}_first_step_ms']:.0f} ({r[f'{prefix}_first_light_ms']:.0f} + "
                    f"{r[f'{prefix}_first_view_ms']:.0f}) | {size[0]}×{size[1]} "
                    f"| {_ms(r[f'{prefix}_step_median_ms'] and r[f'{prefix}_step_median_ms'] / 1000)} / "
                    f"{_ms(r[f'{prefix}_step_max_ms'] and r[f'{prefix}_step_max_ms'] / 1000)} "
                    f"({100 * (r[f'{prefix}_steps_over_budget'] or 0):.0f} %) "
                    f"| {r[f'{prefix}_coarse_error']:.3f} "
                    f"| {_ms(r[f'{prefix}_time_to_10pc_ms'] and r[f'{prefix}_time_to_10pc_ms'] / 1000)} / "
                    f"{_ms(r[f'{prefix}_time_to_5pc_ms'] and r[f'{prefix}_time_to_5pc_ms'] / 1000)} "
                    f"| {r[f'{prefix}_converged_ms']:.0f} |")
            size = r["budget_switch_coarse_size"]
            predicted = r["budget_switch_predicted_view_ms"]
            lines.append(
                f"| {r['scene']} | switch | {r['budget_switch_first_image_ms']:.0f} "
                f"| {r['budget_switch_first_step_ms']:.0f} (view {r['budget_switch_view_ms']:.0f}, predicted "
                f"{'–' if predicted is None else f'{predicted:.0f}'}) | {size[0]}×{size[1]} | | | | |")
        for r in rows:
            if "budget_first_image_ms" in r:
                error = r["budget_converged_error_against_manual"]
                lines += ["", f"{r['scene']}: cost model {r['budget_cost_model']!r}; Budget's converged image "
                          f"against Manual's at the same light position: relative RMSE "
                          f"{'–' if error is None else f'{error:.3f}'}."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="demo.blend only, one repeat")
    parser.add_argument("--scenes", nargs="*", default=None)
    parser.add_argument("--samples", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--budget-ms", type=float, default=60.0,
                        help="Budget mode's target frame time (the viewport's step budget is one frame, 60 ms)")
    parser.add_argument("--output", default=None,
                        help="results file stem under benchmarks/results (default interactive, or interactive_quick)")
    arguments = parser.parse_args(argv)
    scenes = arguments.scenes or (("demo",) if arguments.quick else SCENES)
    repeats = 1 if arguments.quick else arguments.repeats
    with tempfile.TemporaryDirectory(prefix="vsgl-interactive-") as tmp:
        folder = Path(tmp)
        build, user = folder / "build", folder / "user"
        build.mkdir()
        user.mkdir()
        proc = run_blender("--command", "extension", "build", "--source-dir", str(REPO), "--output-dir", str(build))
        assert proc.returncode == 0, proc.stderr
        proc = run_blender("--command", "extension", "install-file", "-r", "user_default", "-e",
                           str(next(build.glob("*.zip"))), blender_env={"BLENDER_USER_RESOURCES": str(user)})
        assert proc.returncode == 0, proc.stderr
        raw, rows = {}, []
        for name in scenes:
            print(f"{name} …", flush=True)
            raw[name] = run_scene(name, user, folder, arguments.samples, repeats, arguments.budget_ms)
            rows.append(summarise(name, raw[name]))
            print(table(rows[-1:], arguments.samples), flush=True)
    stem = arguments.output or ("interactive_quick" if arguments.quick else "interactive")
    results = REPO / "benchmarks" / "results"
    text = table(rows, arguments.samples)
    (results / f"{stem}.md").write_text("# Interactive speed\n\n" + text)
    (results / f"{stem}.json").write_text(json.dumps({"rows": rows, "raw": {name: compact(r) for name, r in raw.items()}}, default=float))
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
