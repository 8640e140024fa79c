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
* the same change with the overlay over Solid shading ("Combined"), in the same session: it draws
  through the same view pipeline, so its steps and converged image must match the Rendered mode's.
  The overlay before it shared the pipeline (its own CPU cache, images read back and uploaded per
  update) is measured in benchmarks/results/interactive_cpu_overlay.md, the last run of that code.

Times are wall-clock on a shared 2-core llvmpipe machine: compare the two paths within one run.
Writes benchmarks/results/interactive.{md,json} (``--quick``: demo only, one repeat, *_quick.*).

    .venv/bin/python benchmarks/interactive.py [--quick] [--scenes demo cornell_box ...]
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


def run_scene(name: str, user: Path, folder: Path, samples: int, repeats: int) -> dict:
    out = folder / f"{name}.json"
    env = {"BLENDER_USER_RESOURCES": str(user), "BLENDER_VSGL_BENCH_OUT": str(out),
           "BLENDER_VSGL_BENCH_SAMPLES": str(samples), "BLENDER_VSGL_BENCH_REPEATS": str(repeats)}
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


def summarise(name: str, result: dict) -> dict:
    timed = result["rendered"][1:] or result["rendered"]  # the first change also reads images back
    rendered_steps = [e["seconds"] for r in timed for e in r["entries"][1:] if e["work"] == "sample"]
    curve = result["rendered"][0].get("error_curve", [])

    def time_to(error):
        return next((point["work_seconds"] for point in curve if point["relative_rmse"] <= error), None)

    overlay_steps = [u["seconds"] for r in result["overlay"] for u in r["updates"][1:] if u["work"] == "sample"]
    per_update = lambda runs, key: statistics.median(r["round_trips"][key] for r in runs)  # noqa: E731
    return {
        "scene": name, "region": result["region"],
        "rendered_first_image_ms": statistics.median(r["first_image_wall"] for r in timed) * 1000,
        "rendered_first_step_ms": statistics.median(r["first_step_seconds"] for r in timed) * 1000,
        "rendered_step_median_ms": statistics.median(rendered_steps) * 1000 if rendered_steps else None,
        "rendered_step_max_ms": max(rendered_steps) * 1000 if rendered_steps else None,
        "rendered_converged_ms": statistics.median(r["converged_wall"] for r in timed) * 1000,
        "rendered_coarse_error": curve[0]["relative_rmse"] if curve else None,
        "rendered_time_to_10pc_ms": None if time_to(0.10) is None else time_to(0.10) * 1000,
        "rendered_time_to_5pc_ms": None if time_to(0.05) is None else time_to(0.05) * 1000,
        "rendered_read_back_bytes": per_update(timed, "read_back_bytes"),
        "rendered_upload_bytes": per_update(timed, "upload_bytes"),
        "overlay_first_image_ms": statistics.median(r["first_image_wall"] for r in result["overlay"]) * 1000,
        "overlay_refined_ms": statistics.median(r["refined_wall"] for r in result["overlay"]) * 1000,
        "overlay_step_median_ms": statistics.median(overlay_steps) * 1000 if overlay_steps else None,
        "overlay_step_max_ms": max(overlay_steps) * 1000 if overlay_steps else None,
        "overlay_final_error": result.get("overlay_final_relative_rmse_nearest"),
        "overlay_read_back_bytes": per_update(result["overlay"], "read_back_bytes"),
        "overlay_upload_bytes": per_update(result["overlay"], "upload_bytes"),
    }


def compact(result: dict) -> dict:
    """The raw result without each step's log entry: per repeat, the steps' work and seconds only."""
    out = dict(result)
    out["rendered"] = [{**{k: v for k, v in r.items() if k != "entries"},
                        "steps": [[e["work"], round(e["seconds"], 4)] for e in r["entries"]]}
                       for r in result["rendered"]]
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
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="demo.blend only, one repeat")
    parser.add_argument("--scenes", nargs="*", default=None)
    parser.add_argument("--samples", type=int, default=8)
    parser.add_argument("--repeats", type=int, default=3)
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
            raw[name] = run_scene(name, user, folder, arguments.samples, repeats)
            rows.append(summarise(name, raw[name]))
            print(table(rows[-1:], arguments.samples), flush=True)
    suffix = "_quick" if arguments.quick else ""
    results = REPO / "benchmarks" / "results"
    text = table(rows, arguments.samples)
    (results / f"interactive{suffix}.md").write_text("# Interactive speed\n\n" + text)
    (results / f"interactive{suffix}.json").write_text(json.dumps({"rows": rows, "raw": {name: compact(r) for name, r in raw.items()}}, default=float))
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
