# SPDX-License-Identifier: GPL-3.0-or-later
"""What our renderer is compared with on the same scene and truth: brute force (every RSM texel a
VPL), random VPLs drawn from VSGL generation's PDF, Cycles at increasing samples, and EEVEE."""

from __future__ import annotations

import math
import statistics

import numpy as np

from .bench import upload
from .demo import log
from .metrics import Errors


def brute_force_table(rsm_arrays) -> dict:
    """Every lit RSM texel of every view as its own VSGL."""
    from vsgl_addon.reference.vsgl import luminance
    from vsgl_addon.reference.vsgl_shading import per_texel_vsgls

    parts = []
    for arrays in rsm_arrays:
        table = per_texel_vsgls(arrays.rsm)
        lit = luminance(table["power"]) > 0.0
        parts.append({name: value[lit] for name, value in table.items()})
    return {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}


def random_vpl_table(rsm_arrays, count: int, seed: int) -> dict:
    """`count` texels drawn with replacement with p ∝ lum(Φ(Rd + Rs)) (VSGL generation's PDF),
    each VSGL from its moments / (count p): an unbiased estimate of the RSM's bounce light."""
    from vsgl_addon.reference.vsgl import MOMENT_CHANNELS, luminance, texel_moments, vsgl_parameters

    moments = np.concatenate([texel_moments(a.rsm).reshape(-1, MOMENT_CHANNELS) for a in rsm_arrays])
    weight = np.concatenate([luminance(a.rsm.flux_diffuse + a.rsm.flux_specular).reshape(-1) for a in rsm_arrays])
    pdf = weight / weight.sum()
    picks = np.random.default_rng(seed).choice(len(pdf), size=count, replace=True, p=pdf)
    table = vsgl_parameters(moments[picks] / (count * pdf[picks])[:, None])
    return table


def brute_and_random(bench, errors: Errors, rsm_sizes, random_rsm, counts, random_seeds, repeats,
                     fixed) -> tuple[list, list, dict]:
    """(brute force rows, random VPL rows, finite flags): brute force at each RSM size, random VPLs
    (N of `counts`, mean over `random_seeds`) from the RSM of size `random_rsm`, shaded by the same
    pass as ours; frame = fixed passes + RSM alone + shading (the CPU sampling is not counted)."""
    brute, random_rows, rsm_time, finite = [], [], {}, {}
    for rsm_size in rsm_sizes:
        arrays, rsm_time[rsm_size] = bench.rsm(rsm_size)
        table = brute_force_table(arrays)
        d, s, shading = bench.shade(upload(table), "cosine", 1)
        row = {"rsm": rsm_size, "vpls": len(table["variance"]), "shading": shading, "rsm_time": rsm_time[rsm_size],
               "frame": fixed + rsm_time[rsm_size] + shading, **errors(d, s)}
        finite[f"brute force RSM {rsm_size}"] = row["finite"]
        brute.append(row)
        log(f"brute force RSM {rsm_size}: {row['vpls']} VPLs, shading {shading:.2f} s, rel RMSE {row['rel']:.3f}")
        if rsm_size == random_rsm:
            for n in counts:
                results = []
                for seed in random_seeds:
                    d, s, shading = bench.shade(upload(random_vpl_table(arrays, n, seed)), "cosine",
                                                repeats if n <= 1024 else 1)
                    results.append({"shading": shading, **errors(d, s)})
                    finite[f"random N={n} seed {seed}"] = results[-1]["finite"]
                row = {"n": n, "rsm": rsm_size, "seeds": len(random_seeds),
                       "shading": statistics.median(r["shading"] for r in results),
                       "rmse": float(np.mean([r["rmse"] for r in results])),
                       "rel": float(np.mean([r["rel"] for r in results])),
                       "rel_min": min(r["rel"] for r in results), "rel_max": max(r["rel"] for r in results),
                       "rel_measured": float(np.mean([r["rel_measured"] for r in results])),
                       "mean_ratio": float(np.mean([r["mean_ratio"] for r in results]))}
                row["frame"] = fixed + rsm_time[rsm_size] + row["shading"]
                random_rows.append(row)
                log(f"random VPLs N={n}: shading {row['shading'] * 1e3:.0f} ms, rel RMSE {row['rel']:.3f}")
    return brute, random_rows, finite


def cycles_sweep(scene, width, height, errors: Errors, max_samples: int, seed: int = 100) -> list[dict]:
    """Cycles at 1, 2, 4, … `max_samples` samples (a seed distinct from the truth's): render wall time
    and error against the truth."""
    from cycles_truth import render_cycles

    rows = []
    samples = 1
    while samples <= max_samples:
        passes = render_cycles(scene, samples=samples, max_bounces=1, seed=seed, resolution=(width, height),
                               filter_width=0.01)
        row = {"samples": samples, "seconds": passes["seconds"],
               **errors(passes["DiffInd"][::-1] * passes["DiffCol"][::-1],
                        passes["GlossInd"][::-1] * passes["GlossCol"][::-1])}
        rows.append(row)
        log(f"Cycles {samples} spp: {row['seconds']:.2f} s, rel RMSE {row['rel']:.3f}")
        samples *= 2
    return rows


def cycles_time_to(rows: list[dict], rmse: float) -> tuple[float, str]:
    """Time Cycles needs to reach `rmse` (log-log interpolation between sample counts); with a
    qualifier '<' (below 1 sample's time) or '>' (not reached at the largest count)."""
    rows = [dict(r, rmse=max(r["rmse"], 1e-12)) for r in rows]
    rmse = max(rmse, 1e-12)
    if rmse >= rows[0]["rmse"]:
        return rows[0]["seconds"], "<"
    for lo, hi in zip(rows, rows[1:]):
        if hi["rmse"] <= rmse:
            t = (math.log(rmse) - math.log(lo["rmse"])) / (math.log(hi["rmse"]) - math.log(lo["rmse"]))
            return math.exp(math.log(lo["seconds"]) + t * (math.log(hi["seconds"]) - math.log(lo["seconds"]))), ""
    return rows[-1]["seconds"], ">"


def eevee_runs(scene, width, height, errors: Errors, with_raytracing: bool, renders: int = 2) -> dict:
    """EEVEE at the scene's settings, its indirect = Combined − Combined with every indirect source
    off; with `with_raytracing` also with ray tracing and fast GI on. Timed on the last of `renders`
    renders (the first compiles shaders)."""
    from cycles_truth import render_eevee

    eevee = scene.eevee
    samples = int(eevee.taa_render_samples)
    saved = (eevee.use_raytracing, eevee.use_fast_gi)

    def render(label):
        first = render_eevee(scene, samples=samples, resolution=(width, height))
        second = render_eevee(scene, samples=samples, resolution=(width, height)) if renders > 1 else first
        log(f"EEVEE {label}: first render {first['seconds']:.1f} s, second {second['seconds']:.2f} s")
        return second["Combined"][::-1].astype(np.float64), first["seconds"], second["seconds"]

    out = {"samples": samples, "default_raytracing": bool(saved[0]), "default_fast_gi": bool(saved[1]),
           "renders": renders}
    default, out["first_seconds"], out["seconds"] = render("as saved")
    eevee.use_raytracing = False
    eevee.use_fast_gi = False
    if saved == (False, False):
        direct_only = default  # the same settings: the default has no indirect source here
    else:
        direct_only, _, _ = render("indirect sources off")
    out["default"] = errors(default - direct_only)
    if with_raytracing:
        eevee.use_raytracing = True
        eevee.use_fast_gi = True
        traced, out["rt_first_seconds"], out["rt_seconds"] = render("ray tracing + fast GI on")
        out["raytraced"] = errors(traced - direct_only)
    eevee.use_raytracing, eevee.use_fast_gi = saved
    return out
