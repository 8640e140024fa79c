# SPDX-License-Identifier: GPL-3.0-or-later
"""Where a light move's latency goes in Rendered shading, in Blender 5.2's window (not a test).

    .venv/bin/python benchmarks/latency.py [--baseline REV] [--rounds 2] [--moves 8] [--steps 8]
                                           [--output latency] [--no-write]

demo.blend in the default 1600 × 900 window, through the camera at resolution scale 0.25 (as
benchmarks/interactive.py): benchmarks/latency_gui.py moves the first light ``--moves`` times from
an idle (converged) viewport and stamps every event between the change and the coarse image on
screen, then the ``--steps`` steps after it (the refinement steps). Per move, in ms from the change:

* ``depsgraph``: Blender's depsgraph_update_post; ``view_update``: the engine marked the scene dirty;
* ``step start`` / ``step end``: the step that rebuilt the light passes and rendered the coarse image
  (interactive.md's "change → first image" is its end); ``its view_draw``: the end of the first
  view_draw after it; ``viewport drawn``: the 3D viewport's POST_PIXEL handler after that (Blender's
  overlays drawn over the image: the frame is then complete but for the window's swap);
* the gaps between them, and the draws of the 3D viewport, the properties editor and the outliner
  Blender made in between (POST_PIXEL handlers), with the view_draw time;
* the refinement steps: their kinds (light passes of the samples, bands) and times.

With ``--baseline REV`` an export of commit REV is installed in its own profile and measured in the
same run, alternating process by process (ABBA...): the shared machine's load varies, read the ratios.
Writes benchmarks/results/latency.{md,json} unless --no-write.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests"))
sys.path.insert(0, str(REPO / "benchmarks"))

from checkout_ab import alternate, extract_commit  # noqa: E402
from helpers_blender import REAL_BLENDER, blender_environment, run_blender  # noqa: E402

STEP_BUDGET = 0.06


def install(source: Path, folder: Path) -> Path:
    """A clean user profile under `folder` with the extension built from `source` installed."""
    build, user = folder / "build", folder / "user"
    build.mkdir(parents=True)
    user.mkdir()
    proc = run_blender("--command", "extension", "build", "--source-dir", str(source), "--output-dir", str(build))
    assert proc.returncode == 0, proc.stderr
    proc = run_blender("--command", "extension", "install-file", "-r", "user_default", "-e",
                       str(next(build.glob("*.zip"))), blender_env={"BLENDER_USER_RESOURCES": str(user)})
    assert proc.returncode == 0, proc.stderr
    return user


def run_gui(user: Path, out: Path, moves: int, steps: int) -> dict:
    env = {"BLENDER_USER_RESOURCES": str(user), "BLENDER_VSGL_BENCH_OUT": str(out),
           "BLENDER_VSGL_BENCH_MOVES": str(moves), "BLENDER_VSGL_BENCH_STEPS": str(steps)}
    proc = subprocess.run([str(REAL_BLENDER), "gui", "--size", "1600x900", "--wait", "900",
                           "--shot", str(out.with_suffix(".png")), str(REPO / "demo.blend"), "--python",
                           str(REPO / "benchmarks" / "latency_gui.py")],
                          cwd=REPO, env=blender_environment(env), capture_output=True, text=True, timeout=1200)
    if not out.is_file():
        raise RuntimeError(f"no result\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    result = json.loads(out.read_text())
    if result["errors"]:
        raise RuntimeError("\n".join(result["errors"]))
    result["load_average"] = os.getloadavg()
    return result


def analyse_move(events: list) -> dict:
    """One move's events -> its milestones and gaps (ms from the change) and its steps."""
    t0 = next(t for kind, t, _ in events if kind == "change")

    def first(kind, after=t0, **match):
        return next((t for k, t, extra in events if k == kind and t >= after
                     and all(extra.get(key) == value for key, value in match.items())), None)

    steps = []
    begin = None
    for kind, t, extra in events:
        if kind == "step_begin":
            begin = t
        elif kind == "step_end" and begin is not None:
            entry = extra.get("entry", {})
            steps.append({"begin": begin, "end": t, "work": entry.get("work"), "level": entry.get("level"),
                          "light_seconds": entry.get("light_seconds"), "view_seconds": entry.get("view_seconds"),
                          "view_passes_seconds": entry.get("view_passes_seconds"),
                          "rows": entry.get("rows"), "columns": entry.get("columns"), "seconds": entry.get("seconds"),
                          "size": entry.get("size"),
                          "spans": entry.get("spans")})
            begin = None
    coarse = next(s for s in steps if s["work"] == "lights")
    draws = []
    begin = None
    for kind, t, extra in events:
        if kind == "draw_begin":
            begin = t
        elif kind == "draw_end" and begin is not None:
            draws.append((begin, t))
            begin = None
    on_screen = next(end for begin, end in draws if begin >= coarse["end"])
    dirty = first("dirty")
    milestones = {"depsgraph": first("depsgraph"), "view_update": dirty,
                  "first view_draw": next((b for b, _ in draws if dirty is not None and b >= dirty), None),
                  "step start": coarse["begin"], "step end": coarse["end"], "its view_draw": on_screen,
                  "viewport drawn": first("post_pixel", on_screen, space="view3d")}
    before_step = [(k, extra.get("space")) for k, t, extra in events if k == "post_pixel" and t < coarse["begin"]]
    ms = {name: None if t is None else (t - t0) * 1000 for name, t in milestones.items()}
    refinement = [s for s in steps if s is not coarse and s["begin"] > coarse["end"]]
    return {"milestones_ms": ms,
            "coarse_step_ms": (coarse["end"] - coarse["begin"]) * 1000,
            "coarse_light_ms": (coarse["light_seconds"] or 0) * 1000,
            "coarse_view_ms": (coarse["view_seconds"] or 0) * 1000,
            "coarse_view_passes_ms": (coarse["view_passes_seconds"] or 0) * 1000,
            "coarse_pixels": None if not coarse.get("size") else coarse["size"][0] * coarse["size"][1],
            "coarse_spans": coarse.get("spans"),
            "view_draw_ms": [(e - b) * 1000 for b, e in draws if b < on_screen],
            "redraws_before_step": {space: sum(1 for _, s in before_step if s == space)
                                    for space in ("view3d", "properties", "outliner")},
            "refinement": [{"work": s["work"], "level": s["level"], "ms": (s["end"] - s["begin"]) * 1000,
                            "light_ms": None if s["light_seconds"] is None else s["light_seconds"] * 1000,
                            "rows": s["rows"], "columns": s.get("columns"),
                            "pipeline_ms": None if s.get("seconds") is None else s["seconds"] * 1000,
                            "spans": s.get("spans")} for s in refinement]}


def summarise(results: list[dict]) -> dict:
    moves = [analyse_move(m) for r in results for m in r["moves"]]
    names = list(moves[0]["milestones_ms"])
    med = lambda values: statistics.median(values) if values else None  # noqa: E731
    milestones = {n: med([m["milestones_ms"][n] for m in moves if m["milestones_ms"][n] is not None]) for n in names}
    refinement = [s["ms"] for m in moves for s in m["refinement"]]
    light_steps = [s["ms"] for m in moves for s in m["refinement"] if s["light_ms"] is not None]
    band_steps = [s["ms"] for m in moves for s in m["refinement"] if s["light_ms"] is None]
    return {"moves": len(moves), "milestones_ms": milestones,
            "coarse_step_ms": med([m["coarse_step_ms"] for m in moves]),
            "coarse_light_ms": med([m["coarse_light_ms"] for m in moves]),
            "coarse_view_ms": med([m["coarse_view_ms"] for m in moves]),
            "coarse_view_passes_ms": med([m.get("coarse_view_passes_ms", 0.0) for m in moves]),
            "coarse_pixels": med([m["coarse_pixels"] for m in moves if m.get("coarse_pixels") is not None]),
            "view_draw_ms": med([d for m in moves for d in m["view_draw_ms"]]),
            "redraws_before_step": {k: med([m["redraws_before_step"][k] for m in moves])
                                    for k in ("view3d", "properties", "outliner")},
            "refinement_median_ms": med(refinement), "refinement_max_ms": max(refinement) if refinement else None,
            "refinement_over_budget": sum(s > STEP_BUDGET * 1000 for s in refinement) / max(len(refinement), 1),
            "light_steps_ms": sorted(light_steps), "band_step_median_ms": med(band_steps),
            "band_step_max_ms": max(band_steps) if band_steps else None,
            "load_average": [r["load_average"] for r in results]}


def table(summaries: dict[str, dict], arguments) -> str:
    labels = list(summaries)
    lines = ["| | " + " | ".join(labels) + (" | after / before |" if len(labels) == 2 else " |"),
             "|---|" + "---|" * (len(labels) + (len(labels) == 2))]

    def row(name, values):
        ratio = ""
        if len(values) == 2 and None not in values and values[0]:
            ratio = f" {values[1] / values[0]:.2f} |"
        cells = " | ".join("–" if v is None else f"{v:.0f}" for v in values)
        lines.append(f"| {name} | {cells} |{ratio}")

    for name in summaries[labels[0]]["milestones_ms"]:
        row(f"change → {name}", [summaries[label]["milestones_ms"][name] for label in labels])
    for key, name in (("coarse_step_ms", "coarse step"), ("coarse_light_ms", "its light passes"),
                      ("coarse_view_ms", "its view render"),
                      ("coarse_view_passes_ms", "of which view passes (the rest: guide, resolve)"),
                      ("coarse_pixels", "its coarse image (pixels)"),
                      ("view_draw_ms", "one view_draw"),
                      ("refinement_median_ms", "refinement step median"),
                      ("refinement_max_ms", "refinement step max"),
                      ("band_step_median_ms", "band step median"), ("band_step_max_ms", "band step max")):
        row(name, [summaries[label][key] for label in labels])
    lines.append("| refinement steps > 60 ms | " + " | ".join(
        f"{100 * summaries[label]['refinement_over_budget']:.0f} %" for label in labels) + " |" +
        (" |" if len(labels) == 2 else ""))
    lines.append("| samples' light-pass steps (ms) | " + " | ".join(
        ", ".join(f"{v:.0f}" for v in summaries[label]["light_steps_ms"]) for label in labels) + " |" +
        (" |" if len(labels) == 2 else ""))
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", default=None, help="a commit to measure in the same run")
    parser.add_argument("--rounds", type=int, default=2, help="Blender sessions per checkout")
    parser.add_argument("--moves", type=int, default=8)
    parser.add_argument("--steps", type=int, default=8, help="steps recorded after each move")
    parser.add_argument("--output", default="latency")
    parser.add_argument("--no-write", action="store_true")
    arguments = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="vsgl-latency-") as tmp:
        folder = Path(tmp)
        variants = [("current", install(REPO, folder / "current"))]
        if arguments.baseline:
            source = extract_commit(arguments.baseline, folder / "baseline_src")
            variants.insert(0, ("baseline", install(source, folder / "baseline")))
        counter = iter(range(1000))
        results = alternate(variants, arguments.rounds, lambda label, user: run_gui(
            user, folder / f"{label}_{next(counter)}.json", arguments.moves, arguments.steps))
    summaries = {label: summarise(runs) for label, runs in results.items()}
    text = table(summaries, arguments)
    print(text)
    if not arguments.no_write:
        results_dir = REPO / "benchmarks" / "results"
        command = "    .venv/bin/python benchmarks/latency.py " + " ".join(argv if argv is not None else sys.argv[1:])
        loads = ", ".join(f"{a[0]:.2f}" for s in summaries.values() for a in s["load_average"])
        (results_dir / f"{arguments.output}.md").write_text(
            "# Light move → first image in Rendered shading, event by event\n\n"
            "demo.blend, Blender 5.2's window (1600 × 900, llvmpipe), through the camera at resolution scale "
            "0.25, Manual mode; medians over every move (ms; milestones from the change). "
            + (f"Before: commit {arguments.baseline}; after: this checkout; Blender sessions alternating "
               "(ABBA). " if arguments.baseline else "")
            + f"Load average (1 min) at each session's end: {loads}. Command:\n\n{command}\n\n{text}\n")
        (results_dir / f"{arguments.output}.json").write_text(json.dumps(
            {"summaries": summaries, "raw": {label: [[analyse_move(m) for m in r["moves"]] for r in runs]
                                             for label, runs in results.items()}}, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
