# SPDX-License-Identifier: GPL-3.0-or-later
"""Plane-split clusters (reference/vsgl.py PLANE_SPLIT) against 000's clusters on the validation suite.

For each scene (its saved settings, visibility on and off, lattice seeds 0 and 1), three frames:

- **000**: the renderer's clusters, N kernels, one VSGL each;
- **split**: the same N kernels, the clusters of the light types given (``--types``, default
  POINT) split by plane (pipeline.PLANE_SPLIT_LIGHT_TYPES), so N plus the extra planes' VSGLs;
- **000 at the split's count**: 000's clusters with N raised to the split frame's VSGL count
  (rounded), the same shading and shadow-map cost.

Each row gives the mean indirect luminance over Cycles' one-bounce truth, the noise-corrected
relative RMSE (tradeoff.metrics.Errors), the frame's VSGL count and its time (informative: a shared
machine). Writes ``benchmarks/results/plane_split.md`` (``--name``) and prints it.

    .venv/bin/python benchmarks/plane_split.py [--only NAME ...] [--types POINT SPOT AREA SUN]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

from validation_suite import scene_with_truth, suite  # noqa: E402

RESOLUTION = (240, 180)
SEEDS = (0, 1)


def frames(name, path, types):
    from vsgl_addon import pipeline
    from vsgl_addon.renderer import FrameRenderer
    from tradeoff.metrics import Errors

    width, height = RESOLUTION
    settings, truth, description = scene_with_truth(name, path, width, height)
    rows = []
    renderer = FrameRenderer()
    saved = pipeline.PLANE_SPLIT_LIGHT_TYPES
    try:
        def run(label, split, count):
            pipeline.PLANE_SPLIT_LIGHT_TYPES = tuple(types) if split else ()
            for visibility in (False, True):
                figures = []
                for seed in SEEDS:
                    chosen = settings.overridden(seed=seed, visibility=visibility, vsgl_count=count)
                    renderer.render(description, chosen, width, height)  # warm (shaders, textures)
                    frame = renderer.render(description, chosen, width, height)
                    errors = Errors(truth, frame.coverage)(frame.indirect_diffuse, frame.indirect_specular)
                    figures.append((errors["mean_ratio"], errors["rel"], frame.counts.get("vsgls", 0),
                                    float(sum(frame.timings.values()))))
                mean = np.mean(figures, axis=0)
                rows.append({"scene": name, "frames": label, "visibility": visibility, "n": count,
                             "mean_ratio": [f[0] for f in figures], "rel": [f[1] for f in figures],
                             "vsgls": float(mean[2]), "frame_ms": 1e3 * float(mean[3])})
            return rows[-1]["vsgls"]

        run("000", False, settings.vsgl_count)
        count = run("split", True, settings.vsgl_count)
        matched = int(round(count * settings.vsgl_count / max(rows[0]["vsgls"], 1.0)))
        run("000 at the split's count", False, max(matched, 1))
    finally:
        pipeline.PLANE_SPLIT_LIGHT_TYPES = saved
        renderer.free()
    return rows


def markdown(rows, types, argv):
    lines = ["# Plane-split clusters against 000's clusters, per scene", "",
             f"`.venv/bin/python benchmarks/plane_split.py {' '.join(argv)}`: split light types "
             f"{', '.join(types)}; {RESOLUTION[0]}x{RESOLUTION[1]}, each scene's saved settings; mean ours / "
             "Cycles and noise-corrected relative RMSE for lattice seeds "
             f"{' and '.join(map(str, SEEDS))}; VSGLs and frame time: means over the seeds (frame time "
             "informative, a shared machine). The module documentation defines the frames.", "",
             "| scene | frames | N (kernels) | visibility | VSGLs | mean / Cycles | rel RMSE | frame ms |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['frames']} | {r['n']} | {'on' if r['visibility'] else 'off'} | "
                     f"{r['vsgls']:.0f} | {' / '.join(f'{v:.3f}' for v in r['mean_ratio'])} | "
                     f"{' / '.join(f'{v:.3f}' for v in r['rel'])} | {r['frame_ms']:.0f} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["many_lights", "closed_room"])
    parser.add_argument("--types", nargs="+", default=["POINT"])
    parser.add_argument("--name", default="plane_split")
    parser.add_argument("--results-dir", type=Path, default=REPO / "benchmarks" / "results")
    args = parser.parse_args(argv)
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    register()
    rows = []
    for name, path, _ in suite():
        if name in args.only:
            start = time.perf_counter()
            rows += frames(name, path, args.types)
            print(f"{name}: {time.perf_counter() - start:.0f} s", file=sys.stderr)
    text = markdown(rows, args.types, argv)
    args.results_dir.mkdir(parents=True, exist_ok=True)
    (args.results_dir / f"{args.name}.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
