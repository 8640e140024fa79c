# SPDX-License-Identifier: GPL-3.0-or-later
"""Why the suite renders with EEVEE or Workbench only in child processes: in the process of the
bpy module, such a render leaves llvmpipe's fragment shaders keeping denormals on some threads, and
later bit-for-bit comparisons then depend on which thread ran a tile (denormal_mode.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

_CHILD = """
import json
import bpy  # noqa: F401
from vsgl_addon.gpu_context import ensure_gpu_context
ensure_gpu_context()
from denormal_mode import fragment_denormals_kept
from test_direct_light import build_scene
from cycles_truth import render_eevee
before = fragment_denormals_kept()
build_scene("POINT", "glossy")
render_eevee(samples=4)
print(json.dumps({"before": before, "after": fragment_denormals_kept(draws=6)}))
"""


@pytest.mark.gpu
def test_an_eevee_render_leaves_fragment_shaders_keeping_denormals():
    renderer = __import__("gpu").platform.renderer_get()
    if "llvmpipe" not in renderer:
        pytest.skip(f"llvmpipe's leak; the GPU here is {renderer}")
    tests = REPO / "tests"
    child = subprocess.run([sys.executable, "-c", _CHILD], cwd=REPO, capture_output=True, text=True, timeout=600,
                           env={**os.environ, "PYTHONPATH": f"{tests}:{REPO}"})
    assert child.returncode == 0, child.stderr[-3000:]
    result = json.loads(child.stdout.strip().splitlines()[-1])
    assert result["before"] == 0.0, result  # a fresh process flushes
    # One thread or both leak: some or all of the probe's pixels keep their denormal.
    assert result["after"] > 0.0, result
