# SPDX-License-Identifier: GPL-3.0-or-later
"""How the glossy receivers' VSGL set's sampling bounds the indirect specular error (not a test).

With MRP-ASG the frame's second VSGL set (light-paths.md: every reflector without the proxies'
specular flux) lights the receivers' glossy lobes. Its N and its kernel size K are the frame's (the
planner shares N per set; K is the settings'); this benchmark changes them for that set alone:

- ``count x F``: the glossy set's VSGLs per view times F (the other sets as they are);
- ``K x F``: the glossy set's kernels at K times F (000 Eq. 3: larger kernels overlap and blur,
  smaller ones leave gaps).

Per scene (the validation suite's cached Cycles truths, 240x180, each scene's saved settings) and
lattice seed: the noise-corrected relative RMSE of the indirect specular layer against Cycles'
GlossInd·GlossCol and of the whole indirect light, and the frame time (informative: a shared
machine). Writes ``benchmarks/results/glossy_set_sampling.md`` and prints it.

    .venv/bin/python benchmarks/glossy_set_sampling.py [--only NAME ...] [--counts F ...] [--ks F ...] [--seeds S]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from validation_suite import scene_with_truth, suite  # noqa: E402

WIDTH, HEIGHT = 240, 180


def patched(count_factor: float = 1.0, k_factor: float = 1.0):
    """A context manager: the glossy set's per-view counts times ``count_factor`` (at least one where
    the plan gave one) and its K times ``k_factor``, restored on exit."""
    from contextlib import contextmanager

    from vsgl_addon import planner, renderer

    @contextmanager
    def manager():
        allocate, render = planner.FramePlan.allocate, renderer.render_scene_vsgls

        def allocate_glossy(self, view_powers, receiver_set="all"):
            counts = allocate(self, view_powers, receiver_set)
            if receiver_set != "glossy" or count_factor == 1.0:
                return counts
            return {light: np.maximum((np.asarray(c) * count_factor).astype(np.int64), np.minimum(c, 1))
                    for light, c in counts.items()}

        def render_glossy(scene_gpu, settings, receiver_lobe="all", *args, **kwargs):
            if receiver_lobe == "glossy" and k_factor != 1.0:
                settings = settings.overridden(k=settings.k * k_factor)
            return render(scene_gpu, settings, receiver_lobe, *args, **kwargs)

        planner.FramePlan.allocate, renderer.render_scene_vsgls = allocate_glossy, render_glossy
        try:
            yield
        finally:
            planner.FramePlan.allocate, renderer.render_scene_vsgls = allocate, render

    return manager()


def measure(name, path, variants, seeds):
    from vsgl_addon.renderer import FrameRenderer
    from tradeoff.metrics import Errors

    settings, truth, description = scene_with_truth(name, path, WIDTH, HEIGHT)
    rows = []
    renderer = FrameRenderer()
    try:
        for label, count_factor, k_factor in variants:
            with patched(count_factor, k_factor):
                figures = []
                for seed in range(seeds):
                    frame = renderer.render(description, settings.overridden(seed=seed), WIDTH, HEIGHT)
                    errors = Errors(truth, frame.coverage)(frame.indirect_diffuse, frame.indirect_specular)
                    figures.append((errors["rel_specular"], errors["rel"], float(sum(frame.timings.values())),
                                    frame.plan.runs("glossy_set")))
            rows.append({"scene": name, "variant": label, "specular": [f[0] for f in figures],
                         "total": [f[1] for f in figures], "frame_ms": 1e3 * float(np.mean([f[2] for f in figures])),
                         "glossy_set": bool(figures[0][3])})
            print(f"{name} {label}: specular {' / '.join(f'{f[0]:.3f}' for f in figures)}", file=sys.stderr)
    finally:
        renderer.free()
    return rows


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["demo", "polished_metal_floor", "occluded_reflector"])
    parser.add_argument("--counts", type=float, nargs="+", default=[2.0, 4.0])
    parser.add_argument("--ks", type=float, nargs="+", default=[0.5, 2.0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--results-dir", type=Path, default=REPO / "benchmarks" / "results")
    args = parser.parse_args(argv)
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    register()
    variants = [("as planned", 1.0, 1.0)] + [(f"count x {f:g}", f, 1.0) for f in args.counts] \
        + [(f"K x {f:g}", 1.0, f) for f in args.ks]
    rows = []
    for name, path, _ in suite():
        if name in args.only:
            rows += measure(name, path, variants, args.seeds)
    lines = ["# The glossy receivers' VSGL set: its sampling against the indirect specular error", "",
             f"`.venv/bin/python benchmarks/glossy_set_sampling.py {' '.join(argv)}`: {WIDTH}x{HEIGHT}, each scene's "
             f"saved settings, lattice seeds 0-{args.seeds - 1}; noise-corrected relative RMSE of the indirect "
             "specular layer (against Cycles' GlossInd·GlossCol) and of the whole indirect light; frame time the "
             "mean over the seeds (informative). The module documentation defines the variants.", "",
             "| scene | glossy set | specular rel RMSE | total rel RMSE | frame ms |", "|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['variant']}{'' if r['glossy_set'] else ' (no glossy set)'} | "
                     f"{' / '.join(f'{v:.3f}' for v in r['specular'])} | {' / '.join(f'{v:.3f}' for v in r['total'])} | "
                     f"{r['frame_ms']:.0f} |")
    text = "\n".join(lines) + "\n"
    args.results_dir.mkdir(parents=True, exist_ok=True)
    (args.results_dir / "glossy_set_sampling.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
