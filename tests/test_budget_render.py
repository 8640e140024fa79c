# SPDX-License-Identifier: GPL-3.0-or-later
"""Budget mode end to end: calibration at first use into the user's cache, the budgeted frame at the
output size with its predicted and measured time in the plan, the command line's --time-budget
(render and vsgl), and a bad cache file's one warning. Times are reported, never asserted."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from test_budget import _plan
from vsgl_addon import budget as B
from vsgl_addon.cli import UsageError, _settings, build_parser
from vsgl_addon.settings import VSGLSettings

REPO = Path(__file__).resolve().parents[1]


def _run(*arguments, cache: Path, timeout=300):
    env = {**__import__("os").environ, "XDG_CACHE_HOME": str(cache)}
    return subprocess.run([sys.executable, "-m", "vsgl_addon", *map(str, arguments)], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout, env=env)


@pytest.mark.parametrize("command", ["render", "vsgl"])
def test_the_time_budget_flag_sets_budget_mode_and_is_validated(command):
    stored = dict(vsgl_count=64, k=1.0, kernel="MODIFIED", rsm_size=64, seed=0, positional_distribution="PER_LOBE")
    scene = type("Scene", (), {"vsgl": type("Props", (), stored)})
    ext = ".exr" if command == "render" else ".npz"
    base = [command, "scene.blend", "--out", "out" + ext]
    assert _settings(scene, build_parser().parse_args(base)).quality_mode == "manual"
    budgeted = _settings(scene, build_parser().parse_args([*base, "--time-budget", "40"]))
    assert (budgeted.quality_mode, budgeted.time_budget_ms) == ("budget", 40.0)
    for bad in ("0", "nan", "1e9"):
        with pytest.raises(UsageError, match="time budget"):
            _settings(scene, build_parser().parse_args([*base, "--time-budget", bad]))
    # --quality picks Manual or Auto; with --time-budget it would ask for two modes.
    for quality in ("auto", "manual"):
        assert _settings(scene, build_parser().parse_args([*base, "--quality", quality])).quality_mode == quality
    with pytest.raises(UsageError, match="two quality modes"):
        _settings(scene, build_parser().parse_args([*base, "--quality", "auto", "--time-budget", "40"]))
    with pytest.raises(UsageError, match="invalid choice: 'budget'"):
        build_parser().parse_args([*base, "--quality", "budget"])


@pytest.mark.gpu
def test_first_use_calibrates_into_the_cache_and_the_frame_reports_predicted_and_measured(monkeypatch, tmp_path):
    from vsgl_addon.budget_render import CALIBRATION, model_for, render_budgeted, scene_key
    from vsgl_addon.renderer import FrameRenderer

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    room, _ = _plan()
    settings = VSGLSettings(quality_mode="budget", time_budget_ms=50.0, visibility=False)
    renderer = FrameRenderer()
    try:
        model = model_for(renderer, room, settings, 48, 36, "test gpu")
        assert B.cache_path().is_file() and len(model.samples) == len(CALIBRATION)
        assert scene_key(room) in model.corrections
        assert B.load_model("test gpu").coefficients == model.coefficients
        images, choice, refitted = render_budgeted(renderer, room, settings, 48, 36, model)
    finally:
        renderer.free()
    assert images.combined.shape == (36, 48, 3) and images.coverage.shape == (36, 48)
    assert np.all(np.isfinite(images.combined))
    assert choice.measured_seconds == pytest.approx(sum(images.timings.values()))
    assert choice.size == B.scaled_size(48, 36, choice.candidate.scale)
    report = images.plan.to_dict()["budget"]
    assert report["target_ms"] == 50.0 and report["predicted_ms"] > 0.0 and report["measured_ms"] > 0.0
    assert len(refitted.samples) == len(CALIBRATION) + 1


@pytest.mark.gpu
def test_the_command_line_prints_predicted_and_measured_time_and_warns_once_for_a_bad_cache(tmp_path):
    out, report = tmp_path / "demo.exr", tmp_path / "demo.json"
    result = _run("render", REPO / "demo.blend", "--out", out, "--resolution", "48x36", "--time-budget", 400,
                  "--report", report, cache=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "time budget: target 400 ms, predicted " in result.stdout and "measured" in result.stdout
    budget = json.loads(report.read_text())["plan"]["budget"]
    assert budget["target_ms"] == 400.0 and budget["measured_ms"] > 0.0 and budget["size"] == [48, 36]
    assert any(line.startswith("  Budget: on — target 400 ms") for line in result.stdout.splitlines())
    cache = tmp_path / "vsgl-addon" / B.CACHE_NAME
    assert cache.is_file()
    cache.write_text("{broken")
    export = _run("vsgl", REPO / "demo.blend", "--out", tmp_path / "vsgls.npz", "--time-budget", 400, cache=tmp_path)
    assert export.returncode == 0, export.stderr
    warnings = [line for line in export.stderr.splitlines() if "cost model cache" in line]
    assert len(warnings) == 1 and "unreadable" in warnings[0] and "built-in cost model" in warnings[0]
    assert "Budget: on — target 400 ms" in export.stdout
