# SPDX-License-Identifier: GPL-3.0-or-later
"""Benchmark of VSGL generation on the GPU (not a test): `.venv/bin/python benchmarks/vsgl_generation.py`.

Measures, with the RSM already on the GPU (as the RSM pass leaves it):

* ``total``: mip atlas (texel moments + reduction) + VSGL kernels + reading the table back;
* ``kernels``: the VSGL kernel stage alone on a built atlas + reading the table back;

for the modified kernel size (000 Eq. 3, bisection) and the original one (Eq. 1) in the same
run, alternating the two so that drift affects both alike, as N (VSGL count) and the RSM side
grow. Reading the (N x 7) table back waits for the GPU to finish, so each time covers the GPU's
work. Every figure is the median of --repeats runs after a warm-up (shader JIT excluded).
The overhead columns compare modified against original (000 reports about 5 µs for its
bisection; ours should stay within 10 % of it).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from gpu_timing import median_seconds  # noqa: E402  (benchmarks/, this script's folder)


def _rsm(size, seed=0):
    """A smooth lit floor with a one-texel checker on top (a high-frequency PDF)."""
    from vsgl_addon.reference import vsgl

    rng = np.random.default_rng(seed)
    v, u = (np.mgrid[0:size, 0:size] + 0.5) / size
    position = np.stack([4 * u - 2, 4 * v - 2, 0.3 * np.sin(5 * u) * np.cos(3 * v)], -1)
    normal = np.stack([0.3 * np.cos(5 * u), -0.2 * np.sin(3 * v), np.ones_like(u)], -1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    rows, cols = np.mgrid[0:size, 0:size]
    checker = np.where((rows + cols) % 2 == 0, 1.0, 0.1)
    blob = np.exp(-((u - 0.3) ** 2 + (v - 0.6) ** 2) / 0.05)
    flux_diffuse = (checker * (0.2 + blob))[..., None] * np.array([1.0, 0.8, 0.6])
    flux_specular = 0.3 * flux_diffuse[..., ::-1]
    axis = np.broadcast_to([0.0, 0.0, 1.0], (size, size, 3)).copy()
    sharpness = 10.0 + 100.0 * rng.random((size, size))
    return vsgl.RSM(position, normal, flux_diffuse, flux_specular, axis, sharpness)


def _median_ms(function, repeats):
    return 1e3 * median_seconds(function, repeats)


def measure(vg, textures, count, repeats):
    """{(mode, part): median ms} for one RSM and one N; modes alternate run by run."""
    generation = vg.VSGLGeneration()
    try:
        def total(kernel):
            generation.build_mip_atlas(textures)
            generation.generate(count, kernel=kernel, rotation=(0.3, 0.6))
            generation.read_table()

        def kernels(kernel):
            generation.generate(count, kernel=kernel, rotation=(0.3, 0.6))
            generation.read_table()

        for kernel in ("modified", "original"):  # warm-up: JIT, allocation
            total(kernel)
        samples = {(mode, part): [] for mode in ("modified", "original") for part in ("total", "kernels")}
        for repeat in range(repeats):
            # A B B A ...: neither mode always runs first (after the atlas build, caches are cold).
            order = ("modified", "original") if repeat % 2 == 0 else ("original", "modified")
            for mode in order:
                samples[(mode, "total")].append(_median_ms(lambda: total(mode), 1))
            generation.build_mip_atlas(textures)
            for _ in range(2):
                for mode in order:
                    samples[(mode, "kernels")].append(_median_ms(lambda: kernels(mode), 1))
        return {key: statistics.median(values) for key, values in samples.items()}
    finally:
        generation.free()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="runs per figure (median), default 7")
    parser.add_argument("--counts", type=int, nargs="+", default=[64, 256, 1024, 4096])
    parser.add_argument("--sizes", type=int, nargs="+", default=[64, 128, 256, 512])
    parser.add_argument("--fixed-size", type=int, default=256, help="RSM side of the N sweep")
    parser.add_argument("--fixed-count", type=int, default=256, help="N of the RSM-size sweep")
    args = parser.parse_args(argv)

    import bpy  # noqa: F401  (before gpu)

    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.passes import vsgl_generation as vg

    renderer = ensure_gpu_context()
    start = time.perf_counter()
    vg.compile_shaders()
    compile_ms = 1e3 * (time.perf_counter() - start)

    configurations = [(args.fixed_size, n) for n in args.counts]
    configurations += [(s, args.fixed_count) for s in args.sizes
                       if (s, args.fixed_count) not in configurations]
    rows = []
    textures_by_size = {}
    for size, count in configurations:
        if size not in textures_by_size:
            textures_by_size[size] = vg.upload_rsm(_rsm(size))
        rows.append((size, count, measure(vg, textures_by_size[size], count, args.repeats)))
    textures_by_size.clear()
    vg.free_shaders()

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"VSGL generation on `{renderer}` ({os.cpu_count()} CPUs, load average {load:.1f}); "
          f"shader compile (once per process) {compile_ms:.0f} ms; median of {args.repeats} runs, "
          f"GPU finished (table read back).\n")
    print("| RSM | N | total modified (ms) | total original (ms) | overhead total | "
          "kernels modified (ms) | kernels original (ms) | overhead kernels |")
    print("|---|---|---|---|---|---|---|---|")
    for size, count, t in rows:
        tm, to = t[("modified", "total")], t[("original", "total")]
        km, ko = t[("modified", "kernels")], t[("original", "kernels")]
        print(f"| {size}² | {count} | {tm:.2f} | {to:.2f} | {100 * (tm / to - 1):+.1f} % | "
              f"{km:.2f} | {ko:.2f} | {100 * (km / ko - 1):+.1f} % |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
