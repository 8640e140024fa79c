# SPDX-License-Identifier: GPL-3.0-or-later
"""Scenes an artist makes every day that have no clean geometry: objects scaled to zero to hide
them, mirrored and sheared transforms, extreme scales. Each renders, with finite pixels."""

from __future__ import annotations

import math

import bpy
import pytest
from mathutils import Matrix

import scene_builders as sb
import scene_generator
from vsgl_addon.settings import VSGLSettings


def _scene_with(transform):
    scene = sb.reset()
    floor = sb.plane("Floor", size=4.0)
    floor.data.materials.append(sb.principled("Red", base_color=(0.8, 0.1, 0.05), roughness=0.3))
    wall = sb.plane("Wall", size=4.0, location=(0, 1.5, 1.5), rotation=(math.radians(90), 0, 0))
    wall.data.materials.append(sb.principled("White", base_color=(0.8, 0.8, 0.8), roughness=0.7))
    block = sb.box("Block", size=0.6, location=(0.3, 0.4, 0.3))
    block.data.materials.append(sb.principled("Gold", base_color=(1.0, 0.7, 0.3), metallic=1.0, roughness=0.2))
    block.matrix_world = Matrix(transform)
    sb.spot_light(power=800.0, location=(0, -0.5, 3), look_at_point=(0, 0.3, 0), spot_size=math.radians(50))
    sb.camera(location=(0, -4, 2), look_at_point=(0, 0.5, 0.8), resolution=(48, 36))
    return scene


def _scaled(sx, sy, sz):
    return ((sx, 0, 0, 0.3), (0, sy, 0, 0.4), (0, 0, sz, 0.3), (0, 0, 0, 1))


TRANSFORMS = {
    "zero-z": _scaled(1, 1, 0),
    "zero-xy": _scaled(0, 0, 1),
    "zero-all": _scaled(0, 0, 0),
    "negative": _scaled(-1, 1, 1),
    "tiny": _scaled(1e-4, 1e-4, 1e-4),
    "huge-flat": _scaled(1e4, 1e4, 1e-4),
    "shear": ((1, 0.8, 0, 0.3), (0, 1, 0.5, 0.4), (0, 0, 1, 0.3), (0, 0, 0, 1)),
}


@pytest.mark.gpu
@pytest.mark.parametrize("name", list(TRANSFORMS))
def test_degenerate_transform_renders_finite_frames(name):
    images = sb.render_frame(_scene_with(TRANSFORMS[name]), VSGLSettings(vsgl_count=64, rsm_size=64), 48, 36)
    sb.assert_finite_frame(images, name)
    assert images.direct.max() > 0.0 and images.indirect.max() > 0.0


@pytest.mark.gpu
def test_engine_renders_a_zero_scale_object():
    """Through Blender's render pipeline: the frame is written, not lost."""
    statistics = scene_generator.render_through_engine(_scene_with(TRANSFORMS["zero-z"]))
    assert statistics.get("resolution") == [48, 36]
    assert statistics["counts"]["triangles"] == 2 + 2 + 12


def test_what_cannot_be_modelled_is_one_warning_line_in_the_json_report(tmp_path):
    """A spot light scaled to zero (its cone is gone) is skipped: the render goes on, and the
    command line's report and output say so in one line."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    _scene_with(_scaled(1, 1, 1))
    sb.spot_light(name="Flattened", location=(0.5, -0.5, 3), look_at_point=(0, 0, 0), scale=(1, 1, 0))
    blend = tmp_path / "flattened.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    result = subprocess.run([sys.executable, "-m", "vsgl_addon", "render", str(blend), "--out",
                             str(tmp_path / "out.exr"), "--vsgl-count", "16", "--report", str(tmp_path / "r.json")],
                            cwd=Path(__file__).resolve().parents[1], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    report = json.loads((tmp_path / "r.json").read_text())
    lines = [line for line in report["warnings"] if "Flattened" in line]
    assert lines == ["VSGL: lights skipped: Flattened (scaled to zero)"]
    assert report["counts"]["lights"] == 1
