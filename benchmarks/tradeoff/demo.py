# SPDX-License-Identifier: GPL-3.0-or-later
"""demo.blend (the one scene of the benchmark), where the benchmark keeps its files, and its progress log."""

from __future__ import annotations

import hashlib
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DEMO = REPO / "demo.blend"
REFERENCE_DIR = REPO / "benchmarks" / "reference"
RESULTS_DIR = REPO / "benchmarks" / "results"
# A pixel counts (in our G-buffer coverage and in Cycles' alpha) when it is covered above this.
COVERED = 0.999


def log(message: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {message}", file=sys.stderr, flush=True)


def open_demo():
    import bpy

    from vsgl_addon import register

    register()
    bpy.ops.wm.open_mainfile(filepath=str(DEMO), load_ui=False)
    return bpy.context.scene


def extract():
    """The plain scene description of the open file (the passes' only input)."""
    import bpy

    from vsgl_addon.scene import extract_scene

    return extract_scene(bpy.context.evaluated_depsgraph_get())


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()
