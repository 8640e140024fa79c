# SPDX-License-Identifier: GPL-3.0-or-later
"""Wall-clock timing of GPU work for the benchmarks: the median of repeated runs, each run ending
only when the GPU has finished (a read-back), so that a time covers the GPU's work and not just
the submission of its commands."""

from __future__ import annotations

import statistics
import time


def median_seconds(function, repeats: int) -> float:
    """Median wall time of `repeats` calls of `function` (which must wait for the GPU itself)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def finish(texture) -> None:
    """Wait for the GPU (read one texel of `texture` back)."""
    import gpu

    framebuffer = gpu.types.GPUFrameBuffer(color_slots=[texture])
    with framebuffer.bind():
        framebuffer.read_color(0, 0, 1, 1, 4, 0, "FLOAT")
