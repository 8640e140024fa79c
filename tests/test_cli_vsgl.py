# SPDX-License-Identifier: GPL-3.0-or-later
"""`python -m vsgl_addon vsgl SCENE.blend --out VSGLS.npz ...`."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

import scene_builders as sb

REPO = Path(__file__).resolve().parents[1]
PER_VSGL = {"light_index": (), "mean": (3,), "variance": (), "diffuse_mean": (3,), "diffuse_variance": (),
            "specular_mean": (3,), "specular_variance": (), "diffuse_amplitude": (3,), "diffuse_axis": (3,),
            "diffuse_sharpness": (), "specular_amplitude": (3,), "specular_axis": (3,),
            "specular_sharpness": (), "power": (3,), "kernel_center": (2,), "kernel_level": ()}
PER_LIGHT = {"rsm_total_power": (3,), "rsm_size": ()}


def _run(*arguments, timeout=300):
    return subprocess.run([sys.executable, "-m", "vsgl_addon", *map(str, arguments)], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def demo_like_blend(tmp_path_factory):
    """A glossy red floor and a wall under a spot and a point light, a zero-power light, and
    scene.vsgl.vsgl_count = 32 saved in the file."""
    path = tmp_path_factory.mktemp("blend") / "scene.blend"
    scene = sb.reset()
    floor = sb.plane("Floor", size=8.0)
    floor.data.materials.append(sb.principled("Glossy floor", base_color=(0.8, 0.2, 0.1), roughness=0.2))
    sb.plane("Wall", size=8.0, location=(0, 3, 2), rotation=(math.radians(90), 0, 0))
    sb.spot_light(power=1000.0, location=(0, -1, 4), look_at_point=(0, 0, 0))
    sb.point_light(power=200.0, location=(2, 0, 2))
    sb.light("POINT", name="Dark", power=0.0, location=(1, 1, 1))
    sb.camera()
    from vsgl_addon import register, unregister

    register()
    try:
        scene.vsgl.vsgl_count = 32
        scene.vsgl.rsm_size = 64
        bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    finally:
        unregister()
    return path


def _load(path):
    with np.load(path) as table:
        return {name: table[name] for name in table.files}


def test_export_has_the_issue_s_arrays_and_the_scene_s_own_settings(demo_like_blend, tmp_path):
    out = tmp_path / "vsgls.npz"
    result = _run("vsgl", demo_like_blend, "--out", out)
    assert result.returncode == 0, result.stderr
    table = _load(out)
    lights = 2  # the zero-power light costs nothing and is not a light of the description
    count = len(table["light_index"])
    for name, shape in PER_VSGL.items():
        assert table[name].shape == (count, *shape), name
    for name, shape in PER_LIGHT.items():
        assert table[name].shape == (lights, *shape), name
    # N = 32 from scene.vsgl is the frame's, shared by the two lights by bounce power (planner.py).
    per_light = np.bincount(table["light_index"], minlength=lights)
    assert per_light.sum() == 32 and per_light.min() >= 1
    assert table["rsm_size"].tolist() == [64, 64]
    for name, values in table.items():
        assert np.all(np.isfinite(values)), name
    # Summed VSGL power estimates each light's RSM total (000 Eq. 5); one lattice, so a few %.
    for light in range(lights):
        estimate = table["power"][table["light_index"] == light].sum(axis=0)
        total = table["rsm_total_power"][light]
        assert total.min() > 0
        np.testing.assert_allclose(estimate, total, rtol=0.05)
    assert count == 32 and "32 VSGLs from 2 lights" in result.stdout


def test_flags_override_the_scene_for_this_run(demo_like_blend, tmp_path):
    out = tmp_path / "vsgls.npz"
    result = _run("vsgl", demo_like_blend, "--out", out, "--vsgl-count", 5, "--k", 4, "--kernel", "original",
                  "--rsm-size", 32, "--seed", 7)
    assert result.returncode == 0, result.stderr
    table = _load(out)
    assert np.bincount(table["light_index"]).sum() == 5 and np.bincount(table["light_index"]).min() >= 1
    assert table["rsm_size"].tolist() == [32, 32]
    assert "original kernel, N = 5, K = 4, RSM 32², seed 7, per-lobe positions" in result.stdout
    assert not np.array_equal(table["diffuse_mean"], table["specular_mean"])  # the default: per lobe
    shared = _run("vsgl", demo_like_blend, "--out", out, "--vsgl-count", 5, "--positional-distribution", "shared")
    assert shared.returncode == 0, shared.stderr
    table = _load(out)
    np.testing.assert_array_equal(table["diffuse_mean"], table["mean"])
    np.testing.assert_array_equal(table["specular_variance"], table["variance"])
    assert "shared positions" in shared.stdout
    two = _run("vsgl", demo_like_blend, "--out", out, "--kernel", "two-vsgl")
    assert two.returncode == 0, two.stderr
    table = _load(out)
    # 003's mode: two VSGLs (diffuse, specular) per RSM view.
    assert len(table["light_index"]) == 2 * int(table["rsm_view_count"].sum())


def test_the_seed_moves_the_kernels_and_repeats_exactly(demo_like_blend, tmp_path):
    tables = []
    for seed in (1, 1, 2):
        out = tmp_path / f"seed{len(tables)}.npz"
        assert _run("vsgl", demo_like_blend, "--out", out, "--seed", seed, "--vsgl-count", 16).returncode == 0
        tables.append(_load(out))
    np.testing.assert_array_equal(tables[0]["kernel_center"], tables[1]["kernel_center"])
    assert not np.allclose(tables[0]["kernel_center"], tables[2]["kernel_center"])


@pytest.mark.parametrize("arguments, says", [
    (["vsgl", "/nonexistent/scene.blend", "--out", "OUT"], "no such file"),
    (["vsgl", "README.md", "--out", "OUT"], "not a .blend file"),
    (["vsgl", "BLEND", "--out", "/nonexistent/folder/v.npz"], "no such folder"),
    (["vsgl", "BLEND", "--out", "OUT.txt"], "must be a .npz file"),
    (["vsgl", "BLEND", "--out", "OUT", "--vsgl-count", "0"], "VSGL count must be in [1, 4096]"),
    (["vsgl", "BLEND", "--out", "OUT", "--vsgl-count", "4097"], "VSGL count must be in [1, 4096]"),
    (["vsgl", "BLEND", "--out", "OUT", "--k", "0.1"], "K must be in [0.25, 16]"),
    (["vsgl", "BLEND", "--out", "OUT", "--k", "nan"], "K must be a finite number"),
    (["vsgl", "BLEND", "--out", "OUT", "--rsm-size", "100"], "power of two"),
    (["vsgl", "BLEND", "--out", "OUT", "--kernel", "fancy"], "invalid choice"),
    (["vsgl", "BLEND", "--out", "OUT", "--positional-distribution", "both"], "invalid choice"),
    (["vsgl", "BLEND", "--out", "OUT", "--vsgl-count", "many"], "not a whole number"),
    (["vsgl", "BLEND"], "required: --out"),
])
def test_bad_input_is_one_clear_line_and_exit_code_2(arguments, says, demo_like_blend, tmp_path):
    arguments = [str(demo_like_blend) if a == "BLEND" else str(tmp_path / "v.npz") if a == "OUT" else a
                 for a in arguments]
    result = _run(*arguments)
    assert result.returncode == 2, result.stderr
    lines = [line for line in result.stderr.splitlines() if "EGL" not in line and line.strip()]
    assert len(lines) == 1 and says in lines[0], result.stderr
    assert not (tmp_path / "v.npz").exists()


def test_a_broken_blend_file_is_one_clear_line(tmp_path):
    broken = tmp_path / "broken.blend"
    broken.write_bytes(b"BLENDER-v500" + bytes(64))
    result = _run("vsgl", broken, "--out", tmp_path / "v.npz")
    assert result.returncode == 2
    lines = [line for line in result.stderr.splitlines() if "EGL" not in line and line.strip()]
    assert "Traceback" not in result.stderr and lines and "could not open it" in lines[-1], result.stderr
