# SPDX-License-Identifier: GPL-3.0-or-later
"""VSGL visibility's temporal stability and peak memory (not a test).

    .venv/bin/python benchmarks/visibility_stability.py [--frames F] [--skip-memory]

* Static: demo.blend rendered twice in a row (same seed, visibility on): the largest difference
  between the two frames' indirect images (0: identical; the point sets and maps depend on the
  scene and the seed only).
* Turning light: demo.blend's spot panning 1°/frame (tradeoff/flicker.py turning_frames), our
  indirect image with visibility off and on each frame; the flicker measure is the speed/accuracy
  benchmark's (mean |I(t) − I(t−1)| over covered pixels and RGB, relative to the mean), and the
  target is its ratio on / off ≤ 1.2.
* Peak memory at 1024², N = 4096, visibility on (a fresh process, tradeoff/memory.py): ≤ 2 GB.

Writes ``benchmarks/results/visibility_stability.{md,json}`` (or ``--results-dir``);
``validation_suite.py`` runs it too.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from tradeoff.demo import COVERED, RESULTS_DIR, extract, log, open_demo  # noqa: E402
from tradeoff.flicker import mean_abs_step, turning_frames  # noqa: E402

SIZE = (240, 180)


def static_difference(settings) -> float:
    from vsgl_addon.renderer import FrameRenderer

    open_demo()
    description = extract()
    renderer = FrameRenderer()
    try:
        first = renderer.render(description, settings, *SIZE).indirect
        second = renderer.render(description, settings, *SIZE).indirect
    finally:
        renderer.free()
    return float(np.abs(first.astype(np.float64) - second).max())


def turning(settings, frames: int) -> dict:
    import bpy
    from vsgl_addon.pipeline import build_visibility

    open_demo()
    images = {False: [], True: []}
    with contextlib.closing(turning_frames(bpy.context.scene, frames, *SIZE, "pan")) as sequence:
        for frame, bench in sequence:
            for visibility in (False, True):
                vsgls, _ = bench.vsgls(settings)
                try:
                    if visibility:
                        build_visibility(bench.scene_gpu, vsgls, settings)
                    d, s, _ = bench.shade(vsgls.tables())
                finally:
                    vsgls.free()
                images[visibility].append((d + s).astype(np.float64))
            mask = bench.coverage > COVERED
    out = {}
    for visibility, sequence in images.items():
        sequence = [image[mask] for image in sequence]
        mean = float(np.mean([image.mean() for image in sequence]))
        change = mean_abs_step(sequence)
        out["on" if visibility else "off"] = {"change": change, "relative": change / mean, "mean": mean}
    out["ratio"] = out["on"]["relative"] / out["off"]["relative"]
    out["frames"] = frames
    return out


def markdown(result: dict) -> str:
    t = result["turning"]
    lines = ["## VSGL visibility: stability and memory", "",
             f"demo.blend at {SIZE[0]}x{SIZE[1]}, {result['settings']}.", "",
             f"- Static scene, two consecutive frames, same seed, visibility on: largest difference "
             f"{result['static_max_difference']:.3g} ({'identical' if result['static_max_difference'] == 0 else 'NOT identical'}).",
             f"- Spot panning 1°/frame, {t['frames']} frames: mean frame-to-frame change / mean, visibility off "
             f"{t['off']['relative']:.4f}, on {t['on']['relative']:.4f}: ratio on / off {t['ratio']:.2f} (target ≤ 1.2)."]
    if result.get("memory"):
        m = result["memory"]
        lines.append(f"- Peak memory (VmHWM) of one frame at {m['size']}², N = {m['n']}, RSM {m['rsm']}², visibility on, "
                     f"fresh process: {m['peak_kb'] / 1024:.0f} MB (target ≤ 2048 MB).")
    return "\n".join(lines) + "\n"


def measure(frames: int = 12, memory: bool = True) -> dict:
    from vsgl_addon.settings import VSGLSettings

    settings = VSGLSettings(vsgl_count=256, rsm_size=128, visibility=True, caustics=False)
    result = {"settings": str(settings), "static_max_difference": static_difference(settings)}
    log(f"static: largest difference of two frames {result['static_max_difference']:.3g}")
    result["turning"] = turning(settings, frames)
    log(f"turning: flicker ratio on / off {result['turning']['ratio']:.2f}")
    if memory:
        from tradeoff.memory import measure_memory

        result["memory"] = measure_memory(1024, 4096, 128, visibility=True)
        log(f"memory: {result['memory']['peak_kb'] / 1024:.0f} MB")
    return result


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=12)
    parser.add_argument("--skip-memory", action="store_true")
    parser.add_argument("--results-dir", type=Path, default=RESULTS_DIR)
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    result = measure(args.frames, not args.skip_memory)
    text = markdown(result)
    args.results_dir.mkdir(parents=True, exist_ok=True)
    (args.results_dir / "visibility_stability.md").write_text(text)
    (args.results_dir / "visibility_stability.json").write_text(json.dumps(result, indent=1, default=str))
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
