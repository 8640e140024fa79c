# SPDX-License-Identifier: GPL-3.0-or-later
"""The ground truth: Cycles' one-bounce indirect radiance of a scene from two seeds, cached in
``benchmarks/reference/<name>_indirect_<w>x<h>.npz`` with its own noise (see the package doc).
The speed/accuracy benchmark's is demo.blend's (``name="demo"``); the validation suite
(benchmarks/validation_suite.py) keeps one per scene of its suite."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .demo import COVERED, DEMO, REFERENCE_DIR, REPO, log, sha256

# The images in a cached truth (the rest are scalars and small arrays).
IMAGES = ("diffuse_a", "diffuse_b", "glossy_a", "glossy_b", "direct", "alpha")


def reference_path(width: int, height: int, name: str = "demo") -> Path:
    return REFERENCE_DIR / f"{name}_indirect_{width}x{height}.npz"


def render_reference(scene, width, height, samples, seeds=(0, 1), source: Path = DEMO,
                     dtype=np.float32) -> dict:
    """Cycles' one-bounce truth of `scene` (opened from `source`, whose hash it records): the two
    seeds' diffuse and glossy indirect images stored as `dtype`, their direct light and alpha,
    and the noise of their mean."""
    from cycles_truth import render_cycles

    renders = []
    for seed in seeds:
        log(f"Cycles truth of {source.name}: {samples} samples, seed {seed}, {width}x{height}")
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
        "diffuse_a": diffuse[0].astype(dtype), "diffuse_b": diffuse[1].astype(dtype),
        "glossy_a": glossy[0].astype(dtype), "glossy_b": glossy[1].astype(dtype),
        "direct": (0.5 * sum(p["DiffDir"] * p["DiffCol"] + p["GlossDir"] * p["GlossCol"] for p in renders)
                   ).astype(dtype),
        "alpha": alpha.astype(dtype),
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
        "blend_sha256": np.array(sha256(source)),
    }


def load_reference(scene, width, height, samples, regenerate: bool, name: str = "demo", source: Path = DEMO,
                   dtype=np.float32) -> dict:
    """The cached truth of `name` (rendered from `scene` first when missing or `regenerate`), its
    images as float64 with row 0 at the bottom, plus the seeds' means and ``path``."""
    path = reference_path(width, height, name)
    if regenerate or not path.is_file():
        data = render_reference(scene, width, height, samples, source=source, dtype=dtype)
        REFERENCE_DIR.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, **data)
        log(f"wrote {path.relative_to(REPO)} ({path.stat().st_size / 1e6:.2f} MB)")
    with np.load(path) as file:
        data = {name: file[name] for name in file.files}
    # The demo's file was written when the truth was demo.blend's alone and names its hash so.
    recorded = str(data.get("blend_sha256", data.get("demo_sha256")))
    if recorded != sha256(source):
        log(f"WARNING: {path.name} was rendered from another {source.name}: run with --regenerate-reference")
    data["path"] = path
    for image in IMAGES:
        data[image] = data[image][::-1].astype(np.float64)  # row 0 at the bottom, as our passes
    data["diffuse"] = 0.5 * (data["diffuse_a"] + data["diffuse_b"])
    data["glossy"] = 0.5 * (data["glossy_a"] + data["glossy_b"])
    data["indirect"] = data["diffuse"] + data["glossy"]
    return data
