# SPDX-License-Identifier: GPL-3.0-or-later
"""The viewport overlay in the bpy module: the view pipeline on the real passes, drawn over a
viewport, and the Blender glue's lifecycle (vsgl_addon/overlay.py on view_pipeline.ViewportSet; the
scheduling alone: test_view_pipeline.py).

No window here, so the draw callback's parts are driven directly: request_view() (what the
callback records), step() (what the timer does: one unit of work per call), draw() into an
offscreen (what the callback draws), and the add-on's real handlers and timer function.
The scene is demo.blend: a spot-lit red floor next to two white walls.
"""

from __future__ import annotations

import math
from pathlib import Path

import bpy
import numpy as np
import pytest

import vsgl_addon
from vsgl_addon import overlay
from vsgl_addon.passes.gpu_util import RoundTrips
from vsgl_addon.scene import extract_scene
from vsgl_addon.settings import OVERLAY_DISPLAYS, VSGLSettings
from vsgl_addon.view_pipeline import COARSE, LIGHTS, SAMPLE, ViewportSet
from vsgl_addon.views import band_projection

pytestmark = pytest.mark.gpu

REPO = Path(__file__).resolve().parents[1]
REGION = (160, 120)  # a small viewport: the coarse overlay at scale 0.5 is 80 x 60
# The glossy VPL pass's cross-bilateral filter is image-space: a band of rows is filtered within its
# rows, so bands equal the whole image only unfiltered (radius 0; the filter's seam is measured in
# tests/test_vpl_render.py). The light PDF: the overlay's light passes have no single view to weigh
# the texels by (planner.plan_frame), so a frame equals the overlay's only with it.
SETTINGS = VSGLSettings(vsgl_count=64, rsm_size=64, vpl_filter_radius=0, pdf="light")


@pytest.fixture
def demo():
    """demo.blend opened, the add-on registered; unregistered (and checked clean) afterwards."""
    vsgl_addon.unregister()
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"), load_ui=False)
    vsgl_addon.register()
    yield bpy.context.scene
    vsgl_addon.unregister()
    assert overlay.views.gpu_resource_count() == 0
    assert not overlay.is_installed()
    bpy.ops.wm.read_factory_settings(use_empty=True)


def camera_view(scene):
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    return description.camera.view_matrix(), description.camera.projection_matrix()


def describe():
    return extract_scene(bpy.context.evaluated_depsgraph_get())


def one_band_set():
    """A ViewportSet whose every sample is one band (the banding has its own tests)."""
    return ViewportSet(step_budget=1e9)


def run_until_idle(views, settings=SETTINGS, scale=0.5, samples=2, limit=40):
    """Step until nothing is pending; the (work, level) of every step."""
    views.set_step_args(settings, scale, samples)
    done = []
    for _ in range(limit):
        pipeline = views.step(describe)
        if pipeline is None:
            return done
        done.append((pipeline.statistics["work"], pipeline.statistics.get("level")))
    raise AssertionError(f"still busy after {limit} steps: {done}")


def draw_to_array(views, key, display="indirect", scale=1.0, size=REGION):
    """What the draw callback draws for OVERLAY_DISPLAYS option `display`, into a cleared offscreen."""
    import gpu

    view_pass, look = overlay.view_pass_and_look(display, scale, 1.0)
    offscreen = gpu.types.GPUOffScreen(*size, format="RGBA32F")
    try:
        with offscreen.bind():
            framebuffer = gpu.state.active_framebuffer_get()
            framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0))
            gpu.state.viewport_set(0, 0, *size)
            drawn = views.draw(key, view_pass, look)
            buffer = framebuffer.read_color(0, 0, size[0], size[1], 4, 0, "FLOAT")
        buffer.dimensions = size[0] * size[1] * 4
        return drawn, np.array(buffer, np.float32).reshape(size[1], size[0], 4)
    finally:
        offscreen.free()


def test_coarse_first_then_full_resolution_samples(demo):
    views = one_band_set()
    try:
        view, projection = camera_view(demo)
        views.request_view(1, view, projection, REGION)
        done = run_until_idle(views, samples=2)
        # The light passes and the coarse image in one step, then the samples at the viewport's pixels.
        assert done[0] == (LIGHTS, COARSE)
        assert views.pipelines[1].history[0]["size"] == (80, 60)
        assert [level for _, level in done[1:]] == [SAMPLE] * (len(done) - 1)
        assert views.pipelines[1].samples == 2 and views.pipelines[1].target.size == REGION
        assert views.statistics["work"] == SAMPLE and views.error is None
    finally:
        views.free()
    assert views.gpu_resource_count() == 0


def test_view_change_does_not_rerun_the_light_passes_and_viewports_share_them(demo, monkeypatch):
    from vsgl_addon import renderer

    builds = []
    # Every build goes through build_stages (build runs it at once; the samples' are staged).
    original = renderer.SceneLights.build_stages.__func__
    monkeypatch.setattr(renderer.SceneLights, "build_stages",
                        classmethod(lambda cls, *a, **k: builds.append(1) or original(cls, *a, **k)))
    views = one_band_set()
    try:
        view, projection = camera_view(demo)
        views.request_view(1, view, projection, REGION)
        run_until_idle(views, samples=1)
        assert len(builds) == 2  # the coarse image's preview passes, then the sample's
        # Orbit: another view matrix. G-buffer and shading only.
        c, s = math.cos(0.2), math.sin(0.2)
        turned = np.array(view) @ np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
        assert views.request_view(1, turned, projection, REGION)
        assert not views.request_view(1, turned, projection, REGION)  # the same again: no change
        assert run_until_idle(views, samples=1) == [(COARSE, COARSE), (SAMPLE, SAMPLE)]
        assert len(builds) == 2
        # A second viewport shares the light passes: the first one's, with no preview of its own.
        views.request_view(2, view, projection, (100, 80))
        assert run_until_idle(views, samples=1) == [(LIGHTS, COARSE), (SAMPLE, SAMPLE)]
        assert len(builds) == 2 and not views.pipelines[2].history[-2]["preview_lights"]
        # The scene changed (depsgraph handler) or a pass parameter changed: the lights rerun, once
        # (the preview's and the samples' passes, each shared).
        views.mark_scene_dirty()
        assert [work for work, _ in run_until_idle(views, samples=1)].count(LIGHTS) == 2  # one per viewport
        assert len(builds) == 4
        run_until_idle(views, settings=VSGLSettings(vsgl_count=8, rsm_size=64), samples=1)
        assert len(builds) == 6
    finally:
        views.free()


def test_draw_shows_the_red_bounce_and_follows_mode_and_intensity_on_the_gpu(demo):
    views = one_band_set()
    try:
        view, projection = camera_view(demo)
        views.request_view(7, view, projection, REGION)
        run_until_idle(views, samples=1)
        # A view update (the light passes kept) goes from the passes to the accumulation images
        # with no image read back.
        read_backs = RoundTrips.read_backs
        nudged = np.array(view)
        nudged[0, 3] += 1e-3
        views.request_view(7, nudged, projection, REGION)
        run_until_idle(views, samples=1)
        assert RoundTrips.read_backs == read_backs
        uploads = RoundTrips.uploads
        drawn, indirect = draw_to_array(views, 7, "indirect")
        assert drawn and RoundTrips.uploads == uploads
        covered = indirect[..., 3] > 0.5
        assert covered.mean() > 0.5  # the camera sees walls and floor almost everywhere
        mean = indirect[covered][:, :3].mean(axis=0)
        assert mean[0] > 1.5 * mean[2] > 0  # the bounce off a red floor is red
        _, brighter = draw_to_array(views, 7, "indirect", scale=4.0)
        np.testing.assert_allclose(brighter[covered][:, :3], 4.0 * indirect[covered][:, :3], rtol=1e-4, atol=1e-6)
        _, diffuse = draw_to_array(views, 7, "indirect_diffuse")
        _, specular = draw_to_array(views, 7, "indirect_specular")
        np.testing.assert_allclose(diffuse[..., :3] + specular[..., :3], indirect[..., :3], rtol=1e-4, atol=1e-6)
        _, direct = draw_to_array(views, 7, "direct")
        _, combined = draw_to_array(views, 7, "combined")
        np.testing.assert_allclose(combined[..., :3], direct[..., :3] + indirect[..., :3], rtol=1e-4, atol=1e-5)
        assert direct[covered][:, :3].max() > indirect[covered][:, :3].max()  # the spot's own light
        # "Added": the indirect light where there is geometry, premultiplied, adding no alpha.
        _, added = draw_to_array(views, 7, "added")
        np.testing.assert_allclose(added[covered][:, :3], indirect[covered][:, :3], rtol=1e-4, atol=1e-6)
        assert np.all(added[..., 3] == 0.0) and np.all(added[~covered & (indirect[..., 3] == 0)][:, :3] == 0)
        # MRP-ASG's part alone: the light of demo's floor proxy, a non-empty part of the specular.
        _, reflectors = draw_to_array(views, 7, "indirect_glossy_reflectors")
        assert reflectors[covered][:, :3].max() > 0.0
        assert np.all(reflectors[..., :3] <= specular[..., :3] + 1e-5)
        from vsgl_addon.proxies import describe_proxies

        lights = views.pipelines[7].lights  # what the statistics panel lists for the overlay
        assert describe_proxies(lights.proxies, lights.scene)[0]["lit_by"]
        assert not draw_to_array(views, 99)[0]  # a viewport with no images yet draws nothing
    finally:
        views.free()


def test_a_failing_pass_is_reported_not_raised(demo):
    views = one_band_set()
    try:
        views.request_view(1, *camera_view(demo), REGION)
        views.set_step_args(SETTINGS, 0.5, 1)

        def broken():
            raise RuntimeError("no scene today")

        assert views.step(broken) is views.pipelines[1]
        assert "no scene today" in views.error
        assert views.step(describe) is None  # stops until the scene changes
        views.mark_scene_dirty()
        assert views.error is None
        assert run_until_idle(views, samples=1)[0] == (LIGHTS, COARSE)
    finally:
        views.free()


def test_200_redraws_with_parameters_changing(demo):
    """The real handlers and timer, 200 times, every kind of change in turn; no exception, no error."""
    import gpu

    scene = demo
    settings = scene.vsgl
    settings.vsgl_count, settings.rsm_size = 32, 32
    settings.viewport_samples = 2
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
            overlay.views.request_view(1, view, projection, REGION)  # what the draw callback records
            interval = overlay.timer()
            assert interval > 0
            done.append(overlay.views.statistics.get("work"))
            with offscreen.bind():
                display = OVERLAY_DISPLAYS.identified(settings.overlay_mode).name
                overlay.views.draw(1, *overlay.view_pass_and_look(display, *overlay._view_transform(scene)))
            assert overlay.views.error is None, overlay.views.error
        assert {LIGHTS, COARSE, SAMPLE} <= set(done)
        assert overlay.views.pipelines[1].steps >= 100  # the timer did real work, not just nothing 200 times
        settings.show_overlay = False  # switching off frees everything at once
        assert overlay.views.gpu_resource_count() == 0
    finally:
        offscreen.free()


def test_depsgraph_handler_marks_only_light_changes(demo):
    scene = demo
    scene.vsgl.show_overlay = True
    version = overlay.views.scene_version
    scene.vsgl.overlay_intensity = 3.0  # display only
    bpy.context.view_layer.update()
    assert overlay.views.scene_version == version
    bpy.data.objects["Floor"].location.z += 0.01
    bpy.context.view_layer.update()
    assert overlay.views.scene_version > version
    version = overlay.views.scene_version
    bpy.data.materials["Glossy red floor"].diffuse_color = (0.1, 0.2, 0.9, 1.0)
    bpy.context.view_layer.update()
    assert overlay.views.scene_version > version
    scene.vsgl.show_overlay = False


def test_switch_off_load_and_disable_free_everything(demo):
    scene = demo
    scene.vsgl.show_overlay = True
    view, projection = camera_view(scene)
    overlay.views.request_view(1, view, projection, REGION)
    for _ in range(3):
        overlay.timer()
    assert overlay.views.gpu_resource_count() > 0
    scene.vsgl.show_overlay = False
    assert overlay.views.gpu_resource_count() == 0
    # Loading a file (load_pre) frees it.
    scene.vsgl.show_overlay = True
    overlay.views.request_view(1, view, projection, REGION)
    overlay.timer()
    assert overlay.views.gpu_resource_count() > 0
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"), load_ui=False)
    assert overlay.views.gpu_resource_count() == 0
    assert overlay.on_load_pre in bpy.app.handlers.load_pre


def test_enable_disable_enable_with_the_overlay_on(demo):
    for round_ in range(2):
        scene = bpy.context.scene
        scene.vsgl.show_overlay = True
        scene.vsgl.vsgl_count, scene.vsgl.rsm_size = 16, 32
        assert overlay.is_installed()
        overlay.views.request_view(1, *camera_view(scene), REGION)
        for _ in range(3):
            overlay.timer()
        assert overlay.views.pipelines[1].has_image and overlay.views.error is None, f"round {round_}"
        vsgl_addon.unregister()
        assert overlay.views.gpu_resource_count() == 0
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
    views = one_band_set()
    try:
        views.request_view(3, ortho.view_matrix(), ortho.projection_matrix(), REGION)
        run_until_idle(views, samples=1)
        drawn, image = draw_to_array(views, 3, "indirect")
        covered = image[..., 3] > 0.5
        assert drawn and covered.mean() > 0.3
        mean = image[covered][:, :3].mean(axis=0)
        assert mean[0] > 1.5 * mean[2] > 0
    finally:
        views.free()


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


def test_a_light_change_keeps_the_point_sets_and_reads_nothing_back(demo):
    """Two viewports, a light moved: the shared light passes' builds read nothing back (no VSGL
    table, no VPL count, no view total for the planner), upload no shadow-map point
    set (kept by the set's backend across builds of the same triangles), and closing the viewports
    drops the kept sets. VPL shadows on (the default): their clusters are made on the GPU too."""

    settings = SETTINGS
    assert settings.vpl_visibility

    light = next(o for o in bpy.context.scene.objects if o.type == "LIGHT")
    location = light.location.copy()
    views = one_band_set()
    try:
        view, projection = camera_view(demo)
        for key in (1, 2):
            views.request_view(key, view, projection, REGION)
        run_until_idle(views, settings=settings)
        kept = views.gpu_resource_count()
        light.location.x += 0.1
        bpy.context.view_layer.update()
        views.mark_scene_dirty()
        read_backs, read_bytes, upload_bytes = RoundTrips.read_backs, RoundTrips.read_back_bytes, RoundTrips.upload_bytes
        steps = run_until_idle(views, settings=settings)
        assert [work for work, _ in steps].count(LIGHTS) >= 1
        # The demo's one RSM view per set gets all N VSGLs: the planner reads no view total either.
        assert (RoundTrips.read_backs - read_backs, RoundTrips.read_back_bytes - read_bytes) == (0, 0)
        assert RoundTrips.upload_bytes - upload_bytes < 2 * 1024 * 1024  # a seed's point sets: 8 MB
        assert views.gpu_resource_count() == kept
        views.retain(())
        assert views.gpu_resource_count() == 0
    finally:
        views.free()
        light.location = location
        bpy.context.view_layer.update()
