# SPDX-License-Identifier: GPL-3.0-or-later
"""Temporal stability: the spot turning 1°/frame, the frame-to-frame change of each kernel mode (the
flicker target's measure), its decomposition into motion and flicker proper, and sweeps over N, K, RSM size
and positions for a turn with real motion (pan) and one without (spin)."""

from __future__ import annotations

import contextlib
import math
import time

import numpy as np

from .baselines import brute_force_table
from .bench import Bench, upload
from .demo import COVERED, extract, log


def turned(base, degrees: float, motion: str):
    """The spot's world matrix after turning `degrees` about an axis through its position: "pan" about
    world Z (the spot on the floor moves: the lighting changes), "spin" about its own cone axis (a round
    cone: the lighting is the same in every frame, only the RSM rotates under the fixed lattice)."""
    from mathutils import Matrix, Vector

    location = base.to_translation()
    axis = Vector((0.0, 0.0, 1.0)) if motion == "pan" else (base.to_3x3() @ Vector((0.0, 0.0, -1.0))).normalized()
    return Matrix.Translation(location) @ Matrix.Rotation(math.radians(degrees), 4, axis) @ Matrix.Translation(-location) @ base


def turning_frames(scene, frames: int, width: int, height: int, motion: str):
    """Yields (frame, bench) while the scene's spot turns 1°/frame by `motion` (see `turned`): one Bench
    (the camera's G-buffer stays, the lights change), the spot restored and the bench freed at the end.
    Use it inside contextlib.closing so that an error in the caller's loop restores the spot at once."""
    import bpy

    spot = next(obj for obj in scene.objects if obj.type == "LIGHT")
    base = spot.matrix_world.copy()
    bench = None
    try:
        for frame in range(frames):
            spot.matrix_world = turned(base, frame, motion)
            bpy.context.view_layer.update()
            description = extract()
            if bench is None:
                bench = Bench(description, width, height)
            else:
                bench.set_scene(description)
            yield frame, bench
    finally:
        spot.matrix_world = base
        bpy.context.view_layer.update()
        if bench is not None:
            bench.free()



def mean_abs_step(sequence) -> float:
    """mean_t mean|x(t) − x(t−1)|: the flicker target's frame-to-frame change of a sequence of images."""
    return float(np.mean([np.abs(b - a).mean() for a, b in zip(sequence, sequence[1:])]))


def change_sweep(scene, frames: int, width: int, height: int, motion: str, configurations, seed: int = 0) -> dict:
    """The flicker target's measure (mean |I(t) − I(t−1)| over covered pixels and RGB, lattice seed `seed`) of both kernel
    modes for each (N, K, RSM size, positional distribution) in `configurations`, the spot turning
    1°/frame by `motion` (see `turned`)."""
    from vsgl_addon.settings import VSGLSettings

    images = {(kernel, *configuration): [] for configuration in configurations for kernel in ("modified", "original")}
    # 003's two VSGLs (whole-RSM totals, no lattice, no kernels) at each RSM size: what the RSM's own
    # rasterization of the turned light changes, without any sampling.
    two_vsgl = {rsm_size: ("two-vsgl", 2, 1.0, rsm_size, VSGLSettings.positional_distribution)
                for rsm_size in sorted({c[2] for c in configurations})}
    images.update({key: [] for key in two_vsgl.values()})
    finite = True
    started = time.perf_counter()
    with contextlib.closing(turning_frames(scene, frames, width, height, motion)) as turning:
        for _, bench in turning:
            for (kernel, n, k, rsm_size, positions), sequence in images.items():
                image, ok = bench.image(VSGLSettings(vsgl_count=n, k=k, kernel=kernel, rsm_size=rsm_size,
                                                     seed=seed, positional_distribution=positions))
                finite &= ok
                sequence.append(image)
    mask = bench.coverage > COVERED

    def change_of(key):
        sequence = [image[mask] for image in images[key]]
        mean = float(np.mean([image.mean() for image in sequence]))
        change = mean_abs_step(sequence)
        return {"change": change, "relative": change / mean, "mean": mean}

    rows = []
    for n, k, rsm_size, positions in configurations:
        row = {"n": n, "k": k, "rsm": rsm_size, "positions": positions,
               "two-vsgl": change_of(two_vsgl[rsm_size])}
        for kernel in ("modified", "original"):
            row[kernel] = change_of((kernel, n, k, rsm_size, positions))
        row["ratio"] = row["modified"]["change"] / row["original"]["change"]
        rows.append(row)
    log(f"{motion} sweep: " + ", ".join(f"N={r['n']} K={r['k']:g} RSM {r['rsm']} {r['positions']}: {r['ratio']:.2f}"
                                        for r in rows))
    return {"motion": motion, "seed": seed, "frames": frames, "size": (width, height), "rows": rows,
            "finite": finite, "seconds": time.perf_counter() - started}


def flicker(scene, frames: int, width: int, height: int, with_brute: bool, n=256, k=1.0, rsm_size=128,
            brute_rsm=64, seeds=16) -> dict:
    """The spot turning 1°/frame: per-mode change and jitter (the flicker target's measure) and, for the two
    kernel modes, its decomposition into motion and flicker proper with `seeds` extra lattice seeds.

    Each frame's own image I(t) uses seed 0. For "modified" and "original" the frame is also rendered
    with seeds 1..S (S = `seeds`, 0 = no decomposition); their mean Ī(t) estimates that mode's expected
    image over the random lattice rotation (its converged image, blur included), smooth in time.
    motion = mean_t mean|Ī(t) − Ī(t−1)| (the real change of the lighting as the mode sees it);
    flicker = mean_t mean|e(t) − e(t−1)| with e = I − Ī (the change of the seed-0 image's sampling
    error: flicker proper). Ī keeps a residual sampling error of 1/√S of one seed's: seed 0 is not
    in Ī, so for independent seeds e has (1 + 1/S) times the variance of I's own error (so does
    e(t) − e(t−1)), i.e. `flicker` reads high by about √(1 + 1/S) (for a Gaussian-like error; the
    factor is the same for both modes and cancels in their ratio), and `motion` keeps a residual
    error of variance 1/S of the error's change. Not rescaled: the factor is reported.
    """
    from vsgl_addon.settings import VSGLSettings

    kernels = ("modified", "original", "two-vsgl")
    images = {kernel: [] for kernel in kernels + (("brute",) if with_brute else ())}
    # Seed-averaged images Ī(t) (seeds 1..S; two-VSGL has no lattice, brute force no sampling).
    expected = {kernel: [] for kernel in ("modified", "original")} if seeds > 0 else {}
    finite = True
    started = time.perf_counter()
    seed_seconds = 0.0
    with contextlib.closing(turning_frames(scene, frames, width, height, "pan")) as turning:
        for frame, bench in turning:
            for kernel in kernels:
                image, ok = bench.image(VSGLSettings(vsgl_count=n, k=k, kernel=kernel, rsm_size=rsm_size,
                                                     seed=0))
                finite &= ok
                images[kernel].append(image)
                if kernel in expected:
                    seed_started = time.perf_counter()
                    total = np.zeros(image.shape)
                    for seed in range(1, seeds + 1):
                        image, ok = bench.image(VSGLSettings(vsgl_count=n, k=k, kernel=kernel,
                                                             rsm_size=rsm_size, seed=seed))
                        finite &= ok
                        total += image
                    expected[kernel].append(total / seeds)
                    seed_seconds += time.perf_counter() - seed_started
            if with_brute:
                arrays, _ = bench.rsm(brute_rsm)
                d, s, _ = bench.shade(upload(brute_force_table(arrays)))
                images["brute"].append((d + s).astype(np.float64))
            log(f"flicker frame {frame + 1}/{frames}")
    mask = bench.coverage > COVERED
    out = {"frames": frames, "n": n, "k": k, "rsm": rsm_size, "brute_rsm": brute_rsm, "size": (width, height),
           "finite": finite, "seeds": seeds, "error_variance_factor": 1.0 + 1.0 / seeds if seeds else None,
           "seconds": time.perf_counter() - started, "seed_average_seconds": seed_seconds}

    for name, seq in images.items():
        seq = [image[mask] for image in seq]
        mean = float(np.mean([image.mean() for image in seq]))
        change = mean_abs_step(seq)
        # Second difference: ~0 for a change that is smooth in time (the light's real motion), so
        # what remains is the frame-to-frame jitter.
        jitter = float(np.mean([np.abs(c - 2 * b + a).mean() for a, b, c in zip(seq, seq[1:], seq[2:])]))
        out[name] = {"change": change, "relative": change / mean, "mean": mean, "jitter": jitter,
                     "jitter_relative": jitter / mean}
        if name in expected:
            average = [image[mask] for image in expected[name]]
            errors = [image - avg for image, avg in zip(seq, average)]
            motion, flicker_proper = mean_abs_step(average), mean_abs_step(errors)
            out[name].update({
                "motion": motion, "motion_relative": motion / mean,
                "flicker": flicker_proper, "flicker_relative": flicker_proper / mean,
                # mean |I(t) − Ī(t)|: the seed-0 image's deviation from its seed average (per frame).
                "deviation": float(np.mean([np.abs(e).mean() for e in errors])),
                "expected_mean": float(np.mean([avg.mean() for avg in average]))})
    if len(expected) == 2:
        # How far apart the two modes' expected images are (their different blur), relative to the mean indirect.
        gap = float(np.mean([np.abs(a[mask] - b[mask]).mean()
                             for a, b in zip(expected["modified"], expected["original"])]))
        out["expected_gap"] = gap
        out["expected_gap_relative"] = gap / out["original"]["mean"]
    return out
