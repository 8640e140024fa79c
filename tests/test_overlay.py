# SPDX-License-Identifier: GPL-3.0-or-later
"""The viewport overlay in the bpy module: the cache on the real passes, drawing, lifecycle
(vsgl_addon/overlay_cache.py, vsgl_addon/overlay.py; the scheduling alone: test_overlay_cache.py).

No window here, so the draw callback's parts are driven directly: request_view() (what the
callback records), step() (what the timer does: one unit of work per call), draw() into an
offscreen (what the callback draws), and the add-on's real handlers and timer function.
The scene is demo.blend: a spot-lit red floor next to two white walls.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import bpy
import numpy as np
import pytest

import vsgl_addon
from vsgl_addon import overlay, overlay_cache
from vsgl_addon.overlay_cache import COARSE, REFINE_DELAY, REFINED, OverlayCache, overlay_size
from vsgl_addon.scene import extract_scene
from vsgl_addon.settings import OVERLAY_DISPLAYS, VSGLSettings
from vsgl_addon.views import band_projection

pytestmark = pytest.mark.gpu

REPO = Path(__file__).resolve().parents[1]
REGION = (160, 120)  # a small viewport: the refined overlay at scale 0.5 is 80 x 60
SETTINGS = VSGLSettings(vsgl_count=64, rsm_size=64)


@pytest.fixture
def demo():
    """demo.blend opened, the add-on registered; unregistered (and checked clean) afterwards."""
    vsgl_addon.unregister()
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"), load_ui=False)
    vsgl_addon.register()
    yield bpy.context.scene
    vsgl_addon.unregister()
    assert overlay.cache.gpu_resource_count() == 0
    assert not overlay.is_installed()
    bpy.ops.wm.read_factory_settings(use_empty=True)


@pytest.fixture(autouse=True)
def one_band(monkeypatch):
    """One refined image per step (the band-by-band refinement has its own test)."""
    monkeypatch.setattr(overlay_cache, "STEP_BUDGET", 1e9)


def camera_view(scene):
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    return description.camera.view_matrix(), description.camera.projection_matrix()


def describe():
    return extract_scene(bpy.context.evaluated_depsgraph_get())


def run_until_idle(cache, settings=SETTINGS, scale=0.5, now=100.0, limit=20):
    """Step until nothing is pending at time `now`; the list of work done."""
    done = []
    for _ in range(limit):
        work = cache.step(describe, settings, scale, now=now)
        if work is None:
            return done
        done.append(work)
    raise AssertionError(f"still busy after {limit} steps: {done}")


def draw_to_array(cache, key, display="indirect", scale=1.0, size=REGION):
    import gpu

    offscreen = gpu.types.GPUOffScreen(*size, format="RGBA32F")
    try:
        with offscreen.bind():
            framebuffer = gpu.state.active_framebuffer_get()
            framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0))
            gpu.state.viewport_set(0, 0, *size)
            drawn = cache.draw(key, display, scale)
            buffer = framebuffer.read_color(0, 0, size[0], size[1], 4, 0, "FLOAT")
        buffer.dimensions = size[0] * size[1] * 4
        return drawn, np.array(buffer, np.float32).reshape(size[1], size[0], 4)
    finally:
        offscreen.free()


def test_overlay_size_coarse_is_a_quarter_per_side():
    assert overlay_size((1280, 720), 0.25, REFINED) == (320, 180)
    assert overlay_size((1280, 720), 0.25, COARSE) == (80, 45)
    assert overlay_size((3, 3), 0.02, COARSE) == (1, 1)


def test_coarse_first_then_refined_when_nothing_changes(demo):
    cache = OverlayCache()
    try:
        view, projection = camera_view(demo)
        cache.request_view(1, view, projection, REGION, now=0.0)
        # Right after a change: the light passes, then the coarse image, and nothing more yet.
        assert run_until_idle(cache, now=0.0) == ["lights", COARSE]
        assert cache.views[1].size == overlay_size(REGION, 0.5, COARSE)
        # Once nothing changed for REFINE_DELAY: the refined image.
        assert run_until_idle(cache, now=REFINE_DELAY + 0.01) == [REFINED]
        assert cache.views[1].level == REFINED and cache.views[1].size == (80, 60)
        assert cache.statistics["level"] == REFINED and cache.statistics["timings"]["vsgl_shading"] > 0
        assert set(cache.statistics["light_timings"]) >= {"scene_extraction", "rsm_and_vsgl_generation"}
        assert [entry["level"] for entry in cache.history] == ["lights", COARSE, REFINED]
    finally:
        cache.free()
    assert cache.gpu_resource_count() == 0


def test_view_change_does_not_rerun_the_light_passes(demo, monkeypatch):
    from vsgl_addon import renderer

    builds = []
    original = renderer.SceneLights.build.__func__
    monkeypatch.setattr(renderer.SceneLights, "build",
                        classmethod(lambda cls, *a: builds.append(1) or original(cls, *a)))
    cache = OverlayCache()
    try:
        view, projection = camera_view(demo)
        cache.request_view(1, view, projection, REGION, now=0.0)
        run_until_idle(cache, now=10.0)
        assert len(builds) == 1
        lights = cache.lights
        # Orbit: another view matrix. G-buffer and shading only.
        turned = np.array(view)
        c, s = math.cos(0.2), math.sin(0.2)
        turned = turned @ np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
        assert cache.request_view(1, turned, projection, REGION, now=20.0)
        assert not cache.request_view(1, turned, projection, REGION, now=20.0)  # the same again: no change
        assert run_until_idle(cache, now=20.0) == [COARSE]
        assert run_until_idle(cache, now=30.0) == [REFINED]
        assert len(builds) == 1 and cache.lights is lights
        # A second viewport shares the light passes.
        cache.request_view(2, view, projection, (100, 80), now=40.0)
        assert run_until_idle(cache, now=50.0) == [COARSE, REFINED]
        assert len(builds) == 1
        # Overlay resolution changed: the views again, not the lights.
        assert sorted(run_until_idle(cache, scale=0.25, now=60.0)) == sorted([COARSE, COARSE, REFINED, REFINED])
        assert len(builds) == 1
        # The scene changed (depsgraph handler) or a pass parameter changed: the lights rerun.
        cache.mark_scene_dirty(now=70.0)
        assert run_until_idle(cache, scale=0.25, now=70.0)[0] == "lights"
        assert len(builds) == 2
        assert run_until_idle(cache, settings=VSGLSettings(vsgl_count=8, rsm_size=64), scale=0.25,
                              now=80.0)[0] == "lights"
        assert len(builds) == 3
    finally:
        cache.free()


def test_draw_shows_the_red_bounce_and_follows_mode_and_intensity(demo):
    cache = OverlayCache()
    try:
        view, projection = camera_view(demo)
        cache.request_view(7, view, projection, REGION, now=0.0)
        run_until_idle(cache, now=10.0)
        drawn, indirect = draw_to_array(cache, 7, "indirect")
        assert drawn
        covered = indirect[..., 3] > 0.5
        assert covered.mean() > 0.5  # the camera sees walls and floor almost everywhere
        mean = indirect[covered][:, :3].mean(axis=0)
        assert mean[0] > 1.5 * mean[2] > 0  # the bounce off a red floor is red
        _, brighter = draw_to_array(cache, 7, "indirect", scale=4.0)
        np.testing.assert_allclose(brighter[covered][:, :3], 4.0 * indirect[covered][:, :3], rtol=1e-4, atol=1e-6)
        _, diffuse = draw_to_array(cache, 7, "indirect_diffuse")
        _, specular = draw_to_array(cache, 7, "indirect_specular")
        np.testing.assert_allclose(diffuse[..., :3] + specular[..., :3], indirect[..., :3], rtol=1e-4, atol=1e-6)
        _, direct = draw_to_array(cache, 7, "direct")
        _, combined = draw_to_array(cache, 7, "combined")
        np.testing.assert_allclose(combined[..., :3], direct[..., :3] + indirect[..., :3], rtol=1e-4, atol=1e-5)
        assert direct[covered][:, :3].max() > indirect[covered][:, :3].max()  # the spot's own light
        # MRP-ASG's part alone: the light of demo's floor proxy, a non-empty part of the specular.
        _, reflectors = draw_to_array(cache, 7, "indirect_glossy_reflectors")
        assert reflectors[covered][:, :3].max() > 0.0
        assert np.all(reflectors[..., :3] <= specular[..., :3] + 1e-5)
        assert cache.statistics["proxies"] and cache.statistics["proxies"][0]["lit_by"]
        assert not draw_to_array(cache, 99)[0]  # a viewport with no images yet draws nothing
    finally:
        cache.free()


def test_a_failing_pass_is_reported_not_raised(demo):
    cache = OverlayCache()
    try:
        cache.request_view(1, *camera_view(demo), REGION, now=0.0)

        def broken():
            raise RuntimeError("no scene today")

        assert cache.step(broken, SETTINGS, 0.5, now=0.0) == "lights"
        assert "no scene today" in cache.error
        assert cache.pending(0.5, now=10.0) is None  # stops until the scene changes
        cache.mark_scene_dirty(now=20.0)
        assert cache.error is None
        assert run_until_idle(cache, now=30.0) == ["lights", COARSE, REFINED]
    finally:
        cache.free()


def test_200_redraws_with_parameters_changing(demo):
    """The real handlers and timer, 200 times, every kind of change in turn; no exception, no error."""
    import gpu

    scene = demo
    settings = scene.vsgl
    settings.vsgl_count, settings.rsm_size = 32, 32
    settings.show_overlay = True
    view, projection = camera_view(scene)
    spot = bpy.data.objects["Spot"]
    modes = OVERLAY_DISPLAYS.identifiers
    offscreen = gpu.types.GPUOffScreen(*REGION, format="RGBA32F")
    done = []
    try:
        for frame in range(200):
            change = frame % 8
            if change == 0:
                settings.overlay_mode = modes[(frame // 8) % len(modes)]
            elif change == 1:
                settings.overlay_intensity = 0.5 + (frame % 5)
            elif change == 2:
                settings.k = 1.0 + (frame % 3) * 0.5
            elif change == 3:
                spot.location.x = 0.8 + 0.05 * math.sin(frame)
            elif change == 4:
                settings.overlay_resolution_scale = (0.25, 0.5)[frame % 2]
            elif change == 5:
                settings.kernel = ("MODIFIED", "ORIGINAL", "TWO_VSGL")[frame % 3]
            elif change == 6:
                view = np.array(view) @ np.array([[1, 0, 0, 0.01], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
            bpy.context.view_layer.update()  # fires depsgraph_update_post, as Blender does after a change
            overlay.cache.request_view(1, view, projection, REGION)  # what the draw callback records
            interval = overlay.timer()
            assert interval > 0
            done.append(overlay.cache.statistics.get("level"))
            with offscreen.bind():
                display = OVERLAY_DISPLAYS.identified(settings.overlay_mode).name
                overlay.cache.draw(1, display, *overlay._view_transform(scene))
            assert overlay.cache.error is None, overlay.cache.error
        assert {"lights", COARSE} <= set(done)
        assert overlay.cache.updates >= 100  # the timer did real work, not just nothing 200 times
        settings.show_overlay = False  # switching off frees everything at once
        assert overlay.cache.gpu_resource_count() == 0
    finally:
        offscreen.free()


def test_depsgraph_handler_marks_only_light_changes(demo):
    scene = demo
    scene.vsgl.show_overlay = True
    version = overlay.cache.scene_version
    scene.vsgl.overlay_intensity = 3.0  # display only
    bpy.context.view_layer.update()
    assert overlay.cache.scene_version == version
    bpy.data.objects["Floor"].location.z += 0.01
    bpy.context.view_layer.update()
    assert overlay.cache.scene_version > version
    version = overlay.cache.scene_version
    bpy.data.materials["Glossy red floor"].diffuse_color = (0.1, 0.2, 0.9, 1.0)
    bpy.context.view_layer.update()
    assert overlay.cache.scene_version > version
    scene.vsgl.show_overlay = False


def test_switch_off_load_and_disable_free_everything(demo):
    scene = demo
    scene.vsgl.show_overlay = True
    view, projection = camera_view(scene)
    overlay.cache.request_view(1, view, projection, REGION)
    for _ in range(3):
        overlay.timer()
    assert overlay.cache.gpu_resource_count() > 0
    scene.vsgl.show_overlay = False
    assert overlay.cache.gpu_resource_count() == 0
    # Loading a file (load_pre) frees it.
    scene.vsgl.show_overlay = True
    overlay.cache.request_view(1, view, projection, REGION)
    overlay.timer()
    assert overlay.cache.gpu_resource_count() > 0
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"), load_ui=False)
    assert overlay.cache.gpu_resource_count() == 0
    assert overlay.on_load_pre in bpy.app.handlers.load_pre


def test_enable_disable_enable_with_the_overlay_on(demo):
    for round_ in range(2):
        scene = bpy.context.scene
        scene.vsgl.show_overlay = True
        scene.vsgl.vsgl_count, scene.vsgl.rsm_size = 16, 32
        assert overlay.is_installed()
        overlay.cache.request_view(1, *camera_view(scene), REGION)
        for _ in range(3):
            overlay.timer()
        assert overlay.cache.views and overlay.cache.error is None, f"round {round_}"
        vsgl_addon.unregister()
        assert overlay.cache.gpu_resource_count() == 0
        assert not overlay.is_installed()
        assert overlay.on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post
        assert not bpy.app.timers.is_registered(overlay.timer)
        assert not hasattr(bpy.types.Scene, "vsgl")
        vsgl_addon.register()
        # The property's value is stored in the scene (an IDProperty) and comes back with it.
        assert bpy.context.scene.vsgl.show_overlay


def test_orthographic_views_are_shaded_too(demo):
    """An orthographic viewport (projection [3][3] = 1) gets the light seen along its direction."""
    from dataclasses import replace

    camera = extract_scene(bpy.context.evaluated_depsgraph_get()).camera
    ortho = replace(camera, type="ORTHO", ortho_scale=9.0)
    assert ortho.projection_matrix()[3, 3] == 1.0
    cache = OverlayCache()
    try:
        cache.request_view(3, ortho.view_matrix(), ortho.projection_matrix(), REGION, now=0.0)
        assert run_until_idle(cache, now=10.0) == ["lights", COARSE, REFINED]
        drawn, image = draw_to_array(cache, 3, "indirect")
        covered = image[..., 3] > 0.5
        assert drawn and covered.mean() > 0.3
        mean = image[covered][:, :3].mean(axis=0)
        assert mean[0] > 1.5 * mean[2] > 0
    finally:
        cache.free()


def test_closed_viewports_are_forgotten(demo):
    cache = OverlayCache()
    try:
        view, projection = camera_view(demo)
        cache.request_view(1, view, projection, REGION, now=0.0)
        cache.request_view(2, view, projection, REGION, now=0.0)
        run_until_idle(cache, now=10.0)
        assert set(cache.views) == {1, 2}
        cache.retain_views({2})
        assert set(cache.views) == set(cache.requests) == {2}
        cache.mark_scene_dirty(now=20.0)
        assert run_until_idle(cache, now=30.0) == ["lights", COARSE, REFINED]  # viewport 2 only
    finally:
        cache.free()


def test_refined_image_in_bands_matches_one_band(demo, monkeypatch):
    """A refined image rendered in bands (each step within STEP_BUDGET) equals the one-step image."""
    view, projection = camera_view(demo)
    single = OverlayCache()
    # The bands are sized from measured render times: on this cache every measured duration is one
    # tick of a counter instead, so the bands are the same on a fast, slow or loaded machine. The
    # coarse image (20 x 15) then takes 1/300 tick per pixel, and a budget of 2.2 ticks makes bands
    # of 8, 17 and 37 rows of the 80 x 60 refined image (each band's own rate sizes the next).
    banded = OverlayCache(clock=itertools.count().__next__)
    try:
        single.request_view(1, view, projection, REGION, now=0.0)
        run_until_idle(single, now=10.0)
        assert single.statistics["bands"] == 1
        monkeypatch.setattr(overlay_cache, "STEP_BUDGET", 2.2)
        banded.request_view(1, view, projection, REGION, now=0.0)
        done = run_until_idle(banded, now=10.0, limit=200)
        assert done == ["lights", COARSE, REFINED, REFINED, REFINED]
        assert [entry["rows"] for entry in banded.history if entry["level"] == "refining"] == [(0, 8, 60), (8, 25, 60)]
        assert banded.statistics["bands"] == len(done) - 2
        assert banded.views[1].size == single.views[1].size == (80, 60)
        assert [entry["level"] for entry in banded.history][2:-1] == ["refining"] * (len(done) - 3)
        for display in ("indirect", "direct"):
            _, a = draw_to_array(single, 1, display, size=(80, 60))
            _, b = draw_to_array(banded, 1, display, size=(80, 60))
            close = np.isclose(a, b, rtol=1e-3, atol=1e-4).all(axis=-1)
            assert close.mean() > 0.99, (display, close.mean())
    finally:
        single.free()
        banded.free()


def test_renderer_takes_a_view_and_projection_and_reuses_scene_lights(demo):
    """FrameRenderer.render(..., view_matrix=, projection_matrix=) and render_view(SceneLights, ...)."""
    from vsgl_addon.renderer import FrameRenderer, SceneLights

    description = describe()
    view, projection = description.camera.view_matrix(), description.camera.projection_matrix()
    renderer = FrameRenderer()
    try:
        default = renderer.render(description, SETTINGS, 48, 36)
        explicit = renderer.render(description, SETTINGS, 48, 36, view_matrix=view, projection_matrix=projection)
        np.testing.assert_array_equal(default.indirect, explicit.indirect)
        with pytest.raises(ValueError, match="both"):
            renderer.render(description, SETTINGS, 48, 36, view_matrix=view)
        lights = SceneLights.build(description, SETTINGS)
        try:
            again = renderer.render_view(lights, SETTINGS, 48, 36, view, projection)
            np.testing.assert_allclose(again.indirect, default.indirect, rtol=1e-5, atol=1e-7)
            band = renderer.render_view(lights, SETTINGS, 48, 18, view, band_projection(projection, 0, 18, 36))
            np.testing.assert_allclose(band.indirect, default.indirect[:18], rtol=1e-4, atol=1e-6)
        finally:
            lights.free()
        assert lights.scene_gpu is None and lights.vsgls is None
    finally:
        renderer.free()
