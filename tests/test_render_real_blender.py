# SPDX-License-Identifier: GPL-3.0-or-later
"""`blender -b demo.blend -E VSGL -f 1` and `-a` in the Blender 5.2 application, extension installed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from helpers_blender import REPO, describe, installed_extension, run_blender
from test_render_engine import LAYERS, PERCENTAGE_SIZES, read_layers

pytestmark = pytest.mark.real_blender


@pytest.fixture(scope="module")
def installed_profile():
    """A clean Blender user profile with the built extension installed and enabled."""
    with installed_extension("vsgl-render-") as installed:
        yield installed


def _render(folder, environment, *frames):
    """Render into ``folder``, a new folder (the tests share one profile folder, and a frame another
    test wrote must not stand in for one this render failed to write)."""
    folder.mkdir()
    # A small copy of the demo keeps the software renderer quick: --python-expr runs before -f/-a.
    shrink = "import bpy; s = bpy.context.scene; s.render.resolution_percentage = 20; s.frame_end = 2"
    return run_blender("-b", str(REPO / "demo.blend"), "--python-expr", shrink, "-E", "VSGL",
                       "-o", str(folder / "frame_###"), "-F", "OPEN_EXR_MULTILAYER", *frames,
                       blender_env=environment, timeout=300)


def test_single_frame_writes_every_pass(installed_profile):
    folder, environment = installed_profile
    folder = folder / "single_frame"
    proc = _render(folder, environment, "-f", "1")
    assert proc.returncode == 0 and "Engine: VSGL" in proc.stdout, describe(proc)
    assert sorted(p.name for p in folder.iterdir()) == ["frame_001.exr"], describe(proc)
    layers = read_layers(folder / "frame_001.exr")
    assert set(LAYERS) <= set(layers), sorted(layers)
    assert layers["Combined"].shape == (72, 96, 4)  # 480x360 at 20 %
    for name in LAYERS:
        assert np.all(np.isfinite(layers[name])), name
    assert layers["Indirect"].mean() > 0


def test_animation_renders_the_frame_range(installed_profile):
    folder, environment = installed_profile
    folder = folder / "animation"
    proc = _render(folder, environment, "-a")
    assert proc.returncode == 0, describe(proc)
    assert sorted(p.name for p in folder.iterdir()) == ["frame_001.exr", "frame_002.exr"], describe(proc)


# Renders the demo through the installed engine at each (x, y, percentage), saves each Render Result
# and prints the size the engine rendered: run with --python-expr after the file is loaded.
_SIZES_SCRIPT = """
import json, sys, bpy
scene = bpy.context.scene
scene.render.engine = "VSGL"
scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
scene.render.image_settings.color_depth = "32"
engine = next(sys.modules[c.__module__] for c in bpy.types.RenderEngine.__subclasses__()
              if getattr(c, "bl_idname", "") == "VSGL")
rendered = []
for x, y, percentage in {sizes}:
    scene.render.resolution_x, scene.render.resolution_y = x, y
    scene.render.resolution_percentage = percentage
    engine.last_frame_statistics.clear()  # a render that makes no frame must not report the last one
    bpy.ops.render.render(scene=scene.name)
    path = "{folder}/size_%d_%d_%d.exr" % (x, y, percentage)
    bpy.data.images["Render Result"].save_render(path, scene=scene)
    rendered.append(engine.last_frame_statistics["resolution"])
print("VSGL-SIZES " + json.dumps(rendered))
"""


def test_rendered_size_is_blenders_at_any_percentage(installed_profile):
    """In Blender 5.2 itself: the Render Result Blender writes and the image the engine renders have
    one size at odd resolutions and percentages (Blender's integer rule)."""
    folder, environment = installed_profile
    folder = folder / "sizes"
    folder.mkdir()
    script = _SIZES_SCRIPT.format(sizes=PERCENTAGE_SIZES, folder=folder)
    proc = run_blender("-b", str(REPO / "demo.blend"), "--python-expr", script, blender_env=environment,
                       timeout=600)
    lines = [line for line in proc.stdout.splitlines() if line.startswith("VSGL-SIZES ")]
    assert proc.returncode == 0 and lines, describe(proc)
    rendered = json.loads(lines[-1].split(" ", 1)[1])
    for (x, y, percentage), size in zip(PERCENTAGE_SIZES, rendered, strict=True):
        height, width = read_layers(folder / f"size_{x}_{y}_{percentage}.exr")["Combined"].shape[:2]
        assert size == [width, height] == [x * percentage // 100, y * percentage // 100], (x, y, percentage)
