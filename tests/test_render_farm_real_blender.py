# SPDX-License-Identifier: GPL-3.0-or-later
"""A render farm renders each frame in its own process (`blender -b file.blend -f N` per task, as
Flamenco does): those frames must be bit-identical to the same frames of one `-a` run, for an
animated light and an animated object, in the Blender 5.2 application with the extension installed."""

from __future__ import annotations

import numpy as np
import pytest

from helpers_blender import REPO, describe, installed_extension, run_blender
from test_render_engine import read_layers

pytestmark = pytest.mark.real_blender

# The demo, small, with a spot light and the gold sphere keyed to move over frames 1-3.
ANIMATE = """
import bpy
scene = bpy.context.scene
scene.render.resolution_percentage = 15
scene.frame_start, scene.frame_end = 1, 3
spot, sphere = bpy.data.objects["Spot"], bpy.data.objects["Gold sphere"]
for frame, (light_x, sphere_y) in ((1, (0.8, 0.2)), (3, (-0.6, 0.9))):
    spot.location.x = light_x
    spot.keyframe_insert("location", frame=frame)
    sphere.location.y = sphere_y
    sphere.keyframe_insert("location", frame=frame)
"""


@pytest.fixture(scope="module")
def installed_profile():
    """A clean Blender user profile with the built extension installed and enabled."""
    with installed_extension("vsgl-farm-") as installed:
        yield installed


def _render(folder, environment, output, *frames):
    proc = run_blender("-b", str(REPO / "demo.blend"), "--python-expr", ANIMATE, "-E", "VSGL",
                       "-o", str(folder / output / "frame_###"), "-F", "OPEN_EXR_MULTILAYER", *frames,
                       blender_env=environment, timeout=300)
    assert proc.returncode == 0, describe(proc)


def test_frames_rendered_one_per_process_equal_one_animation_run(installed_profile):
    folder, environment = installed_profile
    _render(folder, environment, "animation", "-a")
    for frame in (3, 1, 2):  # out of order, as a farm hands out tasks
        _render(folder, environment, "tasks", "-f", str(frame))
    images = {}
    for frame in (1, 2, 3):
        one_run = read_layers(folder / "animation" / f"frame_{frame:03d}.exr")
        task = read_layers(folder / "tasks" / f"frame_{frame:03d}.exr")
        assert sorted(one_run) == sorted(task)
        for name in one_run:
            assert np.array_equal(one_run[name], task[name]), f"frame {frame}, layer {name}"
        images[frame] = one_run["Indirect"]
    # The animation is real: each frame's light differs from the last.
    assert not np.array_equal(images[1], images[2]) and not np.array_equal(images[2], images[3])
