# SPDX-License-Identifier: GPL-3.0-or-later
"""Where a scene's indirect error enters, stage by stage, with visibility (not a test): brute-force
VPLs from the GPU's RSM, their SG lobes, the VSGL clusters, and the VSGLs' visibility, each as mean
and relative RMSE against Cycles on one pixel subset.

    .venv/bin/python benchmarks/visibility_decomposition.py [--only NAME ...] [--stride S] [--samples K]
        [--skip-vpls [NAME ...]] [--k K] [--vsgl-count N] [--ism-points P] [--ism-size S] [--rsm-size S]
        [--origin-sigmas S]
        [--map-origin-sigmas S] [--max-slope T] [--filter-radius R] [--append] [--results-dir DIR]

On every S-th pixel (both ways) of the suite's 240x180 camera G-buffer, per pixel, the luminance of:

* VPL exact, exact visibility / no visibility: every RSM texel a VPL with its exact lobes
  (energy_budget.vpl_light), visibility estimated by ray-casting K VPLs per pixel drawn ∝ their
  unshadowed light (energy_budget.visible_share): what the RSM itself gives (resolution, the
  light's footprint against the camera's view, the Principled layering);
* VPL SG lobes, exact visibility / no visibility: the same VPLs with 000 Eqs. 6-7's SG lobes (the
  diffuse SG normalized over the hemisphere, as the VSGLs carry it), visibility sampled ∝ their
  own light: the lobe fit alone;
* VSGL off / maps / exact / bare: the scene's VSGL table shaded by the float64 reference
  (reference/vsgl_shading.shade, the scene's diffuse mode) without visibility, with the GPU's
  imperfect shadow maps (the shader's lookup, reference/vsgl_shading.vsgl_visibility), with the
  segment to each map's shadow origin ray-cast (hits within pipeline.VSGL_OWN_REFLECTOR_SIGMAS σv of
  it left out, as the maps leave those points out), and with the bare segment to the VSGL's mean
  (visibility_diagnosis.exact_visibility).

Against Cycles' one-bounce truth (DiffInd·DiffCol + GlossInd·GlossCol): mean ours / Cycles and the
noise-corrected relative RMSE sqrt(mean((x − a)(x − b))) / mean(truth) of the luminance (a, b the
truth's two seeds) over the subset, for all its pixels and per material. Knobs of the float64
lookups (the GPU's maps themselves stay as built): ``--origin-sigmas`` moves the exact rows' shadow
origin, ``--max-slope`` caps the maps' slope-scaled bias, ``--filter-radius`` the maps' filter;
``--map-origin-sigmas`` builds the maps themselves (and centres every row's lookups) that many σv
off the mean (passes/ism.py set_shadow_origin_sigmas); ``--k``, ``--vsgl-count``, ``--ism-points``,
``--ism-size`` and ``--rsm-size`` change the scene's settings (the RSM side the frame planner scales
per light: planner.rsm_size_for_share). The sampled visibility's
own noise (K rays per pixel) is charged to the VPL rows: their rel RMSE carries it (printed: the
standard error of the visible share, relative to the mean). Writes
``benchmarks/results/visibility_decomposition.md``.
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

from validation_suite import sampled_pixels, scene_with_truth, suite  # noqa: E402
from build_validation_scenes import RESOLUTION  # noqa: E402
from energy_budget import rsm_vpls, visible_share, vpl_light  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.demo import log  # noqa: E402
from visibility_diagnosis import exact_visibility  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
STAGES = (("vpl_exact_vis", "VPL exact lobes, exact visibility"),
          ("vpl_exact_off", "VPL exact lobes, no visibility"),
          ("vpl_sg_vis", "VPL SG lobes, exact visibility"),
          ("vpl_sg_off", "VPL SG lobes, no visibility"),
          ("vsgl_off", "VSGL, no visibility"),
          ("vsgl_maps", "VSGL, shadow maps"),
          ("vsgl_exact", "VSGL, exact (shadow origin)"),
          ("vsgl_bare", "VSGL, exact (bare segment to the mean)"))


def errors(x, a, b, truth):
    """(mean ours / Cycles, noise-corrected relative RMSE) over the given pixels."""
    mean = float(truth.mean())
    corrected = math.sqrt(max(float(np.mean((x - a) * (x - b))), 0.0))
    return float(x.mean()) / mean, corrected / mean


def decompose(name, path, stride, samples, overrides, vpls_too=True, knobs=None, seed=0):
    from vsgl_addon.passes.vsgl_shading import ISM_MAX_RADIUS
    from vsgl_addon.pipeline import VSGL_OWN_REFLECTOR_SIGMAS, build_visibility
    from vsgl_addon.reference import ism

    knobs = knobs or {}
    filter_radius = knobs.get("filter_radius", ISM_MAX_RADIUS)
    saved_slope, saved_origin = ism.ISM_MAX_SLOPE, ism.SHADOW_ORIGIN_SIGMAS
    from vsgl_addon.reference.vsgl_shading import diffuse_mode_for_kernel, shade, vsgl_visibility

    width, height = RESOLUTION
    saved, truth, description = scene_with_truth(name, path, width, height)
    settings = saved.overridden(visibility=True, **overrides)
    triangles = np.asarray(description.geometry.positions, np.float64)
    bench = Bench(description, width, height)
    stages = {}
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride)
        material = bench.material_index[pick]

        start = time.perf_counter()
        vpls = rsm_vpls(bench.scene_gpu, settings.rsm_size) if vpls_too else {"flux": []}
        rng = np.random.default_rng(seed)
        noise = {"exact": math.nan, "sg": math.nan}
        for lobes in ("exact", "sg") if vpls_too else ():
            light, _, _ = vpl_light(vpls, position, normal, view, rd, f0, alpha, lobes)
            share, error = visible_share(light, vpls, position, triangles, samples, rng)
            unshadowed = light.sum(axis=1)
            stages[f"vpl_{lobes}_off"] = unshadowed
            stages[f"vpl_{lobes}_vis"] = unshadowed * share
            noise[lobes] = float(np.sqrt(np.mean((unshadowed * error) ** 2)))
            del light
        log(f"  {name}: {len(vpls['flux'])} VPLs in {time.perf_counter() - start:.0f} s")

        vsgls, _ = bench.vsgls(settings)
        try:
            build_visibility(bench.scene_gpu, vsgls, settings)
            for key in ("vsgl_off", "vsgl_maps", "vsgl_exact", "vsgl_bare"):
                stages[key] = np.zeros(len(position))
            for table, atlas in zip(vsgls.table_arrays(), vsgls.isms):
                table = {k: np.asarray(v, np.float64) for k, v in table.items()}
                maps = atlas.count // len(table["variance"])
                _, _, terms = shade(table, position, normal, view, rd, f0, alpha,
                                    diffuse_mode=diffuse_mode_for_kernel(settings.kernel), per_term=True)
                weight = terms.sum(axis=3) @ LUMINANCE  # (P, N, 2)
                # The knobs change the float64 lookups only: the maps stay the GPU's.
                try:
                    ism.ISM_MAX_SLOPE = knobs.get("max_slope", saved_slope)
                    v_maps = vsgl_visibility(atlas.read(), maps, table, position, normal, filter_radius,
                                             surfaces=atlas.normal_offset)
                    ism.ISM_MAX_SLOPE = saved_slope
                    ism.SHADOW_ORIGIN_SIGMAS = knobs.get("origin_sigmas", saved_origin)
                    v_exact = exact_visibility(table, maps, position, triangles, VSGL_OWN_REFLECTOR_SIGMAS)
                finally:
                    ism.ISM_MAX_SLOPE, ism.SHADOW_ORIGIN_SIGMAS = saved_slope, saved_origin
                v_bare = exact_visibility(table, maps, position, triangles, 0.0, pushed=False)
                stages["vsgl_off"] += weight.sum(axis=(1, 2))
                stages["vsgl_maps"] += (weight * v_maps).sum(axis=(1, 2))
                stages["vsgl_exact"] += (weight * v_exact).sum(axis=(1, 2))
                stages["vsgl_bare"] += (weight * v_bare).sum(axis=(1, 2))
        finally:
            vsgls.free()
        names = bench.materials
    finally:
        bench.free()
    a = (truth["diffuse_a"] + truth["glossy_a"])[pick].astype(np.float64) @ LUMINANCE
    b = (truth["diffuse_b"] + truth["glossy_b"])[pick].astype(np.float64) @ LUMINANCE
    cycles = truth["indirect"][pick].astype(np.float64) @ LUMINANCE
    for key, _ in STAGES:
        stages.setdefault(key, np.full(len(cycles), math.nan))
    rows = {"all": {key: errors(stages[key], a, b, cycles) for key, _ in STAGES}}
    shares = {"all": 1.0}
    for index in np.unique(material):
        here = material == index
        if here.sum() < 8 or cycles[here].sum() <= 0.0:
            continue
        label = names[index] if 0 <= index < len(names) else str(index)
        rows[label] = {key: errors(stages[key][here], a[here], b[here], cycles[here]) for key, _ in STAGES}
        shares[label] = float(cycles[here].sum() / cycles.sum())
    result = {"pixels": int(pick.sum()), "vpls": len(vpls["flux"]), "rows": rows, "shares": shares,
              "vsgl_count": settings.vsgl_count, "k": settings.k, "sampling_noise": {k: v / float(cycles.mean()) for k, v in noise.items()}}
    for label, row in rows.items():
        log(f"{name} [{label}]: " + ", ".join(f"{key} {m:.3f}/{r:.3f}" for key, (m, r) in row.items()))
    return result


def markdown(results, argv_text, first=True):
    lines = ["# Where the indirect error enters, with visibility: VPLs, SG lobes, VSGLs, maps", "",
             "The module documentation of `benchmarks/visibility_decomposition.py` defines the stages. Each "
             "cell: mean ours / Cycles, then the noise-corrected relative RMSE of the luminance over the "
             "subset's pixels (not the suite's figure: fewer pixels, luminance; nan: not computed). Material "
             "rows: that material's pixels (its share of Cycles' light on the subset). Each table is one "
             "run (`--append` adds a run's table).", ""] if first else [""]
    lines += [f"`.venv/bin/python benchmarks/visibility_decomposition.py {argv_text}`", ""]
    header = "| scene / pixels | " + " | ".join(label for _, label in STAGES) + " |"
    lines += [header, "|---" * (len(STAGES) + 1) + "|"]
    for name, result in results.items():
        for label, row in result["rows"].items():
            title = (f"**{name}** ({result['pixels']} px, {result['vpls']} VPLs, N = {result['vsgl_count']}, K = {result['k']:g})"
                     if label == "all" else f"{name}: {label} ({result['shares'][label]:.0%})")
            lines.append(f"| {title} | " + " | ".join(f"{m:.3f} / {r:.3f}" for m, r in row.values()) + " |")
    lines += ["", "Sampled visibility's standard error (RMS over the pixels, relative to Cycles' mean), exact / SG "
              "lobes: " + "; ".join(f"{name} {r['sampling_noise']['exact']:.3f} / {r['sampling_noise']['sg']:.3f}"
                                   for name, r in results.items()) + "."]
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["sun_courtyard", "many_lights"])
    parser.add_argument("--stride", type=int, default=8)
    parser.add_argument("--samples", type=int, default=128, help="ray-cast VPLs per pixel")
    parser.add_argument("--vsgl-count", type=int, default=None, help="N instead of the scene's")
    parser.add_argument("--k", type=float, default=None, help="the kernel size K instead of the scene's (000 Eq. 3)")
    parser.add_argument("--ism-points", type=int, default=None, help="points per shadow map instead of the scene's")
    parser.add_argument("--ism-size", type=int, default=None, help="shadow map side instead of the scene's")
    parser.add_argument("--rsm-size", type=int, default=None,
                        help="the settings' RSM side instead of the scene's (the frame planner scales each light's)")
    parser.add_argument("--skip-vpls", nargs="*", default=None, metavar="NAME",
                        help="only the VSGL rows for these scenes (all without a name; the VPL rows take "
                             "minutes per light with many lights)")
    parser.add_argument("--origin-sigmas", type=float, default=None,
                        help="the exact rows' shadow origin this many σv off the mean (reference/ism.py "
                             "SHADOW_ORIGIN_SIGMAS; the GPU's maps keep theirs)")
    parser.add_argument("--map-origin-sigmas", type=float, default=None,
                        help="the GPU's maps built (and every row looked up) this many σv off the mean "
                             "(passes/ism.py set_shadow_origin_sigmas)")
    parser.add_argument("--max-slope", type=float, default=None,
                        help="the maps' lookup with this cap of the slope-scaled bias (reference/ism.py ISM_MAX_SLOPE)")
    parser.add_argument("--filter-radius", type=int, default=None,
                        help="the maps' lookup with this largest filter radius (passes/vsgl_shading.py ISM_MAX_RADIUS)")
    parser.add_argument("--append", action="store_true", help="add this run's table to the results file")
    parser.add_argument("--results-dir", type=Path, default=REPO / "benchmarks" / "results")
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    overrides = {key: value for key, value in (("vsgl_count", args.vsgl_count), ("k", args.k),
                                                                  ("ism_points", args.ism_points), ("ism_size", args.ism_size),
                                                                  ("rsm_size", args.rsm_size)) if value is not None}
    knobs = {key: value for key, value in (("origin_sigmas", args.origin_sigmas), ("max_slope", args.max_slope),
                                           ("filter_radius", args.filter_radius)) if value is not None}
    if args.map_origin_sigmas is not None:
        from vsgl_addon.passes.ism import set_shadow_origin_sigmas

        set_shadow_origin_sigmas(args.map_origin_sigmas)
    results = {}
    for name, path, _ in suite():
        if name in args.only:
            start = time.perf_counter()
            vpls_too = args.skip_vpls is None or (args.skip_vpls and name not in args.skip_vpls)
            results[name] = decompose(name, path, args.stride, args.samples, overrides, vpls_too, knobs)
            log(f"  ({time.perf_counter() - start:.0f} s)")
    argv_text = (f"--only {' '.join(args.only)} --stride {args.stride} --samples {args.samples}"
                 + "".join(f" --{key.replace('_', '-')} {value}" for key, value in overrides.items())
                 + "".join(f" --{key.replace('_', '-')} {value}" for key, value in knobs.items())
                 + ("" if args.map_origin_sigmas is None else f" --map-origin-sigmas {args.map_origin_sigmas}")
                 + ("" if args.skip_vpls is None else (" --skip-vpls " + " ".join(args.skip_vpls)).rstrip()))
    target = args.results_dir / "visibility_decomposition.md"
    append = args.append and target.is_file()
    text = markdown(results, argv_text, first=not append)
    args.results_dir.mkdir(parents=True, exist_ok=True)
    with target.open("a" if append else "w") as out:
        out.write(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
