# SPDX-License-Identifier: GPL-3.0-or-later
"""Our renderer measured: the fixed passes of a full frame, every (kernel, N, K, RSM, positions)
configuration's time and error, what per-lobe positions cost in shading, and parameter extremes."""

from __future__ import annotations

import statistics

import numpy as np

from .demo import log


def fixed_passes(scene, description, width, height) -> tuple[float, float, object]:
    """(fixed seconds, whole frame seconds, the demo's settings) of the second of two FrameRenderer
    frames with the demo's settings: fixed = scene upload, G-buffer, direct light, read-back."""
    from vsgl_addon.renderer import FrameRenderer
    from vsgl_addon.settings import VSGLSettings

    frame_renderer = FrameRenderer()
    # The VSGLs' trade-off: without the glossy VPL pass (the demo's floor is a sharp reflector), whose
    # own figures are the validation suite's and benchmarks/vpl_caustics.py's.
    demo_settings = VSGLSettings.from_properties(scene.vsgl).overridden(caustics=False)
    for _ in range(2):
        frame = frame_renderer.render(description, demo_settings, width, height)
    frame_renderer.free()
    fixed = sum(v for name, v in frame.timings.items() if name not in ("rsm_and_vsgl_generation", "vsgl_shading"))
    full_frame = sum(frame.timings.values())
    log(f"demo frame ({demo_settings}): {full_frame * 1e3:.0f} ms, fixed passes {fixed * 1e3:.0f} ms")
    return fixed, full_frame, demo_settings


def measure_ours(bench, errors, configurations, repeats, fixed, demo_settings) -> tuple[list, dict, dict]:
    """(rows, per-material errors of the demo settings per positional distribution, finite flags)
    for each (kernel, N, K, RSM size, positions) in `configurations`, lattice seed 0."""
    from vsgl_addon.reference.vsgl_shading import diffuse_mode_for_kernel
    from vsgl_addon.settings import VSGLSettings

    ours, regions, finite = [], {}, {}
    for kernel, n, k, rsm_size, positions in configurations:
        settings = VSGLSettings(vsgl_count=n, k=k, kernel=kernel, rsm_size=rsm_size, seed=0,
                                positional_distribution=positions)
        vsgls, generation = bench.vsgls(settings)
        d, s, shading = bench.shade(vsgls.tables(), diffuse_mode_for_kernel(kernel), repeats if n <= 1024 else 1)
        row = {"kernel": kernel, "n": vsgls.vsgl_count, "k": k, "rsm": rsm_size, "positions": positions,
               "generation": generation, "shading": shading, "frame": fixed + generation + shading,
               **errors(d, s)}
        vsgls.free()
        finite[f"{kernel} N={n} K={k:g} RSM {rsm_size} {positions}"] = row["finite"]
        ours.append(row)
        if (kernel, n, k, rsm_size) == (demo_settings.kernel, demo_settings.vsgl_count, demo_settings.k,
                                        demo_settings.rsm_size):
            regions[positions] = errors.by_region(d + s, bench.material_index, bench.materials)
        log(f"{kernel:9s} N={n:5d} K={k:g} RSM {rsm_size:3d} {positions:8s}: gen {generation * 1e3:.0f} ms, "
            f"shading {shading * 1e3:.0f} ms, rel RMSE {row['rel']:.3f}, mean ratio {row['mean_ratio']:.3f}")
    return ours, regions, finite


def position_cost(bench, n, rsm_size, runs) -> dict:
    """What per-lobe positions cost in shading: one table with shared positions, shaded with the
    position terms computed once per VSGL (what "shared" does) and once per lobe (what "per-lobe"
    does), alternating `runs` times, in this process."""
    from vsgl_addon.passes.vsgl_shading import VSGLTable
    from vsgl_addon.settings import VSGLSettings

    vsgls, _ = bench.vsgls(VSGLSettings(vsgl_count=n, rsm_size=rsm_size, positional_distribution="shared"))
    once = vsgls.tables()
    twice = [VSGLTable(table.texture, table.count, False) for table in once]
    cost = {"n": n, "once": [], "twice": []}
    for _ in range(runs):
        for name, tables in (("once", once), ("twice", twice)):
            cost[name].append(bench.shade(tables)[2])
    vsgls.free()
    cost["ratio"] = statistics.median(cost["twice"]) / statistics.median(cost["once"])
    log(f"position terms per lobe / once, N = {n}: {cost['ratio']:.3f}")
    return cost


def extremes(bench, largest_rsm) -> dict:
    """Finite flags of the raw shading outputs at parameter extremes (N = 1 / 4096, K = 0.25 / 16,
    RSM 1² / `largest_rsm`²), lattice seed 3."""
    from vsgl_addon.reference.vsgl_shading import diffuse_mode_for_kernel
    from vsgl_addon.settings import VSGLSettings

    finite = {}
    for kernel, n, k, rsm_size in [("modified", 1, 0.25, 1), ("original", 1, 16.0, 1), ("two-vsgl", 2, 1.0, 1),
                                   ("modified", 4096, 16.0, largest_rsm), ("original", 4096, 0.25, largest_rsm),
                                   ("modified", 1, 16.0, 64)]:
        vsgls, _ = bench.vsgls(VSGLSettings(vsgl_count=n, k=k, kernel=kernel, rsm_size=rsm_size, seed=3))
        d, s, _ = bench.shade(vsgls.tables(), diffuse_mode_for_kernel(kernel))
        vsgls.free()
        finite[f"extreme {kernel} N={n} K={k:g} RSM {rsm_size}"] = bool(np.all(np.isfinite(d)) and np.all(np.isfinite(s)))
    return finite
