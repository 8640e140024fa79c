# SPDX-License-Identifier: GPL-3.0-or-later
"""The VSGL render engine and `python -m vsgl_addon render`."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import OpenEXR
import pytest

import cycles_truth
import scene_builders as sb
from vsgl_addon.renderer import FrameRenderer
from vsgl_addon.scene import extract_scene
from vsgl_addon.settings import VSGLSettings

REPO = Path(__file__).resolve().parents[1]
LAYERS = ("Combined", "Direct", "Indirect", "Indirect Diffuse", "Indirect Specular", "Indirect Glossy Reflectors",
          "Indirect Caustics")


def _run(*arguments, timeout=300):
    return subprocess.run([sys.executable, "-m", "vsgl_addon", *map(str, arguments)], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout)


def read_layers(path) -> dict[str, np.ndarray]:
    """Layer name -> (H, W, C) float32 (RGB or RGBA) of a Blender multilayer EXR; row 0 = top."""
    layers = {}
    with OpenEXR.File(str(path), separate_channels=True) as exr:
        for part in exr.parts:
            for name, channel in part.channels.items():
                view_layer, layer, component = name.rsplit(".", 2)
                layers.setdefault(layer, {})[component] = channel.pixels
    return {name: np.stack([c[k] for k in "RGBA" if k in c], axis=-1) for name, c in layers.items()}


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    folder = tmp_path_factory.mktemp("render")
    out, report = folder / "demo.exr", folder / "report.json"
    result = _run("render", REPO / "demo.blend", "--out", out, "--resolution", "96x72", "--vsgl-count", 64,
                  "--report", report)
    assert result.returncode == 0, result.stderr
    return out, report, result


def test_render_command_writes_every_layer_and_they_add_up(rendered):
    out, _, _ = rendered
    layers = read_layers(out)
    assert set(LAYERS) <= set(layers), sorted(layers)
    for name in LAYERS:
        assert layers[name].shape[:2] == (72, 96), name
        assert np.all(np.isfinite(layers[name])), name
    np.testing.assert_allclose(layers["Combined"][..., :3], layers["Direct"] + layers["Indirect"], rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(layers["Indirect"], layers["Indirect Diffuse"] + layers["Indirect Specular"],
                               rtol=1e-5, atol=1e-7)
    assert layers["Indirect"].mean() > 0.0 and layers["Direct"].mean() > layers["Indirect"].mean()
    # MRP-ASG's pass is a part of Indirect Specular.
    reflectors = layers["Indirect Glossy Reflectors"]
    assert reflectors.max() > 0.0 and np.all(reflectors <= layers["Indirect Specular"] + 1e-6)
    # The glossy VPLs' pass (the polished floor's light on the walls) is a part of Indirect Diffuse.
    caustics = layers["Indirect Caustics"]
    assert caustics.max() > 0.0 and np.all(caustics <= layers["Indirect Diffuse"] + 1e-6)
    # The red floor bounces red light: the indirect light is redder than white.
    mean = layers["Indirect"].reshape(-1, 3).mean(axis=0)
    assert mean[0] > 2 * mean[1], mean
    assert out.with_suffix(".png").stat().st_size > 1000


def test_render_report_has_timings_counts_parameters_and_renderer(rendered):
    _, report, result = rendered
    data = json.loads(report.read_text())
    assert {"rsm_and_vsgl_generation", "gbuffer", "direct_light", "vsgl_shading"} <= set(data["timings"])
    # The demo's glossy red floor is a rectangle proxy and a sharp reflector: the diffuse receivers' set
    # leaves its specular flux to the VPLs, the glossy one to MRP-ASG, a third keeps it for the
    # receivers MRP-ASG leaves (light-paths.md): three VSGL sets, the glossy one with
    # planner.GLOSSY_SET_FACTOR × N.
    from vsgl_addon.planner import GLOSSY_SET_FACTOR

    assert data["counts"]["proxies"] >= 1 and "mrp_asg" in data["timings"]
    assert data["counts"]["vsgls"] == (2 + GLOSSY_SET_FACTOR) * 64 and data["counts"]["lights"] == 1
    assert data["counts"]["vpls"] > 0 and data["counts"]["vpls_per_pixel"] > 0.0 and "vpl_culling" in data["timings"]
    assert data["settings"]["caustics"] is True and data["settings"]["delta"] == 0.001
    assert data["count_labels"]["vpls_per_pixel"] == "VPLs per Pixel"
    # ... and the report lists it: object, size, its material's roughness, the lights reaching it.
    assert len(data["proxies"]) == data["counts"]["proxies"]
    floor = data["proxies"][0]
    assert floor["object"] and len(floor["lit_by"]) == data["counts"]["lights"] == 1 and floor["lit_by"][0]
    assert min(floor["size"]) > 0.5 and 0.0 <= floor["roughness"] < 1.0 and floor["alpha"] < 0.1
    assert data["settings"]["vsgl_count"] == 64 and data["settings"]["kernel"] == "modified"
    assert data["settings"]["positional_distribution"] == "per-lobe"
    assert data["resolution"] == [96, 72] and "llvmpipe" in data["gpu_renderer"]
    assert "vsgl_shading" in result.stdout
    # The frame plan: N = 64 per VSGL set (the glossy one GLOSSY_SET_FACTOR × N), MRP-ASG and the VPLs
    # on for the floor, each decision's reason.
    plan = data["plan"]
    assert plan["vsgls"] == {"diffuse": 64, "glossy": GLOSSY_SET_FACTOR * 64, "all": 64}
    assert plan["decisions"]["mrp_asg"]["run"]
    assert plan["decisions"]["vpl_pass"]["run"] and plan["decisions"]["whole_set"]["run"]
    assert all(decision["reason"] for decision in plan["decisions"].values())
    assert "frame plan:" in result.stdout and plan["summary"][0] in result.stdout


@pytest.mark.parametrize("arguments, says", [
    (["render", "/nonexistent.blend", "--out", "OUT"], "no such file"),
    (["render", "BLEND", "--out", "OUT", "--resolution", "0x10"], "each side must be in [1, 16384]"),
    (["render", "BLEND", "--out", "OUT", "--resolution", "big"], "not WIDTHxHEIGHT"),
    (["render", "BLEND", "--out", "OUT.png"], "must be a .exr file"),
    (["render", "BLEND", "--out", "OUT", "--report", "/nonexistent/r.json"], "no such folder"),
    (["render", "BLEND", "--out", "OUT", "--k", "32"], "K must be in [0.25, 16]"),
])
def test_render_bad_input_is_one_line_and_exit_code_2(arguments, says, tmp_path):
    arguments = [str(REPO / "demo.blend") if a == "BLEND" else str(tmp_path / "out.exr") if a == "OUT" else a
                 for a in arguments]
    result = _run(*arguments)
    assert result.returncode == 2, result.stderr
    lines = [line for line in result.stderr.splitlines() if "EGL" not in line and line.strip()]
    assert len(lines) == 1 and says in lines[0], result.stderr
    assert not (tmp_path / "out.exr").exists()


def _small_scene():
    scene = sb.reset()
    floor = sb.plane("Floor", size=4.0)
    floor.data.materials.append(sb.principled("Red", base_color=(0.8, 0.1, 0.05), roughness=0.3))
    wall = sb.plane("Wall", size=4.0, location=(0, 1.5, 1.5), rotation=(math.radians(90), 0, 0))
    wall.data.materials.append(sb.principled("White", base_color=(0.8, 0.8, 0.8), roughness=0.7))
    sb.spot_light(power=800.0, location=(0, -0.5, 3), look_at_point=(0, 0.3, 0), spot_size=math.radians(50))
    sb.camera(location=(0, -4, 2), look_at_point=(0, 0.5, 0.8), resolution=(48, 36))
    return scene


@pytest.mark.gpu
def test_engine_renders_through_blender_with_resolution_percentage(tmp_path):
    from vsgl_addon import register, unregister

    scene = _small_scene()
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 64, 48, 50
    register()
    try:
        scene.render.engine = "VSGL"
        bpy.ops.render.render(scene=scene.name)
        scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
        scene.render.image_settings.color_depth = "32"
        bpy.data.images["Render Result"].save_render(str(tmp_path / "r.exr"), scene=scene)
    finally:
        unregister()
    layers = read_layers(tmp_path / "r.exr")
    assert layers["Combined"].shape == (24, 32, 4)
    assert set(LAYERS) <= set(layers)
    assert layers["Indirect"].max() > 0


#: (resolution x, y, percentage): odd sizes, and sizes where resolution × (percentage / 100.0) in
#: float falls just below the integer (100 × 0.29 = 28.999...), the case Blender's integer rule
#: resolution × percentage // 100 (BKE_render_resolution) decides.
PERCENTAGE_SIZES = [(100, 77, 29), (101, 75, 33), (99, 73, 37), (101, 77, 50), (50, 101, 58),
                    (97, 71, 67), (101, 63, 100)]


@pytest.mark.gpu
@pytest.mark.parametrize("x, y, percentage", PERCENTAGE_SIZES)
def test_engine_image_and_camera_have_the_size_blender_renders(x, y, percentage, tmp_path):
    """The Render Result Blender allocates, the image the engine renders and the camera's resolution
    (its aspect) are one size at any percentage."""
    from vsgl_addon import engine, register, unregister
    from vsgl_addon.views import render_size

    scene = _small_scene()
    scene.render.resolution_x, scene.render.resolution_y = x, y
    scene.render.resolution_percentage = percentage
    register()
    try:
        scene.render.engine = "VSGL"
        engine.last_frame_statistics.clear()  # only this render's figures, not an earlier test's
        bpy.ops.render.render(scene=scene.name)
        scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
        scene.render.image_settings.color_depth = "32"
        bpy.data.images["Render Result"].save_render(str(tmp_path / "r.exr"), scene=scene)
        camera = extract_scene(sb.depsgraph(scene)).camera
    finally:
        unregister()
    height, width = read_layers(tmp_path / "r.exr")["Combined"].shape[:2]
    assert engine.last_frame_statistics["resolution"] == [width, height]
    assert camera.resolution == (width, height) == render_size(scene.render)


@pytest.mark.gpu
@pytest.mark.parametrize("settings", [
    VSGLSettings(vsgl_count=1), VSGLSettings(vsgl_count=4096, rsm_size=64), VSGLSettings(k=0.25),
    VSGLSettings(k=16.0), VSGLSettings(rsm_size=1), VSGLSettings(kernel="original", k=16.0),
    VSGLSettings(kernel="two-vsgl", rsm_size=64), VSGLSettings(vsgl_count=4096, positional_distribution="shared"),
    VSGLSettings(vsgl_count=1, rsm_size=1, positional_distribution="shared"),
], ids=lambda s: f"N{s.vsgl_count}-K{s.k:g}-{s.kernel}-rsm{s.rsm_size}-{s.positional_distribution}")
def test_no_nan_or_inf_reaches_a_pixel_at_the_parameter_extremes(settings):
    images = sb.render_frame(_small_scene(), settings, 48, 36)
    sb.assert_finite_frame(images)
    assert images.indirect.max() > 0.0


@pytest.mark.gpu
def test_mean_indirect_radiance_is_within_10_percent_of_cycles():
    """Units and energy: the demo's one-bounce indirect light, VSGL versus Cycles (max bounces 1)."""
    from vsgl_addon import register, unregister

    register()
    try:
        bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"))
        scene = bpy.context.scene
        scene.render.resolution_x, scene.render.resolution_y = 96, 72
        truth = cycles_truth.indirect_radiance(cycles_truth.render_cycles(scene, samples=64, max_bounces=1))
        settings = VSGLSettings.from_properties(scene.vsgl)
        description = extract_scene(bpy.context.evaluated_depsgraph_get())
    finally:
        unregister()
    renderer = FrameRenderer()
    try:
        ours = renderer.render(description, settings, 96, 72).indirect
    finally:
        renderer.free()
    ratio = ours.mean() / truth.mean()
    print(f"mean indirect radiance, VSGL / Cycles: {ratio:.3f}")
    assert 0.9 <= ratio <= 1.1
