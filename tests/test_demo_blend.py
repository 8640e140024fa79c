# SPDX-License-Identifier: GPL-3.0-or-later
"""demo.blend is what tools/build_demo_blend.py builds, and carries its VSGL settings."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

SUMMARY = """
import bpy, sys
sys.path.insert(0, {repo!r})
from vsgl_addon import register, unregister
register()
bpy.ops.wm.open_mainfile(filepath=sys.argv[-1])
scene = bpy.context.scene
objects = sorted((o.name, o.type, tuple(round(v, 4) for v in o.matrix_world.translation)) for o in scene.objects)
lights = sorted((l.name, l.type, round(l.energy, 3), round(l.shadow_soft_size, 3)) for l in bpy.data.lights)
v = scene.vsgl
print(repr((objects, lights, (v.vsgl_count, v.k, v.kernel, v.rsm_size, v.seed, v.positional_distribution),
            (scene.render.resolution_x, scene.render.resolution_y), scene.camera.name)))
unregister()
"""


def _summary(path):
    result = subprocess.run([sys.executable, "-c", SUMMARY.format(repo=str(REPO)), str(path)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return result.stdout.strip().splitlines()[-1]


def test_committed_demo_blend_is_what_the_script_builds(tmp_path):
    rebuilt = tmp_path / "demo.blend"
    build = subprocess.run([sys.executable, str(REPO / "tools" / "build_demo_blend.py"), str(rebuilt)],
                           capture_output=True, text=True, timeout=120)
    assert build.returncode == 0, build.stderr
    committed = _summary(REPO / "demo.blend")
    assert committed == _summary(rebuilt)
    assert "('Spot', 'SPOT', 1500.0, 0.0)" in committed and "(256, 1.0, 'MODIFIED', 128, 0, 'PER_LOBE')" in committed
