# SPDX-License-Identifier: GPL-3.0-or-later
"""The sidebar and the viewport overlay in the Blender 5.2 application, with its window (screenshots).

Builds the extension, installs it into a clean user profile under /tmp, opens demo.blend (a
spot-lit red floor next to two white walls) with `real-blender gui`, and lets
tests/gui_overlay_script.py drive the interface and take the screenshots. They are kept as test
artefacts in tests/artifacts/screenshots/ (gitignored; replaced as a whole by each run, after the
session, which works in a scratch folder of its own), with result.json (the measured coarse and
refined update times among it), update_times.txt and session.log:

    01_sidebar_overlay_off.png        the VSGL tab in the sidebar, overlay off
    02_overlay_on_indirect_only.png   overlay on, "Indirect Only", through the camera
    03_overlay_added_to_solid.png     "Added to Viewport" over solid shading
    04_vsgl_count_1.png               VSGL Count 256 -> 1 ("Indirect Only"): the overlay changes
    05_after_orbit_view_only.png      another view (the light passes are not rerun)
    06_after_moving_the_spot.png      the spot moved (the light passes rerun)
    07_overlay_switched_off.png       off again (GPU resources freed)
    08_render_properties.png          VSGL as the render engine: its panels in Render Properties
                                      (after a look-dev preview render into an image datablock)
"""

from __future__ import annotations

import json
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from helpers_blender import REAL_BLENDER, REPO, blender_environment, describe, run_blender, scratch_dir

pytestmark = pytest.mark.real_blender

SHOTS = REPO / "tests" / "artifacts" / "screenshots"
SCREEN = (1600, 900)


def _screenshot(path: Path) -> np.ndarray:
    """(H, W, 3) float in [0, 255], row 0 at the top (as on screen)."""
    import bpy

    image = bpy.data.images.load(str(path))
    try:
        image.colorspace_settings.name = "Non-Color"
        width, height = image.size
        pixels = np.empty(width * height * 4, np.float32)
        image.pixels.foreach_get(pixels)
    finally:
        bpy.data.images.remove(image)
    return pixels.reshape(height, width, 4)[::-1, :, :3] * 255.0


def _update_times(result) -> list[str]:
    """The measured coarse and refined update times, one line each (update_times.txt)."""
    lines = []
    for label, entry in result["timings"].items():
        for update in entry["updates"]:
            size = update.get("size")
            extra = ""
            if update.get("rows"):
                first, end, height = update["rows"]
                extra = f" rows {first}-{end} of {height}, samples {update['samples']}"
            lines.append(f"{label:17s} {update['work']:8s} {'' if not size else '%dx%d' % tuple(size):8s} "
                         f"{update['seconds'] * 1000:7.1f} ms{extra}")
    return lines


def _publish(folder: Path) -> None:
    """Replace tests/artifacts/screenshots as a whole with this run's files: no file of an earlier
    (or failed) run is left among them, and the tests read only this run's own folder."""
    SHOTS.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".screenshots-", dir=SHOTS.parent))
    shutil.copytree(folder, staging, dirs_exist_ok=True)
    for _attempt in range(3):  # another run of this checkout may publish at the same moment
        shutil.rmtree(SHOTS, ignore_errors=True)
        try:
            staging.rename(SHOTS)
            return
        except OSError:
            continue
    shutil.rmtree(staging, ignore_errors=True)


@pytest.fixture(scope="module")
def session():
    """Run the GUI session once, in a scratch folder of its own; (result.json as a dict, {shot name:
    pixels}). Its files are then published to tests/artifacts/screenshots."""
    with scratch_dir("vsgl-gui-") as folder:
        build, user, shots = folder / "build", folder / "user", folder / "screenshots"
        for path in (build, user, shots):
            path.mkdir()
        proc = run_blender("--command", "extension", "build", "--source-dir", str(REPO), "--output-dir", str(build))
        assert proc.returncode == 0, describe(proc)
        env = {"BLENDER_USER_RESOURCES": str(user)}
        proc = run_blender("--command", "extension", "install-file", "-r", "user_default", "-e",
                           str(next(build.glob("*.zip"))), blender_env=env)
        assert proc.returncode == 0, describe(proc)
        # real-blender gui picks a free X display itself (Xvfb -displayfd): no display number here.
        # --wait and the timeout only guard against a hang: the script ends the session when done.
        proc = subprocess.run(
            [str(REAL_BLENDER), "gui", "--size", f"{SCREEN[0]}x{SCREEN[1]}", "--wait", "600",
             "--shot", str(shots / "final.png"), "demo.blend", "--python",
             str(REPO / "tests" / "gui_overlay_script.py")],
            cwd=REPO, env=blender_environment(env | {"BLENDER_VSGL_SHOTS": str(shots)}),
            capture_output=True, text=True, timeout=900)
        result_file = shots / "result.json"
        result = json.loads(result_file.read_text()) if result_file.is_file() else None
        if result is not None:
            (shots / "update_times.txt").write_text("\n".join(_update_times(result)) + "\n")
        (shots / "session.log").write_text(describe(proc))
        _publish(shots)
        assert proc.returncode == 0, describe(proc)
        assert result is not None, describe(proc)
        assert not result["errors"], "\n".join(result["errors"]) + "\n" + describe(proc)
        assert "Traceback" not in proc.stdout + proc.stderr, describe(proc)
        pixels = {name: _screenshot(shots / file) for name, file in result["shots"].items()}
    return result, pixels


def _at(image, point, radius=6):
    """Mean colour of a (2 radius)² square around a window point (origin at the bottom left)."""
    x, y = int(round(point[0])), SCREEN[1] - int(round(point[1]))
    return image[y - radius:y + radius, x - radius:x + radius].reshape(-1, 3).mean(axis=0)


def _region(image, region):
    x, y, width, height = region
    return image[SCREEN[1] - (y + height):SCREEN[1] - y, x:x + width]


def test_every_screenshot_was_taken(session):
    result, pixels = session
    assert sorted(result["shots"]) == ["01_sidebar_overlay_off", "02_overlay_on_indirect_only",
                                       "03_overlay_added_to_solid", "04_vsgl_count_1", "05_after_orbit_view_only",
                                       "06_after_moving_the_spot", "07_overlay_switched_off",
                                       "08_render_properties"]
    for name, image in pixels.items():
        assert image.shape == (SCREEN[1], SCREEN[0], 3), name


def test_sidebar_shows_the_vsgl_tab(session):
    result, pixels = session
    assert result["sidebar"]["category"] == "VSGL"
    x, y, width, height = result["sidebar"]["rect"]
    assert width > 150 and height > 300
    # The panel is drawn there: not a flat colour.
    assert _region(pixels["01_sidebar_overlay_off"], (x, y, width, height)).std() > 10


def test_overlay_on_shows_red_bounce_on_the_white_walls(session):
    result, pixels = session
    off, on, added = (pixels[n] for n in ("01_sidebar_overlay_off", "02_overlay_on_indirect_only",
                                          "03_overlay_added_to_solid"))
    for name in ("back_wall_low", "left_wall_low"):
        point = result["points"][name]
        before, indirect, sum_ = _at(off, point), _at(on, point), _at(added, point)
        # Off: a grey solid-shaded wall. On: red bounce light (red well above green and blue).
        assert abs(before[0] - before[2]) < 12, (name, before)
        assert indirect[0] > indirect[1] + 25 and indirect[0] > indirect[2] + 25, (name, indirect)
        assert np.abs(indirect - before).max() > 25, (name, before, indirect)
        # Added: the grey wall, redder.
        assert sum_[0] > before[0] + 5 and sum_[0] - sum_[2] > before[0] - before[2] + 5, (name, before, sum_)
    # The whole viewport changes where the overlay is drawn, and only inside the viewport.
    region = result["region"]
    assert np.abs(_region(on, region) - _region(off, region)).mean() > 10
    assert np.abs(on[:20] - off[:20]).mean() < 1  # the top bar is untouched


def test_a_parameter_change_visibly_changes_the_overlay(session):
    result, pixels = session
    region = result["region"]
    many, few = _region(pixels["02_overlay_on_indirect_only"], region), _region(pixels["04_vsgl_count_1"], region)
    changed = np.abs(many - few).max(axis=-1) > 12
    assert changed.mean() > 0.02, changed.mean()


def test_view_change_reuses_light_passes_and_off_frees(session):
    result, pixels = session
    assert result["scene_version_after_orbit"] == result["scene_version_before_orbit"]
    assert result["scene_version_after_move"] > result["scene_version_before_move"]
    # A view change starts from a coarse image on the kept light passes; a scene change reruns them.
    view_updates = [u["work"] for u in result["timings"]["view_change"]["updates"]]
    assert view_updates[0] == "coarse" and view_updates[-1] == "sample", view_updates
    scene_updates = [u["work"] for u in result["timings"]["scene_change"]["updates"]]
    assert scene_updates[0] == "lights" and scene_updates[-1] == "sample", scene_updates
    assert result["gpu_resources_after_off"] == 0
    region = result["region"]
    assert np.abs(_region(pixels["07_overlay_switched_off"], region)
                  - _region(pixels["06_after_moving_the_spot"], region)).mean() > 2


def test_update_times_are_recorded(session):
    """Every timed change went coarse (or lights and coarse) first and ended with its samples, in
    bands of rows; the times go to the artefacts (update_times.txt). How long they take is
    benchmarks/interactive.py's question: a loaded machine must not fail this test."""
    result, _pixels = session
    assert set(result["timings"]) == {"first", "parameter_change", "view_change", "scene_change"}
    for label, entry in result["timings"].items():
        updates = entry["updates"]
        assert updates and updates[0]["level"] == "coarse", (label, updates)
        assert updates[-1]["level"] == "sample" and updates[-1]["samples"] == 1, (label, updates)
        for update in updates:
            assert update["seconds"] >= 0 and "error" not in update, (label, update)
            if update["level"] == "sample":
                first, end, height = update["rows"]
                assert 0 <= first <= end <= height, (label, update)


def test_render_properties_and_look_dev_preview(session):
    result, pixels = session
    assert result["preview"]["outcome"] == ["FINISHED"]
    assert result["preview"]["images"] == ["VSGL N256 K1 Modified RSM128 Seed0 Combined"]
    x, y, width, height = result["properties_rect"]
    # The properties editor now shows other panels than before (the VSGL ones).
    assert np.abs(_region(pixels["08_render_properties"], (x, y, width, height))
                  - _region(pixels["07_overlay_switched_off"], (x, y, width, height))).mean() > 3
