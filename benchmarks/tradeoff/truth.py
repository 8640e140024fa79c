# SPDX-License-Identifier: GPL-3.0-or-later
"""The ground truth: Cycles' one-bounce indirect radiance of demo.blend from two seeds, cached in
``benchmarks/reference/demo_indirect_<w>x<h>.npz`` with its own noise (see the package doc)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .demo import COVERED, DEMO, REFERENCE_DIR, REPO, log, sha256


def reference_path(width: int, height: int) -> Path:
    return REFERENCE_DIR / f"demo_indirect_{width}x{height}.npz"


def render_reference(scene, width, height, samples, seeds=(0, 1)) -> dict:
    from cycles_truth import render_cycles

    renders = []
    for seed in seeds:
        log(f"Cycles truth: {samples} samples, seed {seed}, {width}x{height}")
        passes = render_cycles(scene, samples=samples, max_bounces=1, seed=seed, resolution=(width, height),
                               filter_width=0.01)
        renders.append(passes)
    diffuse = [p["DiffInd"] * p["DiffCol"] for p in renders]
    glossy = [p["GlossInd"] * p["GlossCol"] for p in renders]
    alpha = np.minimum(renders[0]["Alpha"], renders[1]["Alpha"])
    mask = alpha > COVERED
    a, b = diffuse[0] + glossy[0], diffuse[1] + glossy[1]
    mean = float((0.5 * (a + b))[mask].mean())
    noise = float(np.sqrt(np.mean((a - b)[mask] ** 2)) / 2.0)  # RMS noise of the mean of the two
    import bpy

    return {
        # Row 0 at the top, as Cycles writes it (flipped when loaded). The two seeds separately:
        # (x − a)(x − b) estimates the squared error of x against the noise-free truth.
        "diffuse_a": diffuse[0].astype(np.float32), "diffuse_b": diffuse[1].astype(np.float32),
        "glossy_a": glossy[0].astype(np.float32), "glossy_b": glossy[1].astype(np.float32),
        "direct": (0.5 * sum(p["DiffDir"] * p["DiffCol"] + p["GlossDir"] * p["GlossCol"] for p in renders)
                   ).astype(np.float32),
        "alpha": alpha.astype(np.float32),
        "samples_per_seed": np.int64(samples),
        "seeds": np.array(seeds, np.int64),
        "seconds_per_seed": np.array([p["seconds"] for p in renders]),
        "noise_rmse": np.float64(noise),
        "noise_relative": np.float64(noise / mean),
        "mean_indirect": np.float64(mean),
        "max_bounces": np.int64(1),
        "filter_width": np.float64(0.01),
        "resolution": np.array([width, height], np.int64),
        "blender_version": np.array(bpy.app.version_string),
        "demo_sha256": np.array(sha256(DEMO)),
    }


def load_reference(scene, width, height, samples, regenerate: bool) -> dict:
    path = reference_path(width, height)
    if regenerate or not path.is_file():
        data = render_reference(scene, width, height, samples)
        REFERENCE_DIR.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, **data)
        log(f"wrote {path.relative_to(REPO)} ({path.stat().st_size / 1e6:.2f} MB)")
    with np.load(path) as file:
        data = {name: file[name] for name in file.files}
    if str(data["demo_sha256"]) != sha256(DEMO):
        log(f"WARNING: {path.name} was rendered from another demo.blend: run with --regenerate-reference")
    data["path"] = path
    for name in ("diffuse_a", "diffuse_b", "glossy_a", "glossy_b", "direct", "alpha"):
        data[name] = data[name][::-1].astype(np.float64)  # row 0 at the bottom, as our passes
    data["diffuse"] = 0.5 * (data["diffuse_a"] + data["diffuse_b"])
    data["glossy"] = 0.5 * (data["glossy_a"] + data["glossy_b"])
    data["indirect"] = data["diffuse"] + data["glossy"]
    return data
