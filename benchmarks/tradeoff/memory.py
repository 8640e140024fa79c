# SPDX-License-Identifier: GPL-3.0-or-later
"""Peak memory: a fresh process (the benchmark's entry script with a hidden flag) renders one
FrameRenderer frame and reports its peak RSS, VmHWM from /proc/self/status."""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from .demo import REPO, extract, log, open_demo

# The command line that runs `memory_child` (its hidden --memory-child flag) in a fresh process.
ENTRY = REPO / "benchmarks" / "speed_accuracy.py"


def _status_kb(field: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    return -1


def memory_child(size: int, n: int, rsm_size: int, visibility: int = 0) -> int:
    """Run in a fresh process: one FrameRenderer frame; print a JSON line with the peak RSS."""
    open_demo()
    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.renderer import FrameRenderer
    from vsgl_addon.settings import VSGLSettings

    ensure_gpu_context()
    description = extract()
    # VmHWM, not ru_maxrss: after fork + exec, getrusage's ru_maxrss keeps the high-water mark of the
    # process image before exec (the forked parent, ~1.6 GB here), so it is not this process's own.
    before = _status_kb("VmHWM")
    rss_before = _status_kb("VmRSS")
    renderer = FrameRenderer()
    start = time.perf_counter()
    # The VSGLs' memory: without the glossy VPL pass (its per-tile lists and VPL table come on top).
    images = renderer.render(description, VSGLSettings(vsgl_count=n, rsm_size=rsm_size, visibility=bool(visibility),
                                                       caustics=False), size, size)
    seconds = time.perf_counter() - start
    raw_d, raw_s = renderer._shading.read()  # the raw outputs, before the renderer's nan_to_num
    finite = bool(np.all(np.isfinite(raw_d)) and np.all(np.isfinite(raw_s)))
    after = _status_kb("VmHWM")
    rss_after = _status_kb("VmRSS")
    ru_maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    renderer.free()
    print("MEMORY " + json.dumps({"before_kb": before, "peak_kb": after, "rss_before_kb": rss_before,
                                  "rss_after_kb": rss_after, "ru_maxrss_kb": ru_maxrss, "seconds": seconds,
                                  "finite": finite,
                                  "vsgls": images.counts.get("vsgls"), "timings": images.timings}), flush=True)
    return 0


def measure_memory(size: int, n: int, rsm_size: int, visibility: bool = False) -> dict:
    """Peak memory of one frame in a fresh process; ``visibility``: with VSGL visibility (imperfect
    shadow maps) on."""
    log(f"peak memory: subprocess rendering {size}² with N = {n}, RSM {rsm_size}², visibility {visibility}")
    result = subprocess.run([sys.executable, str(ENTRY), "--memory-child", str(size), str(n), str(rsm_size),
                             str(int(visibility))],
                            capture_output=True, text=True, timeout=3600)
    for line in result.stdout.splitlines():
        if line.startswith("MEMORY "):
            out = json.loads(line[7:])
            out.update(size=size, n=n, rsm=rsm_size, visibility=bool(visibility))
            return out
    raise RuntimeError(f"memory subprocess failed (exit {result.returncode}):\n{result.stderr[-3000:]}")
