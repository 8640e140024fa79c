# SPDX-License-Identifier: GPL-3.0-or-later
"""benchmarks/scenes/*.blend are what tools/build_validation_scenes.py builds (the suite's truths
were rendered from them), with the add-on's default settings and the suite's render size."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCENES = REPO / "benchmarks" / "scenes"

# One line per file: objects (with their world matrices and vertex counts), lights, materials'
# Principled inputs, the camera, render size and scene.vsgl. A .blend is not byte-identical between
# saves (it records times and paths), so what is compared is what the renderers see.
SUMMARY = """
import bpy, sys
sys.path.insert(0, {repo!r})
from vsgl_addon import register, unregister
register()
r = lambda values: tuple(round(float(v), 4) for v in values)
for path in sys.argv[sys.argv.index("--") + 1:]:
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    objects = sorted((o.name, o.type, tuple(r(row) for row in o.matrix_world),
                      len(o.data.vertices) if o.type == "MESH" else 0,
                      tuple(m.name for m in o.data.materials) if o.type == "MESH" else ()) for o in scene.objects)
    lights = sorted((l.name, l.type, round(l.energy, 3), r(l.color), round(l.shadow_soft_size, 3),
                     round(getattr(l, "spot_size", 0.0), 4), round(getattr(l, "size", 0.0), 3))
                    for l in bpy.data.lights)
    materials = []
    for m in sorted(bpy.data.materials, key=lambda m: m.name):
        bsdf = next(n for n in m.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
        materials.append((m.name, r(bsdf.inputs["Base Color"].default_value),
                          *(round(bsdf.inputs[k].default_value, 4)
                            for k in ("Roughness", "Metallic", "Specular IOR Level"))))
    v = scene.vsgl
    print(repr((path.rsplit("/", 1)[-1], objects, lights, materials,
                (v.vsgl_count, v.k, v.kernel, v.rsm_size, v.seed, v.positional_distribution),
                (scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage),
                scene.camera.name, round(scene.camera.data.lens, 3), r(scene.world.color))))
unregister()
"""


def _summaries(paths):
    result = subprocess.run([sys.executable, "-c", SUMMARY.format(repo=str(REPO)), "--", *map(str, paths)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    return [line for line in result.stdout.splitlines() if line.startswith("(")]


def test_committed_validation_scenes_are_what_the_script_builds(tmp_path):
    build = subprocess.run([sys.executable, str(REPO / "tools" / "build_validation_scenes.py"), str(tmp_path)],
                           capture_output=True, text=True, timeout=120)
    assert build.returncode == 0, build.stderr
    rebuilt = sorted(tmp_path.glob("*.blend"))
    committed = sorted(SCENES.glob("*.blend"))
    assert [p.name for p in committed] == [p.name for p in rebuilt] and len(committed) >= 7
    committed_summaries = _summaries(committed)
    assert committed_summaries == _summaries(rebuilt)
    for summary in committed_summaries:
        fields = ast.literal_eval(summary)
        # The add-on's defaults (the suite measures them) and the truth's render size.
        assert fields[4] == (256, 1.0, "MODIFIED", 128, 0, "PER_LOBE"), fields[0]
        assert fields[5] == (240, 180, 100) and fields[6] == "Camera", fields[0]
        assert fields[2], f"{fields[0]} has no light"



def test_each_scene_has_a_cached_truth():
    for blend in SCENES.glob("*.blend"):
        assert (REPO / "benchmarks" / "reference" / f"{blend.stem}_indirect_240x180.npz").is_file(), blend.name
