# SPDX-License-Identifier: GPL-3.0-or-later
"""Our accuracy per scene of the validation suite, against each scene's cached Cycles truth (not a test).

    .venv/bin/python benchmarks/validation_suite.py [--quick] [--regenerate-reference] [--only NAME ...]
        [--skip-visibility-benchmarks] [--results-dir DIR]

The suite: the scenes of tools/build_validation_scenes.py (``benchmarks/scenes/<name>.blend``, each
stressing one kind of light path) and demo.blend. Per scene, our renderer (FrameRenderer, the
scene's saved settings: the add-on's defaults for the suite's scenes) renders one frame at 240x180
after a warm-up frame, and its indirect light is compared with Cycles' one-bounce truth
(DiffInd·DiffCol + GlossInd·GlossCol, max bounces 1, two seeds; cached in
``benchmarks/reference/<name>_indirect_240x180.npz``, float16 for the suite's scenes, the demo's is
the speed/accuracy benchmark's float32 one) over the pixels covered in both:

* mean indirect ours / Cycles;
* relative RMSE, noise-corrected (sqrt(mean((x − a)(x − b))) / mean, a and b the truth's seeds:
  the truth's noise is not charged to us) and plain (against the seeds' mean, the truth's noise
  included);
* robust relative RMSE: ours and the truth (each seed) clamped at the truth's 99.5th percentile
  (over covered pixels and RGB) first, so that a few extreme highlight pixels (caustic peaks,
  fireflies) do not decide the figure; noise-corrected and plain;
* diffuse and specular splits: noise-corrected relative RMSE of our indirect diffuse against
  Cycles' DiffInd·DiffCol and of our indirect specular against GlossInd·GlossCol, and each one's
  share of Cycles' indirect light;
* our frame time (the sum of the second frame's passes: informative, this machine is shared) and
  the truth's own noise (RMS of its seeds' difference / 2, relative to its mean).

A full run (not --quick or --only) also measures VSGL visibility's cost at N = 64 / 256 / 1024
(benchmarks/visibility_cost.py), its flicker under a turning light, a static scene's consecutive
frames and the peak memory at 1024², N = 4096 (benchmarks/visibility_stability.py), and appends
them (``--skip-visibility-benchmarks`` leaves them out).

Writes ``benchmarks/results/validation_suite.{md,json}`` (``_quick`` with --quick: two scenes, for
the smoke test) and prints the markdown. With every truth cached a full run takes about 30 s
(many_lights alone ~10 s: 24 lights, each with its RSM views); rendering the suite's seven truths
(--regenerate-reference, or a missing file) takes about 18 min here, the demo's 4 min more.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
# The add-on, the tests' Cycles helpers (cycles_truth), this folder (tradeoff, gpu_timing) and the
# scene builder (its scene list and what each scene tests).
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from build_validation_scenes import RESOLUTION, SCENES, purpose, scene_path  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.demo import COVERED, DEMO, RESULTS_DIR, log  # noqa: E402
from tradeoff.metrics import Errors  # noqa: E402
from tradeoff.suite_figures import before_after, plot  # noqa: E402
from tradeoff.truth import load_reference  # noqa: E402

DEMO_PURPOSE = ("demo.blend: a spot-lit glossy red floor bounces onto white walls and a glossy gold sphere "
                "(glossy-to-glossy, caustics).")
# Cycles samples per seed of each truth: as many as keep its noise small against its mean within
# the time budget (measured per scene: the caustic scenes converge slowest, diffuse rooms fastest).
TRUTH_SAMPLES = {"occluder": 2048, "sun_courtyard": 1024, "sun_ground": 1024, "cornell_box": 1024, "closed_room": 1024,
                 "caustic_panel": 8192, "glossy_floor_object": 4096, "many_lights": 2048, "demo": 4096,
                 "polished_metal_floor": 4096, "occluded_reflector": 4096}
QUICK_SCENES = ("occluder", "cornell_box")
# The README's before/after image of VSGL visibility (full runs only).
BEFORE_AFTER = "occluder"
BEFORE_AFTER_IMAGE = REPO / "docs" / "images" / "visibility-before-after.png"
# The README's image of the glossy VPL pass (004): its caustic scene with the pass off, on, and Cycles.
CAUSTICS_SCENE = "caustic_panel"
CAUSTICS_IMAGE = REPO / "docs" / "images" / "caustics-off-on.png"
# The caustic region: Cycles' brightest 2 % of covered pixels (luminance of the RGB mean).
CAUSTIC_FRACTION = 0.02
# The truth's values above this percentile (covered pixels, RGB) are the "extreme highlights".
ROBUST_PERCENTILE = 99.5


def suite() -> list[tuple[str, Path, str]]:
    """(name, .blend, what it tests) of every scene, in the table's order."""
    return [(name, scene_path(name), purpose(name)) for name in SCENES] + [("demo", DEMO, DEMO_PURPOSE)]


def measure_suite(measure, only=None) -> list:
    """``measure(name, path)`` of every scene of the suite (of ``only``'s names when given), the add-on
    registered (scene.vsgl exists only then) on a GPU context: the per-scene benchmarks' loop."""
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    register()
    ensure_gpu_context()
    return [measure(name, path) for name, path, _ in suite() if not only or name in only]


def budget_scene(name: str, path: Path):
    """(saved settings, Cycles truth, SceneDescription, the frame plan in Budget mode through the
    camera, that plan's pinned settings) of a scene at RESOLUTION: the passes Budget runs there,
    held fixed as budget.choose fixes them (the Budget benchmarks' start)."""
    from vsgl_addon.planner import plan_frame

    width, height = RESOLUTION
    saved, truth, description = scene_with_truth(name, path, width, height)
    camera = description.camera
    plan = plan_frame(description, saved.overridden(quality_mode="budget"), None,
                      camera.projection_matrix() @ camera.view_matrix())
    return saved, truth, description, plan, plan.pinned(saved)


def open_scene(path: Path):
    import bpy

    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    return bpy.context.scene


def scene_with_truth(name: str, path: Path, width: int, height: int, regenerate: bool = False):
    """(the scene's saved settings, its Cycles one-bounce truth (tradeoff.truth.load_reference, cached
    as float16, the demo's as float32), its SceneDescription): the truth's render switches the scene
    to Cycles, so the file is opened again before it is described for ours."""
    import bpy

    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    scene = open_scene(path)
    settings = VSGLSettings.from_properties(scene.vsgl)
    truth = load_reference(scene, width, height, TRUTH_SAMPLES[name], regenerate, name=name, source=path,
                           dtype=np.float32 if name == "demo" else np.float16)
    open_scene(path)
    return settings, truth, extract_scene(bpy.context.evaluated_depsgraph_get())


def sampled_pixels(bench: Bench, truth: dict, stride: int, materials=None):
    """The shading inputs of every `stride`-th pixel (both ways) of `bench`'s camera G-buffer that
    it and the truth cover (of the named `materials` only, when given), float64: (pick (h, w) mask,
    position, normal, view (unit, towards the eye), Rd, F0, GGX α (clamped at 1e-3)), each (P, ...)."""
    from vsgl_addon.passes.gpu_util import read_texture

    width, height = bench.width, bench.height
    arrays = bench.gbuffer.to_numpy()
    rd_img = read_texture(bench.inputs.diffuse_reflectance, width, height)[..., :3]
    f0_img = read_texture(bench.inputs.specular_f0, width, height)[..., :3]
    pick = np.zeros((height, width), bool)
    pick[stride // 2::stride, stride // 2::stride] = True
    pick &= (arrays["position"][..., 3] > COVERED) & (truth["alpha"] > COVERED)
    if materials is not None:
        wanted = [i for i, name in enumerate(bench.materials) if name in materials]
        pick &= np.isin(bench.material_index, wanted)
    position = arrays["position"][..., :3][pick].astype(np.float64)
    normal = arrays["normal"][..., :3][pick].astype(np.float64)
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-30)
    alpha = np.maximum(arrays["normal"][..., 3][pick].astype(np.float64) ** 2, 1e-3)
    rd, f0 = rd_img[pick].astype(np.float64), f0_img[pick].astype(np.float64)
    camera = np.asarray(bench.gbuffer.camera_vector, np.float64).reshape(-1)
    view = camera[:3] - position if camera.shape[0] == 3 or camera[3] > 0 else np.broadcast_to(camera[:3], position.shape)
    view = view / np.linalg.norm(view, axis=-1, keepdims=True)
    return pick, position, normal, view, rd, f0, alpha


def robust_errors(truth: dict, mask: np.ndarray, ours: np.ndarray) -> dict:
    """Relative RMSE (noise-corrected and plain) with ours and the truth's seeds clamped at the
    truth's ROBUST_PERCENTILE-th percentile: a few extreme pixels no longer dominate."""
    seeds = [(truth["diffuse_a"] + truth["glossy_a"])[mask], (truth["diffuse_b"] + truth["glossy_b"])[mask]]
    limit = float(np.percentile(truth["indirect"][mask], ROBUST_PERCENTILE))
    x = np.minimum(ours[mask], limit)
    a, b = (np.minimum(seed, limit) for seed in seeds)
    mean = float(np.mean(np.minimum(truth["indirect"][mask], limit)))
    corrected = math.sqrt(max(float(np.mean((x - a) * (x - b))), 0.0))
    measured = float(np.sqrt(np.mean((x - 0.5 * (a + b)) ** 2)))
    return {"rel_robust": corrected / mean, "rel_robust_measured": measured / mean, "robust_limit": limit}


def frame_errors(truth: dict, frame) -> tuple[dict, np.ndarray]:
    """(tradeoff.metrics.Errors' figures of `frame`'s indirect light over the pixels it and the truth
    cover, with robust_errors' added; the indirect diffuse + specular image, float64)."""
    check = Errors(truth, frame.coverage)
    both = check(frame.indirect_diffuse, frame.indirect_specular)
    ours = (frame.indirect_diffuse + frame.indirect_specular).astype(np.float64)
    both.update(robust_errors(truth, check.mask, ours))
    return both, ours


def measure_scene(name: str, path: Path, about: str, width: int, height: int, regenerate: bool) -> dict:
    from vsgl_addon.renderer import FrameRenderer

    settings, truth, description = scene_with_truth(name, path, width, height, regenerate)
    renderer = FrameRenderer()
    visibility = {}
    images = {"truth": truth["indirect"]}
    try:
        # Both ways of VSGL visibility (000 §5), whatever the scene saved; the saved way is the row.
        for shadowed in (not settings.visibility, settings.visibility):
            for _ in range(2):  # the first frame compiles shaders and warms llvmpipe
                frame = renderer.render(description, settings.overridden(visibility=shadowed), width, height)
            both, ours = frame_errors(truth, frame)
            images["on" if shadowed else "off"] = ours
            visibility["on" if shadowed else "off"] = {
                "mean_ratio": both["mean_ratio"], "rel": both["rel"], "rel_robust": both["rel_robust"],
                "frame_seconds": float(sum(frame.timings.values())), "ism_seconds": float(frame.timings.get("ism", 0.0)),
                "shading_seconds": float(frame.timings.get("vsgl_shading", 0.0))}
        # The glossy VPL pass (004) the other way from the saved settings: does any scene get worse?
        caustics = {}
        frames = {settings.caustics: frame}
        frames[not settings.caustics] = renderer.render(
            description, settings.overridden(caustics=not settings.caustics), width, height)
        mask = Errors(truth, frame.coverage).mask
        luminance = truth["indirect"][mask].astype(np.float64).mean(axis=-1)
        region = np.zeros_like(mask)
        region[mask] = luminance >= np.quantile(luminance, 1.0 - CAUSTIC_FRACTION)
        truth_region = float(truth["indirect"][region].astype(np.float64).mean())
        for on, shown in frames.items():
            both, ours = frame_errors(truth, shown)
            images["caustics_on" if on else "caustics_off"] = ours
            caustics["on" if on else "off"] = {
                "mean_ratio": both["mean_ratio"], "rel": both["rel"], "rel_robust": both["rel_robust"],
                "caustic_region_ratio": float(ours[region].mean()) / truth_region,
                "vpls": int(shown.counts.get("vpls", 0)), "vpls_per_pixel": float(shown.counts.get("vpls_per_pixel", 0.0)),
                "vpl_seconds": float(shown.timings.get("vpl_culling", 0.0) + shown.timings.get("vpl_extraction", 0.0)),
                "frame_seconds": float(sum(shown.timings.values()))}
    finally:
        renderer.free()
    errors = Errors(truth, frame.coverage)
    figures = errors(frame.indirect_diffuse, frame.indirect_specular)
    ours = (frame.indirect_diffuse + frame.indirect_specular).astype(np.float64)
    figures.update(robust_errors(truth, errors.mask, ours))
    # Where the error is: per material of the camera's G-buffer (the same pixels as the frame's).
    bench = Bench(description, width, height)
    try:
        figures["regions"] = errors.by_region(ours, bench.material_index, bench.materials)
    finally:
        bench.free()
    figures.update({
        "scene": name, "blend": str(path.relative_to(REPO)), "purpose": about,
        "settings": str(settings), "settings_values": settings, "frame_seconds": float(sum(frame.timings.values())), "timings": frame.timings,
        "counts": frame.counts, "covered_pixels": int(errors.mask.sum()), "visibility": visibility,
        "caustics": caustics,
        "mean_truth": errors.mean, "mean_ours": float(ours[errors.mask].mean()),
        "truth_samples_per_seed": int(truth["samples_per_seed"]),
        "truth_seconds": float(np.sum(truth["seconds_per_seed"])),
        "truth_noise_relative": float(truth["noise_relative"]),
        "truth_file": str(truth["path"].relative_to(REPO)),
        "truth_file_bytes": truth["path"].stat().st_size, "images": images})
    log(f"{name}: mean ratio {figures['mean_ratio']:.3f}, rel RMSE {figures['rel']:.3f} "
        f"(plain {figures['rel_measured']:.3f}, robust {figures['rel_robust']:.3f}), "
        f"frame {figures['frame_seconds'] * 1e3:.0f} ms, truth noise {figures['truth_noise_relative']:.3f}")
    return figures


def _short(settings) -> str:
    return (f"N = {settings.vsgl_count}, RSM {settings.rsm_size}², ISM {settings.ism_size}², "
            f"{settings.ism_points} points per ISM")


def _shown_path(path: Path) -> str:
    path = path.resolve()
    return str(path.relative_to(REPO)) if path.is_relative_to(REPO) else str(path)


def markdown(rows: list[dict], renderer: str, quick: bool, run_seconds: float) -> str:
    width, height = rows[0]["resolution"] if rows else RESOLUTION
    lines = [f"# Validation suite: our indirect light against Cycles, per scene{' (--quick)' if quick else ''}", "",
             f"`.venv/bin/python benchmarks/validation_suite.py{' --quick' if quick else ''}`; {width}x{height}, "
             f"each scene's saved settings, GPU: {renderer}; run {run_seconds:.0f} s.", "",
             "Ratios and errors over the pixels covered in both images. rel RMSE: noise-corrected "
             "(the truth's own noise is not charged to us) / plain (measured against the mean of the "
             f"truth's two seeds). Robust: both images clamped at the truth's {ROBUST_PERCENTILE:g}th "
             "percentile first. Diffuse / specular: noise-corrected relative RMSE of each split against "
             "Cycles' DiffInd·DiffCol / GlossInd·GlossCol; spec share: GlossInd·GlossCol's share of Cycles' "
             "indirect. Frame time: informative (shared machine, llvmpipe). Truth noise: RMS of the two "
             "seeds' difference / 2, relative to the truth's mean.", "",
             "| scene | mean ours / Cycles | rel RMSE | rel RMSE plain | robust rel RMSE | robust plain | "
             "diffuse rel RMSE | specular rel RMSE | spec share | frame ms | truth spp × 2 | truth noise |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['mean_ratio']:.3f} | {r['rel']:.3f} | {r['rel_measured']:.3f} | "
                     f"{r['rel_robust']:.3f} | {r['rel_robust_measured']:.3f} | {r['rel_diffuse']:.3f} | "
                     f"{r['rel_specular']:.3f} | {r['share_specular']:.2f} | {r['frame_seconds'] * 1e3:.0f} | "
                     f"{r['truth_samples_per_seed']} | {r['truth_noise_relative']:.3f} |")
    lines += ["", "**VSGL visibility** (imperfect shadow maps, 000 §5; `--visibility` of the render command), "
              "off against on, same settings otherwise: mean ours / Cycles, noise-corrected and robust relative "
              "RMSE, and frame, shadow-map and shading time (ms).", "",
              "| scene | mean off | mean on | rel RMSE off | rel RMSE on | robust off | robust on | "
              "frame off | frame on | ISM | shading off | shading on |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        off, on = r["visibility"]["off"], r["visibility"]["on"]
        lines.append(f"| {r['scene']} | {off['mean_ratio']:.3f} | {on['mean_ratio']:.3f} | {off['rel']:.3f} | "
                     f"{on['rel']:.3f} | {off['rel_robust']:.3f} | {on['rel_robust']:.3f} | "
                     f"{off['frame_seconds'] * 1e3:.0f} | {on['frame_seconds'] * 1e3:.0f} | {on['ism_seconds'] * 1e3:.0f} | "
                     f"{off['shading_seconds'] * 1e3:.0f} | {on['shading_seconds'] * 1e3:.0f} |")
    lines += ["", "**Caustics (glossy VPLs, 004)** off against on (`--caustics` of the render command), same "
              "settings otherwise; the pass runs only where a lit sharp reflector exists (VPLs > 0). Caustic "
              f"region: Cycles' brightest {100 * CAUSTIC_FRACTION:g} % of covered pixels, its mean ours / Cycles. "
              "VPL ms: extraction + culling and shading.", "",
              "| scene | VPLs | VPLs per pixel | mean off | mean on | rel RMSE off | rel RMSE on | robust off | "
              "robust on | caustic region off | caustic region on | VPL ms | frame off | frame on |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        off, on = r["caustics"]["off"], r["caustics"]["on"]
        lines.append(f"| {r['scene']} | {on['vpls']} | {on['vpls_per_pixel']:.0f} | {off['mean_ratio']:.3f} | "
                     f"{on['mean_ratio']:.3f} | {off['rel']:.3f} | {on['rel']:.3f} | {off['rel_robust']:.3f} | "
                     f"{on['rel_robust']:.3f} | {off['caustic_region_ratio']:.3f} | {on['caustic_region_ratio']:.3f} | "
                     f"{on['vpl_seconds'] * 1e3:.0f} | {off['frame_seconds'] * 1e3:.0f} | {on['frame_seconds'] * 1e3:.0f} |")
    lines += ["", "Where the error is (the material with the largest share of the noise-corrected squared "
              "error: its share, its relative RMSE and mean ratio ours / Cycles, its share of Cycles' light):", ""]
    for r in rows:
        worst, region = max(r["regions"].items(), key=lambda item: item[1]["error_share"])
        lines.append(f"- {r['scene']}: {worst} — {100 * region['error_share']:.0f} % of the error, rel RMSE "
                     f"{region['rel']:.2f}, mean ratio {region['mean_ratio']:.2f}, {100 * region['light_share']:.0f} % "
                     "of the light")
    lines += ["", "What each scene tests:", ""]
    lines += [f"- **{r['scene']}** (`{r['blend']}`, {r['settings']}): {r['purpose']}" for r in rows]
    lines += ["", "Truths: " + "; ".join(
        f"{r['scene']} {r['truth_samples_per_seed']} × 2 spp in {r['truth_seconds']:.0f} s "
        f"({r['truth_file_bytes'] / 1e3:.0f} kB)" for r in rows) + "."]
    return "\n".join(lines) + "\n"


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=f"only {', '.join(QUICK_SCENES)} (smoke test)")
    parser.add_argument("--only", nargs="+", help="only these scenes")
    parser.add_argument("--regenerate-reference", action="store_true", help="render the Cycles truths again")
    parser.add_argument("--reference-only", action="store_true", help="make the missing truths, then stop")
    parser.add_argument("--skip-visibility-benchmarks", action="store_true",
                        help="leave out the visibility cost, stability and memory measures (always left out with --quick)")
    parser.add_argument("--results-dir", type=Path, default=RESULTS_DIR,
                        help="where the results go (default benchmarks/results; concurrent runs each their own)")
    return parser.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    started = time.perf_counter()
    from vsgl_addon import register

    register()  # scene.vsgl exists only with the add-on registered
    from vsgl_addon.gpu_context import ensure_gpu_context

    renderer = ensure_gpu_context()
    width, height = RESOLUTION
    chosen = args.only or (QUICK_SCENES if args.quick else None)
    scenes = [s for s in suite() if chosen is None or s[0] in chosen]
    if args.reference_only:
        from tradeoff.truth import reference_path

        for name, path, _ in scenes:
            if args.regenerate_reference or not reference_path(width, height, name).is_file():
                load_reference(open_scene(path), width, height, TRUTH_SAMPLES[name], True, name=name, source=path,
                               dtype=np.float32 if name == "demo" else np.float16)
        return 0
    rows = []
    for name, path, about in scenes:
        row = measure_scene(name, path, about, width, height, args.regenerate_reference)
        row["resolution"] = [width, height]
        rows.append(row)
    suffix = "_quick" if args.quick else ""
    extra = {}
    if not (args.quick or args.only or args.skip_visibility_benchmarks):
        # VSGL visibility's cost at N = 64 / 256 / 1024 (480x360, RSM 128²), its stability under a
        # turning light and on a static scene, and its peak memory at 1024², N = 4096.
        import visibility_cost
        import visibility_stability

        extra["visibility_cost"] = visibility_cost.measure(DEMO, (64, 256, 1024))
        extra["visibility_stability"] = visibility_stability.measure()
    results = args.results_dir
    results.mkdir(parents=True, exist_ok=True)
    images = {row["scene"]: row.pop("images") for row in rows}
    chosen_settings = {row["scene"]: row.pop("settings_values") for row in rows}
    # The README's image is rewritten only by a run into the committed results.
    image = BEFORE_AFTER_IMAGE if results.resolve() == RESULTS_DIR.resolve() else results / BEFORE_AFTER_IMAGE.name
    if BEFORE_AFTER in images and not args.quick:
        shown = images[BEFORE_AFTER]
        before_after(shown["truth"], shown["off"], shown["on"], image,
                     f"{BEFORE_AFTER}: indirect light only, {width}x{height}, {_short(chosen_settings[BEFORE_AFTER])}")
    if CAUSTICS_SCENE in images and not args.quick:
        shown = images[CAUSTICS_SCENE]
        caustics_image = CAUSTICS_IMAGE if results.resolve() == RESULTS_DIR.resolve() else results / CAUSTICS_IMAGE.name
        before_after(shown["truth"], shown["caustics_off"], shown["caustics_on"], caustics_image,
                     f"{CAUSTICS_SCENE}: indirect light only, {width}x{height}, {_short(chosen_settings[CAUSTICS_SCENE])}",
                     labels=("Caustics (VPL) off: VSGLs", "Caustics (VPL) on"))
    plot(rows, results / f"validation_suite{suffix}.png")
    text = markdown(rows, renderer, args.quick, time.perf_counter() - started)
    if extra:
        text += "\n" + visibility_cost.markdown(extra["visibility_cost"], DEMO.name, renderer)
        text += "\n" + visibility_stability.markdown(extra["visibility_stability"])
    text += (f"\nPlot (mean ratio and relative RMSE, visibility off and on): "
             f"`{_shown_path(results / f'validation_suite{suffix}.png')}`."
             + ("" if args.quick or BEFORE_AFTER not in images else f" Before/after image: `{_shown_path(image)}`.") + "\n")
    (results / f"validation_suite{suffix}.md").write_text(text)
    (results / f"validation_suite{suffix}.json").write_text(json.dumps(
        {"renderer": renderer, "quick": args.quick, "resolution": [width, height], "scenes": rows, **extra,
         "robust_percentile": ROBUST_PERCENTILE, "covered_threshold": COVERED}, indent=1, default=str))
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
