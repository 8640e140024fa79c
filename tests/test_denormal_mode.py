# SPDX-License-Identifier: GPL-3.0-or-later
"""Why the suite renders with EEVEE or Workbench only in child processes: in the process of the
bpy module, such a render leaves llvmpipe's fragment shaders keeping denormals on some threads, and
later bit-for-bit comparisons then depend on which thread ran a tile (denormal_mode.py)."""

from __future__ import annotations

import pytest

from denormal_mode import run_in_child

_CHILD = """
import json
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
    import gpu

    renderer = gpu.platform.renderer_get()
    if "llvmpipe" not in renderer:
        pytest.skip(f"llvmpipe's leak; the GPU here is {renderer}")
    result = run_in_child(_CHILD)
    assert result["before"] == 0.0, result  # a fresh process flushes
    # One thread or both leak: some or all of the probe's pixels keep their denormal.
    assert result["after"] > 0.0, result
