# SPDX-License-Identifier: GPL-3.0-or-later
"""Rendered shading with the VSGL engine in the Blender 5.2 application, with its window.

Builds and installs the extension into a clean profile, opens demo.blend with `real-blender gui`
and lets tests/gui_rendered_script.py drive it. The screenshots are kept as test artefacts in
tests/artifacts/rendered/ (gitignored; replaced as a whole by each run), with result.json, f12.png
(the F12 render of the same camera, saved with the scene's colour management) and session.log:

    01_rendered_camera.png                Rendered shading through the camera, converged
    02_rendered_after_moving_the_spot.png the spot moved: the light passes rerun
    03_solid.png, 04_rendered_again.png,  Solid -> Rendered -> Solid under a GPU resource tracker
    05_solid_again.png
    06_two_rendered_viewports.png         the viewport split: two Rendered viewports, two views
    07_addon_disabled.png                 the add-on disabled with Rendered viewports open
    08_addon_enabled_again.png            enabled again: both viewports render again
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
from test_overlay_real_blender import _screenshot

pytestmark = pytest.mark.real_blender

SHOTS = REPO / "tests" / "artifacts" / "rendered"
SCREEN = (1600, 900)


def _publish(folder: Path) -> None:
    SHOTS.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".rendered-", dir=SHOTS.parent))
    shutil.copytree(folder, staging, dirs_exist_ok=True)
    shutil.rmtree(SHOTS, ignore_errors=True)
    staging.rename(SHOTS)


@pytest.fixture(scope="module")
def session():
    with scratch_dir("vsgl-rendered-") as folder:
        build, user, shots = folder / "build", folder / "user", folder / "shots"
        for path in (build, user, shots):
            path.mkdir()
        proc = run_blender("--command", "extension", "build", "--source-dir", str(REPO), "--output-dir", str(build))
        assert proc.returncode == 0, describe(proc)
        env = {"BLENDER_USER_RESOURCES": str(user)}
        proc = run_blender("--command", "extension", "install-file", "-r", "user_default", "-e",
                           str(next(build.glob("*.zip"))), blender_env=env)
        assert proc.returncode == 0, describe(proc)
        proc = subprocess.run(
            [str(REAL_BLENDER), "gui", "--size", f"{SCREEN[0]}x{SCREEN[1]}", "--wait", "1500",
             "--shot", str(shots / "final.png"), "demo.blend", "--python",
             str(REPO / "tests" / "gui_rendered_script.py")],
            cwd=REPO, env=blender_environment(env | {"BLENDER_VSGL_SHOTS": str(shots)}),
            capture_output=True, text=True, timeout=1800)
        result_file = shots / "result.json"
        result = json.loads(result_file.read_text()) if result_file.is_file() else None
        (shots / "session.log").write_text(describe(proc))
        _publish(shots)
        assert proc.returncode == 0, describe(proc)
        assert result is not None, describe(proc)
        assert not result["errors"], "\n".join(result["errors"]) + "\n" + describe(proc)
        assert "Traceback" not in proc.stdout + proc.stderr, describe(proc)
        pixels = {name: _screenshot(SHOTS / file) for name, file in result["shots"].items()}
        pixels["f12"] = _screenshot(SHOTS / result["f12"])
    return result, pixels


def _luminance(image):
    return image[..., :3] @ np.array([0.2126, 0.7152, 0.0722])


def _camera_crop(result, image, inset=4):
    """The screenshot inside the camera frame (its dashed border left out), row 0 at the top."""
    frame = np.array(result["camera_frame"])
    x0, x1 = int(np.ceil(frame[:, 0].min())) + inset, int(np.floor(frame[:, 0].max())) - inset
    y0, y1 = int(np.ceil(frame[:, 1].min())) + inset, int(np.floor(frame[:, 1].max())) - inset
    return image[SCREEN[1] - y1:SCREEN[1] - y0, x0:x1]


def _resample(image, shape):
    """Nearest-neighbour resampling to (h, w): the F12 render onto the screenshot's crop."""
    h, w = image.shape[:2]
    ys = ((np.arange(shape[0]) + 0.5) * h / shape[0]).astype(int)
    xs = ((np.arange(shape[1]) + 0.5) * w / shape[1]).astype(int)
    return image[ys][:, xs]


def test_every_screenshot_was_taken(session):
    result, pixels = session
    assert sorted(result["shots"]) == ["01_rendered_camera", "02_rendered_after_moving_the_spot", "03_solid",
                                       "04_rendered_again", "05_solid_again", "06_two_rendered_viewports",
                                       "07_addon_disabled", "08_addon_enabled_again"]


def test_rendered_camera_view_matches_f12(session):
    """Target: luminance correlation >= 0.95 inside the camera frame (same passes, units and colour
    management; the viewport's selection outline and camera-frame lines are on top of it)."""
    result, pixels = session
    crop = _camera_crop(result, pixels["01_rendered_camera"])
    # The F12 image covers exactly the camera frame; the crop's inset is cut from it the same way.
    f12 = pixels["f12"]
    frame = np.array(result["camera_frame"])
    width, height = frame[:, 0].max() - frame[:, 0].min(), frame[:, 1].max() - frame[:, 1].min()
    fx, fy = 4 * f12.shape[1] / width, 4 * f12.shape[0] / height
    f12 = f12[int(round(fy)):f12.shape[0] - int(round(fy)), int(round(fx)):f12.shape[1] - int(round(fx))]
    f12 = _resample(f12, crop.shape[:2])
    a, b = _luminance(crop).ravel(), _luminance(f12).ravel()
    correlation = float(np.corrcoef(a, b)[0, 1])
    print(f"luminance correlation Rendered viewport vs F12: {correlation:.4f} over {a.size} pixels")
    (SHOTS / "f12_correlation.txt").write_text(f"{correlation:.4f}\n")
    assert correlation >= 0.95
    # Not only the same structure: the same brightness (within 10 % on average).
    assert abs(a.mean() - b.mean()) < 0.1 * b.mean(), (a.mean(), b.mean())


def test_the_viewport_converges_in_steps_with_its_status(session):
    result, _pixels = session
    (history,) = result["steps"]["first"]
    works = [entry["work"] for entry in history]
    assert history[0]["index"] == 0, "the step log lost its first entries"
    assert works[0] == "lights" and works.count("lights") == 1
    assert history[0]["level"] == "coarse"  # the light passes and a coarse image in one step
    samples = result["samples"]
    assert samples >= 2 and history[-1]["samples"] == samples and all("sample" == w for w in works[1:])
    steps = [entry["seconds"] for entry in history[1:]]
    print(f"refinement steps: {len(steps)}, median {np.median(steps) * 1000:.0f} ms, max {max(steps) * 1000:.0f} ms")
    assert result["first_status"] == ["VSGL sample %d/%d (converged) | %.0f ms/step" % (
        samples, samples, history[-1]["seconds"] * 1000)]


def test_moving_a_light_changes_the_image_within_a_step(session):
    result, pixels = session
    first = result["first_step_after_move"]
    assert first["work"] == "lights" and first["level"] == "coarse"
    assert result["lights_after_move"] > result["lights_before_move"]
    region = result["region"]
    before = pixels["01_rendered_camera"][SCREEN[1] - region[1] - region[3]:SCREEN[1] - region[1]]
    after = pixels["02_rendered_after_moving_the_spot"][SCREEN[1] - region[1] - region[3]:SCREEN[1] - region[1]]
    assert np.abs(after - before).max(axis=-1).mean() > 3


def test_solid_rendered_solid_leaves_no_gpu_resource(session):
    result, pixels = session
    assert result["gpu_objects_made"] > 0  # the Rendered viewport did make textures meanwhile
    assert result["gpu_objects_left"] == []
    assert result["pipelines_in_solid_after"] == 0
    # Rendered again looks as before Solid (the spot moved); Solid looks like Solid.
    assert np.abs(pixels["04_rendered_again"] - pixels["02_rendered_after_moving_the_spot"]).mean() < 3
    assert np.abs(pixels["05_solid_again"] - pixels["03_solid"]).mean() < 3


def test_two_viewports_and_enable_disable_enable(session):
    result, pixels = session
    assert len(result["steps"]["two_viewports"]) == 2
    for history in result["steps"]["two_viewports"]:
        assert history[-1]["samples"] == 2
    assert result["resources_at_end"] and all(count > 0 for count in result["resources_at_end"])
    two, disabled, enabled = (pixels[n] for n in ("06_two_rendered_viewports", "07_addon_disabled",
                                                  "08_addon_enabled_again"))
    assert np.abs(disabled - two).mean() > 2
    assert np.abs(enabled - two).mean() < 3
