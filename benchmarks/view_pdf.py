# SPDX-License-Identifier: GPL-3.0-or-later
"""The view-dependent PDF (000 §5, reference/brsm.py) against the light PDF, per suite scene (not a test).

    .venv/bin/python benchmarks/view_pdf.py [--only NAME ...] [--results-dir DIR]
        [--flicker-frames F] [--flicker-seeds S] [--skip-flicker] [--defensive B ...] [--repeats R]
        [--seeds S] [--other-normalization] [--every-light] [--name STEM]

Per scene of benchmarks/validation_suite.py (its cached Cycles truths, 240x180, each scene's saved
settings: N = 256, visibility on), one frame with ``pdf = light`` and one with ``pdf = view``, after
a warm-up frame of each: mean indirect ours / Cycles and the noise-corrected relative RMSE, and the
median over ``--repeats`` frames of each PDF (alternating) of the frame time, the light passes' time
(RSMs, view PDF, VSGL generation) and the process's CPU time: the view PDF's cost against the light
PDF's in the same run. Each scene's footprint ratio: the surface area of the lights' RSM texels
(settings' RSM size, texels with flux; a sun's texel is its area on the sun's plane over cos θ,
another light's its solid angle times d² over cos θ) over the part of it the camera sees (texels
whose position is the camera G-buffer's at their pixel, within two texel footprints).

Every error is the mean over ``--seeds`` lattice seeds (the scene's seed and the next ones, 4 by
default; one seed's relative RMSE moves by ±10 % on the sun scenes), each seed's in the JSON.
``--other-normalization``: also the view PDF's frames with the per-view normalization of the VSGL
powers to the RSM total the other way (pipeline.NORMALIZE_VIEW_PDF_POWERS flipped; off by default).
``--every-light``: the view PDF for every light type, not only the planner's
(planner.VIEW_PDF_LIGHT_TYPES, suns): the measurement behind that rule. ``--name``: the results' stem.

Targets (the issue's): on a scene whose light's footprint is at least 10x the camera's view
(sun_courtyard: a sun over a 40 m ground; sun_ground: a sun over an open 60 m ground) the view PDF's
relative RMSE at least 20 % lower; no scene
worse by more than 5 %; the modified/original kernel flicker ratio with the view PDF at or under
0.5. Flicker, on that scene with ``pdf = view`` at its saved settings (seed 0), F frames of each
motion: *light*, the sun turning 1°/frame about world Z (its azimuth: the shadows move), and
*camera*, the camera panning 0.5°/frame about world Z (the G-buffer, so the view PDF, moves). The
measure is the speed/accuracy benchmark's (tradeoff/flicker.py): mean |I(t) − I(t−1)| over the
pixels covered in every frame and RGB, relative to the mean, per kernel, and its ratio modified /
original. Both motions put the lighting's real change in that measure (for the camera: the
image's own motion), which both kernels share; with S > 0 seeds each frame is also rendered with
lattice seeds 1..S and the ratio of flicker proper (the change of I − Ī, Ī the seed average) is
reported as well. ``--defensive B ...``: each scene's view-PDF frame again at each defensive share β of
the mixture (reference/brsm.py), against the same run's light-PDF frame: the sweep that chooses the one
global default. Writes ``view_pdf.{md,json}`` and prints the markdown.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from validation_suite import open_scene, scene_with_truth, suite  # noqa: E402
from tradeoff.demo import RESULTS_DIR  # noqa: E402
from tradeoff.metrics import Errors  # noqa: E402

WIDTH, HEIGHT = 240, 180
LARGE_FOOTPRINT = "sun_courtyard"
FOOTPRINT_TARGET = 10.0
FLICKER_TARGET = 0.5
#: Degrees per frame of each flicker motion.
MOTION_STEP = {"light": 1.0, "camera": 0.5}


def footprint_ratio(description, settings) -> dict:
    """Surface area of the lights' RSM texels with flux over the part of it the camera sees (see the
    module documentation), with both areas in m²."""
    from vsgl_addon.passes.gbuffer import render_gbuffer
    from vsgl_addon.passes.rsm import SceneGPU, render_rsm_views
    from vsgl_addon.reference.rsm import incoming_directions

    scene_gpu = SceneGPU(description)
    try:
        camera = description.camera
        view_projection = camera.projection_matrix() @ camera.view_matrix()
        gbuffer = render_gbuffer(scene_gpu, camera.view_matrix(), camera.projection_matrix(), (WIDTH, HEIGHT))
        try:
            seen_position = gbuffer.to_numpy()["position"]
        finally:
            gbuffer.free()
        total = seen = 0.0
        for index, light in enumerate(description.lights):
            for view in render_rsm_views(scene_gpu, index, settings.rsm_size):
                a = view.to_numpy()
                view.free()
                keep = a.coverage & (a.flux_white > 0.0)
                y = a.rsm.position[keep].astype(np.float64)
                n = a.rsm.normal[keep].astype(np.float64)
                n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
                mu = np.clip(np.abs(np.einsum("ij,ij->i", incoming_directions(light, y), n)), 1e-3, 1.0)
                area = a.texel_measure[keep] / mu
                if light.type != "SUN":
                    area = area * np.sum((np.asarray(light.position, np.float64) - y) ** 2, axis=-1)
                clip = np.c_[y, np.ones(len(y))] @ view_projection.T
                w = clip[:, 3]
                ndc = clip[:, :3] / np.where(np.abs(w) > 1e-30, w, 1e-30)[:, None]
                inside = (w > 0.0) & np.all(np.abs(ndc) <= 1.0, axis=1)
                px = np.clip(((ndc[:, 0] + 1.0) * 0.5 * WIDTH).astype(np.int64), 0, WIDTH - 1)
                py = np.clip(((ndc[:, 1] + 1.0) * 0.5 * HEIGHT).astype(np.int64), 0, HEIGHT - 1)
                g = seen_position[py, px]
                near = np.linalg.norm(g[:, :3] - y, axis=-1) <= np.maximum(2.0 * np.sqrt(area), 1e-2)
                visible = inside & (g[:, 3] > 0.5) & near
                total += float(area.sum())
                seen += float(area[visible].sum())
    finally:
        scene_gpu.free()
    return {"rsm_area": total, "seen_area": seen, "ratio": total / seen if seen > 0.0 else float("inf")}


def flicker(name: str, path: Path, frames: int, seeds: int) -> dict:
    """Modified / original kernel flicker with the view PDF under light and camera motion (see the
    module documentation)."""
    import bpy

    from tradeoff.demo import COVERED
    from tradeoff.flicker import mean_abs_step, turned
    from vsgl_addon.renderer import FrameRenderer
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    out = {"scene": name, "frames": frames, "seeds": seeds, "step_degrees": dict(MOTION_STEP)}
    for motion, step in MOTION_STEP.items():
        scene = open_scene(path)
        settings = VSGLSettings.from_properties(scene.vsgl).overridden(pdf="view", seed=0)
        mover = scene.camera if motion == "camera" else next(o for o in scene.objects if o.type == "LIGHT")
        base = mover.matrix_world.copy()
        images = {kernel: [] for kernel in ("modified", "original")}
        expected = {kernel: [] for kernel in images} if seeds > 0 else {}
        covered = None
        renderer = FrameRenderer()
        try:
            for frame in range(frames):
                mover.matrix_world = turned(base, step * frame, "pan")
                bpy.context.view_layer.update()
                description = extract_scene(bpy.context.evaluated_depsgraph_get())
                for kernel in images:
                    image = renderer.render(description, settings.overridden(kernel=kernel), WIDTH, HEIGHT)
                    images[kernel].append(image.indirect.astype(np.float64))
                    mask = image.coverage > COVERED
                    covered = mask if covered is None else covered & mask
                    if kernel in expected:
                        total = sum(renderer.render(description, settings.overridden(kernel=kernel, seed=seed),
                                                    WIDTH, HEIGHT).indirect.astype(np.float64)
                                    for seed in range(1, seeds + 1))
                        expected[kernel].append(total / seeds)
        finally:
            renderer.free()
            mover.matrix_world = base
        row = {}
        for kernel, sequence in images.items():
            sequence = [image[covered] for image in sequence]
            mean = float(np.mean([image.mean() for image in sequence]))
            row[kernel] = {"change": mean_abs_step(sequence), "relative": mean_abs_step(sequence) / mean,
                           "mean": mean, "finite": bool(all(np.all(np.isfinite(i)) for i in sequence))}
            if kernel in expected:
                errors = [i - e[covered] for i, e in zip(sequence, expected[kernel])]
                row[kernel]["flicker_proper_relative"] = mean_abs_step(errors) / mean
        row["ratio"] = row["modified"]["relative"] / row["original"]["relative"]
        if expected:
            row["flicker_proper_ratio"] = (row["modified"]["flicker_proper_relative"]
                                           / row["original"]["flicker_proper_relative"])
        out[motion] = row
        print(f"{name} flicker, {motion} motion: modified / original {row['ratio']:.3f}"
              + (f", flicker proper {row['flicker_proper_ratio']:.3f}" if expected else ""), flush=True)
    return out


def measure(name: str, path: Path, defensive=(), repeats: int = 3, seeds: int = 1, other_normalization: bool = False) -> dict:

    from vsgl_addon.passes.contract import LIGHT_PASSES
    from vsgl_addon.reference import brsm
    from vsgl_addon.renderer import FrameRenderer

    settings, truth, description = scene_with_truth(name, path, WIDTH, HEIGHT)
    renderer = FrameRenderer()
    row = {"scene": name, "footprint": footprint_ratio(description, settings)}
    try:
        for pdf in ("light", "view"):  # warm-up: every shader of both compiled
            renderer.render(description, settings.overridden(pdf=pdf), WIDTH, HEIGHT)
        times = {"light": [], "view": []}
        for index in range(max(int(repeats), 1)):
            for pdf in ("light", "view") if index % 2 == 0 else ("view", "light"):
                cpu = time.process_time()
                frame = renderer.render(description, settings.overridden(pdf=pdf), WIDTH, HEIGHT)
                cpu = time.process_time() - cpu
                times[pdf].append((float(sum(frame.timings.values())), float(frame.timings[LIGHT_PASSES.name]), cpu))
                if index == 0:  # the frames of a seed are the same image
                    errors = Errors(truth, frame.coverage)(frame.indirect_diffuse, frame.indirect_specular)
                    row[pdf] = {"mean_ratio": errors["mean_ratio"], "rel": errors["rel"],
                                "view_pdf": frame.plan.decisions["view_pdf"].reason,
                                "seeds": {str(settings.seed): {"mean_ratio": errors["mean_ratio"],
                                                               "rel": errors["rel"]}}}
        for pdf, values in times.items():
            frame_seconds, light_seconds, cpu_seconds = (statistics.median(v) for v in zip(*values))
            row[pdf].update(frame_seconds=frame_seconds, light_pass_seconds=light_seconds, cpu_seconds=cpu_seconds)
        # Further lattice seeds: one seed's relative RMSE moves by ±10 % on the sun scenes
        # (N = 256 kernels over a large map), so each PDF's figures are the means over the seeds.
        for pdf in ("light", "view"):
            for seed in range(settings.seed + 1, settings.seed + max(int(seeds), 1)):
                frame = renderer.render(description, settings.overridden(pdf=pdf, seed=seed), WIDTH, HEIGHT)
                errors = Errors(truth, frame.coverage)(frame.indirect_diffuse, frame.indirect_specular)
                row[pdf]["seeds"][str(seed)] = {"mean_ratio": errors["mean_ratio"], "rel": errors["rel"]}
            row[pdf]["mean_ratio"] = float(np.mean([e["mean_ratio"] for e in row[pdf]["seeds"].values()]))
            row[pdf]["rel"] = float(np.mean([e["rel"] for e in row[pdf]["seeds"].values()]))
        if other_normalization:  # the view PDF's frames with the other per-view power normalization, same seeds
            from vsgl_addon import pipeline

            default_normalization = pipeline.NORMALIZE_VIEW_PDF_POWERS
            pipeline.NORMALIZE_VIEW_PDF_POWERS = not default_normalization
            try:
                errors = [Errors(truth, frame.coverage)(frame.indirect_diffuse, frame.indirect_specular)
                          for frame in (renderer.render(description, settings.overridden(pdf="view", seed=int(seed)),
                                                        WIDTH, HEIGHT) for seed in row["light"]["seeds"])]
            finally:
                pipeline.NORMALIZE_VIEW_PDF_POWERS = default_normalization
            rel = float(np.mean([e["rel"] for e in errors]))
            row["other_normalization"] = {"normalized": not default_normalization,
                                          "mean_ratio": float(np.mean([e["mean_ratio"] for e in errors])), "rel": rel,
                                          "rel_change": rel / row["light"]["rel"] - 1.0}
        default = brsm.DEFENSIVE_SHARE
        try:
            for share in defensive:  # the same frame with another β of the mixture, same run
                brsm.DEFENSIVE_SHARE = float(share)
                rel = float(np.mean([
                    Errors(truth, frame.coverage)(frame.indirect_diffuse, frame.indirect_specular)["rel"]
                    for frame in (renderer.render(description, settings.overridden(pdf="view", seed=int(seed)),
                                                  WIDTH, HEIGHT) for seed in row["light"]["seeds"])]))
                row.setdefault("defensive", {})[f"{share:g}"] = {"rel": rel, "rel_change": rel / row["light"]["rel"] - 1.0}
        finally:
            brsm.DEFENSIVE_SHARE = default
    finally:
        renderer.free()
    row["rel_change"] = row["view"]["rel"] / row["light"]["rel"] - 1.0
    print(f"{name}: footprint {row['footprint']['ratio']:.1f}x the view, rel RMSE light {row['light']['rel']:.3f}, "
          f"view {row['view']['rel']:.3f} ({100 * row['rel_change']:+.1f} %)", flush=True)
    return row


def markdown(rows, flicker_result=None, command="") -> str:
    lines = ["# View PDF (000 §5) against the light PDF", "",
             f"`{command or '.venv/bin/python benchmarks/view_pdf.py'}`; 240×180, each scene's saved settings (N = 256, "
             "visibility on), the validation suite's cached Cycles truths; noise-corrected relative RMSE and mean "
             "ours / Cycles, each the mean over the lattice seeds (the JSON has every seed's). Footprint: "
             "the lights' RSM texels' surface area over the part of it the camera sees. Targets: on a scene whose "
             f"footprint is at least {FOOTPRINT_TARGET:g}× the view (sun_courtyard, sun_ground) at least 20 % lower with the "
             f"view PDF, no scene worse by more than 5 %, modified / original flicker with the view PDF ≤ "
             f"{FLICKER_TARGET:g}.", "",
             "Times: the median of the repeats, light and view frames alternating (a shared machine: compare "
             "within a row); light passes: the RSMs, the view PDF and VSGL generation (the `rsm_and_vsgl_generation` "
             "timing); CPU: the process's CPU seconds per frame (llvmpipe's threads included), which other "
             "processes' load does not inflate.", "",
             "| scene | footprint / view | mean light | mean view | rel RMSE light | rel RMSE view | change | "
             "frame ms light / view | light passes ms light / view | CPU s light / view |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['footprint']['ratio']:.1f} | {r['light']['mean_ratio']:.3f} | "
                     f"{r['view']['mean_ratio']:.3f} | {r['light']['rel']:.3f} | {r['view']['rel']:.3f} | "
                     f"{100 * r['rel_change']:+.1f} % | {r['light']['frame_seconds'] * 1e3:.0f} / "
                     f"{r['view']['frame_seconds'] * 1e3:.0f} | {r['light'].get('light_pass_seconds', 0) * 1e3:.0f} / "
                     f"{r['view'].get('light_pass_seconds', 0) * 1e3:.0f} | {r['light'].get('cpu_seconds', 0):.2f} / "
                     f"{r['view'].get('cpu_seconds', 0):.2f} |")
    for r in rows:
        if r["footprint"]["ratio"] >= FOOTPRINT_TARGET:
            met = r["rel_change"] <= -0.20
            lines += ["", f"{r['scene']}: footprint {r['footprint']['ratio']:.1f}× the view (at least "
                      f"{FOOTPRINT_TARGET:g}×), {100 * r['rel_change']:+.1f} % (target ≤ −20 %: {'met' if met else 'missed'})."]
    worst = max(rows, key=lambda r: r["rel_change"])
    lines += [f"Worst scene: {worst['scene']} {100 * worst['rel_change']:+.1f} % (target ≤ +5 %: "
              f"{'met' if worst['rel_change'] <= 0.05 else 'missed'})."]
    if rows and "other_normalization" in rows[0]:
        normalized = rows[0]["other_normalization"]["normalized"]
        word = "normalized" if normalized else "not normalized"
        lines += ["", f"## The view PDF {'with' if normalized else 'without'} the per-view power normalization", "",
                  f"Each view's VSGL powers {'scaled' if normalized else 'not scaled'} to its RSM total "
                  f"(pipeline.NORMALIZE_VIEW_PDF_POWERS {'on' if normalized else 'off'}), the same seeds; change "
                  "against the light PDF's relative RMSE.", "",
                  f"| scene | mean view, {word} | rel RMSE view, {word} | change |", "|---|---|---|---|"]
        for r in rows:
            u = r["other_normalization"]
            lines.append(f"| {r['scene']} | {u['mean_ratio']:.3f} | {u['rel']:.3f} | {100 * u['rel_change']:+.1f} % |")
    shares = list(rows[0].get("defensive", {})) if rows else []
    if shares:
        from vsgl_addon.reference.brsm import DEFENSIVE_SHARE

        lines += ["", "## Defensive share β of the mixture", "",
                  f"The view PDF's relative RMSE change against the light PDF (the table's light column, same run) at "
                  f"each β (the light PDF's share; the default is {DEFENSIVE_SHARE:g}), every scene.", "",
                  "| scene | " + " | ".join(f"β = {b}" for b in shares) + " |", "|---|" + "---|" * len(shares)]
        for r in rows:
            lines.append(f"| {r['scene']} | " + " | ".join(f"{100 * r['defensive'][b]['rel_change']:+.1f} %"
                                                          for b in shares) + " |")
        lines.append("| worst | " + " | ".join(f"{100 * max(r['defensive'][b]['rel_change'] for r in rows):+.1f} %"
                                                 for b in shares) + " |")
    if flicker_result:
        f = flicker_result
        lines += ["", f"## Flicker with the view PDF, modified / original kernel", "",
                  f"{f['scene']}, pdf = view, seed 0, {f['frames']} frames; light: the sun turning "
                  f"{f['step_degrees']['light']:g}°/frame about world Z; camera: the camera panning "
                  f"{f['step_degrees']['camera']:g}°/frame about world Z. Mean frame-to-frame change over the pixels "
                  "covered in every frame / mean indirect (tradeoff/flicker.py's measure; the real change of the "
                  "lighting or the image's motion is in it for both kernels)"
                  + (f"; flicker proper: the change of the deviation from the average of seeds 1..{f['seeds']}." if f["seeds"] else "."),
                  "", "| motion | modified | original | ratio | flicker proper ratio |", "|---|---|---|---|---|"]
        for motion in MOTION_STEP:
            m = f[motion]
            proper = f"{m['flicker_proper_ratio']:.3f}" if "flicker_proper_ratio" in m else "—"
            lines.append(f"| {motion} | {m['modified']['relative']:.4f} | {m['original']['relative']:.4f} | "
                         f"{m['ratio']:.3f} | {proper} |")
        worst_motion = max(MOTION_STEP, key=lambda motion: f[motion]["ratio"])
        lines += ["", f"Flicker ratio, worst motion ({worst_motion}): {f[worst_motion]['ratio']:.3f} (target ≤ "
                  f"{FLICKER_TARGET:g}: {'met' if f[worst_motion]['ratio'] <= FLICKER_TARGET else 'missed'})."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", help="only these scenes")
    parser.add_argument("--results-dir", type=Path, default=RESULTS_DIR)
    parser.add_argument("--flicker-frames", type=int, default=8)
    parser.add_argument("--flicker-seeds", type=int, default=0)
    parser.add_argument("--skip-flicker", action="store_true")
    parser.add_argument("--repeats", type=int, default=3, help="timed frames per PDF (alternating)")
    parser.add_argument("--other-normalization", action="store_true",
                        help="also the view PDF with the per-view normalization of the VSGL powers the other way")
    parser.add_argument("--every-light", action="store_true",
                        help="the view PDF for every light type, not only the planner's (suns)")
    parser.add_argument("--name", default="view_pdf", help="the results' file stem")
    parser.add_argument("--seeds", type=int, default=4,
                        help="lattice seeds (the scene's and the next ones) whose errors are averaged per PDF")
    parser.add_argument("--defensive", type=float, nargs="+", default=[],
                        help="also the view PDF at each of these defensive shares β (a sweep, same run)")
    args = parser.parse_args(argv)
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    ensure_gpu_context()
    if args.every_light:
        from vsgl_addon import planner

        planner.VIEW_PDF_LIGHT_TYPES = ("SUN", "SPOT", "POINT", "AREA")
    scenes = [(name, path) for name, path, _ in suite() if not args.only or name in args.only]
    rows = [measure(name, path, args.defensive, args.repeats, args.seeds, args.other_normalization)
            for name, path in scenes]
    flicker_result = None
    if not args.skip_flicker:
        flicker_result = next((flicker(name, path, args.flicker_frames, args.flicker_seeds)
                               for name, path in scenes if name == LARGE_FOOTPRINT), None)
    given = list(sys.argv[1:] if argv is None else argv)
    if "--results-dir" in given:  # where it wrote is not how to reproduce it
        at = given.index("--results-dir")
        del given[at:at + 2]
    command = " ".join([".venv/bin/python benchmarks/view_pdf.py"] + given)
    text = markdown(rows, flicker_result, command)
    args.results_dir.mkdir(parents=True, exist_ok=True)
    (args.results_dir / f"{args.name}.md").write_text(text, encoding="utf-8")
    (args.results_dir / f"{args.name}.json").write_text(json.dumps({"scenes": rows, "flicker": flicker_result}, indent=2),
                                                    encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
