# SPDX-License-Identifier: GPL-3.0-or-later
"""The Rendered viewport's pipeline on the real passes (bpy module, llvmpipe): the image it draws is
the renderer's, nothing is read back or uploaded per view update, the joint bilateral upsampling
keeps the edges of a coarse image, and every GPU object goes with free(). The window:
test_rendered_real_blender.py."""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np
import pytest

from scene_generator import GPUResourceTracker
from vsgl_addon.passes.gpu_util import RoundTrips
from vsgl_addon.renderer import FrameRenderer
from vsgl_addon.scene import extract_scene
from vsgl_addon.settings import VSGLSettings
from vsgl_addon.view_pipeline import ViewPipeline

pytestmark = pytest.mark.gpu

REPO = Path(__file__).resolve().parents[1]
REGION = (160, 120)
# The light PDF, the viewport's (it has no single view to weigh the texels by, planner.plan_frame):
# a frame equals a viewport sample only with it.
SETTINGS = VSGLSettings(vsgl_count=32, rsm_size=64, pdf="light")


@pytest.fixture(scope="module")
def demo():
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"), load_ui=False)
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    yield description
    bpy.ops.wm.read_factory_settings(use_empty=True)


def _draw(pipeline, view_pass="combined", size=REGION):
    import gpu

    offscreen = gpu.types.GPUOffScreen(*size, format="RGBA32F")
    try:
        with offscreen.bind():
            framebuffer = gpu.state.active_framebuffer_get()
            framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0))
            gpu.state.viewport_set(0, 0, *size)
            assert pipeline.draw(view_pass)
            buffer = framebuffer.read_color(0, 0, size[0], size[1], 4, 0, "FLOAT")
        buffer.dimensions = size[0] * size[1] * 4
        return np.array(buffer, np.float32).reshape(size[1], size[0], 4)
    finally:
        offscreen.free()


def _run(pipeline, describe, scale, samples, limit=400, settings=SETTINGS):
    for _ in range(limit):
        if pipeline.step(describe, settings, scale, samples) is None:
            return
    raise AssertionError("not converged")


@pytest.mark.parametrize("projection_kind", ["camera", "orthographic"])
def test_one_full_resolution_sample_is_the_renderers_image_and_every_pass_is_shown(demo, projection_kind):
    from vsgl_addon.views import orthographic_projection

    view, projection = demo.camera.view_matrix(), demo.camera.projection_matrix()
    if projection_kind == "orthographic":
        projection = orthographic_projection(4.0, 3.0, 0.1, 50.0)
    pipeline = ViewPipeline(step_budget=0.02)  # several bands per sample
    renderer = FrameRenderer()
    try:
        pipeline.request_view(view, projection, REGION)
        _run(pipeline, lambda: demo, 1.0, 1)
        expected = renderer.render(demo, SETTINGS, *REGION, view, projection)
        for view_pass, image in (("combined", expected.combined), ("direct", expected.direct),
                                 ("indirect", expected.indirect), ("indirect_diffuse", expected.indirect_diffuse),
                                 ("indirect_specular", expected.indirect_specular),
                                 ("indirect_glossy_reflectors", expected.indirect_glossy_reflectors)):
            drawn = _draw(pipeline, view_pass)
            assert np.isfinite(drawn).all()
            # The resolve at equal resolution weighs the pixel's own texel 1 up to float32 rounding
            # of its texel coordinate: a pixel next to a bright edge may take ~1e-7 of its neighbour.
            close = np.abs(drawn[..., :3] - image) <= 1e-4 * np.abs(image) + 1e-6
            assert close.mean() > 0.9999, (view_pass, close.mean())
            assert np.abs(drawn[..., :3] - image).max() <= 1e-3 * max(image.max(), 1e-6), view_pass
        assert (drawn[..., 3] == 1.0).all()
        assert expected.indirect_glossy_reflectors.max() > 0.0  # demo's floor is a lit proxy: not a black pass
    finally:
        pipeline.free()
        renderer.free()


def test_view_updates_make_no_cpu_round_trip(demo):
    """After the light passes, a view change's coarse image and its samples stay on the GPU: no
    texture read back, no image uploaded (only the direct-light and MRP-ASG passes' per-light tables, a
    few texels per render, and one texel read per step to wait for the GPU, two for a coarse image)."""
    view, projection = demo.camera.view_matrix(), demo.camera.projection_matrix()
    pipeline = ViewPipeline()
    try:
        pipeline.request_view(view, projection, REGION)
        # Light passes + coarse image, then the sample's own light passes (the preview's are smaller
        # shadow maps of other point sets): what a view change keeps.
        _run(pipeline, lambda: demo, 0.25, 1)
        for shift in (0.1, 0.2, 0.3):
            moved = view.copy()
            moved[0, 3] += shift
            pipeline.request_view(moved, projection, REGION)
            read_backs, upload_bytes = RoundTrips.read_backs, RoundTrips.upload_bytes
            steps = pipeline.steps
            _run(pipeline, lambda: demo, 0.25, 1)  # coarse, then one sample in bands (same seed)
            assert pipeline.guide_builds == 1 + round(shift / 0.1)  # a new view: a new guide
            # Every render of this update (a loaded machine makes the bands many and small).
            renders = sum(1 for entry in list(pipeline.history)[-(pipeline.steps - steps):] if entry.get("level"))
            assert RoundTrips.read_backs == read_backs
            image_bytes = REGION[0] * REGION[1] * 16
            # Per render: the direct light's and MRP-ASG's per-light tables (proxies, constants),
            # about a kilobyte, never an image.
            uploaded = RoundTrips.upload_bytes - upload_bytes
            assert uploaded < max(renders, 1) * image_bytes / 50, (uploaded, renders)
    finally:
        pipeline.free()


@pytest.mark.parametrize("vpl_shadows", [False, True])
def test_a_light_change_reads_nothing_back_and_uploads_no_point_set(demo, vpl_shadows):
    """A light moved: the light builds (the coarse image's preview, then one per sample's seed) read
    nothing back: no VSGL table (the
    shadow maps' origins are made on the GPU), no VPL count (read when the statistics are shown),
    and no view total (the demo's one RSM view per set gets all N VSGLs whatever its power, so the
    planner needs none; its power is read when the statistics or the report ask). The shadow maps'
    point sets stay on the GPU across builds of the same triangles (8 MB a seed). With VPL shadows
    (the default) too: the VPLs' clusters and their maps' origins are made on the GPU
    (vpl_culling.extract_vpls with shadows)."""
    from dataclasses import replace

    settings = replace(SETTINGS, vpl_visibility=vpl_shadows)

    light = next(o for o in bpy.context.scene.objects if o.type == "LIGHT")
    location = light.location.copy()

    def describe():
        return extract_scene(bpy.context.evaluated_depsgraph_get())

    pipeline = ViewPipeline()
    try:
        pipeline.request_view(demo.camera.view_matrix(), demo.camera.projection_matrix(), REGION)
        _run(pipeline, describe, 0.25, 2, settings=settings)
        light.location.x += 0.1
        bpy.context.view_layer.update()
        pipeline.mark_scene_dirty()
        read_backs, read_bytes, upload_bytes = RoundTrips.read_backs, RoundTrips.read_back_bytes, RoundTrips.upload_bytes
        steps = pipeline.steps
        _run(pipeline, describe, 0.25, 2, settings=settings)
        entries = list(pipeline.history)[-(pipeline.steps - steps):]
        builds = sum(1 for entry in entries if entry.get("work") == "lights" or entry.get("lights_complete"))
        assert builds == 3  # the coarse image's preview passes, then one per sample's seed (in stages)
        assert pipeline.guide_builds == 1  # the triangles and the view stayed: the guide G-buffer too
        # The demo has a sharp reflector: the VPLs, and with VPL shadows their clusters' maps, are made.
        assert pipeline.lights.vpls is not None
        assert (pipeline.lights.vpls.isms is not None) == vpl_shadows
        assert (RoundTrips.read_backs - read_backs, RoundTrips.read_back_bytes - read_bytes) == (0, 0)
        # Asked for, the plan's measured bounce powers are read then, one VSGL table per set, and
        # equal the power of the one-kernel table the planner read before.
        plan = pipeline.lights.plan
        light_plan = next(entry for entry in plan.lights if entry.gets_rsm)
        assert light_plan.rsm_views == 1 and len(plan.receiver_sets) == 3
        report = plan.to_dict()
        assert RoundTrips.read_backs - read_backs == len(plan.receiver_sets)
        powers = report["lights"][light_plan.index]["rsm_power"]
        assert set(powers) == set(plan.receiver_sets) and all(power > 0.0 for power in powers.values())
        assert "% of the bounce" in plan.light_line(light_plan)
        assert RoundTrips.read_backs - read_backs == len(plan.receiver_sets)  # read once
        from vsgl_addon.passes.vsgl_generation import VSGLGeneration
        from vsgl_addon.planner import view_power

        for lobe, table_set in zip(plan.receiver_sets, (pipeline.lights.vsgls, pipeline.lights.glossy_vsgls,
                                                        pipeline.lights.whole_vsgls)):
            (view,) = table_set.views_by_light[light_plan.index]
            generation = VSGLGeneration()  # what the planner read before: a one-kernel table
            try:
                generation.build_mip_atlas(view.rsm_textures(), None)
                generation.generate(1, settings.k, settings.kernel)
                expected = view_power(generation.read_table()["rsm_total_power"])
            finally:
                generation.free()
            assert powers[lobe] == pytest.approx(expected, rel=1e-6)
        # Without the kept point sets: 8 MB per build.
        assert RoundTrips.upload_bytes - upload_bytes < 2 * 1024 * 1024
        # Asked for, the VPL count of the GPU extraction is read then (4 bytes), with or without VPL
        # shadows.
        vpls = pipeline.lights.vpls
        if vpls is not None:
            from vsgl_addon.renderer import ViewCounts

            read_bytes = RoundTrips.read_back_bytes
            counts = ViewCounts({}, {"vpls": lambda: vpls.count})
            assert counts["vpls"] == counts["vpls"] >= 0
            assert RoundTrips.read_back_bytes - read_bytes == 4
    finally:
        pipeline.free()
        light.location = location
        bpy.context.view_layer.update()


def test_coarse_image_keeps_edges_sharper_than_bilinear(demo, monkeypatch):
    """Scale 0.25 upsampled by the joint bilateral filter against the full-resolution render, at the
    pixels next to a depth or coverage edge: at most 0.65x the error of bilinear upsampling of the same
    render (measured 0.60x here, 0.59x before glossy receivers saw flat clusters' Lambertian emission;
    the rest is the coarse render's own lack of detail, mostly the gold sphere's reflection). The glossy
    receivers' set keeps N (planner.GLOSSY_SET_FACTOR 1): with 2 N the gold sphere's finer reflection
    is more detail the coarse render lacks."""
    from vsgl_addon import planner
    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.renderer import SceneLights

    monkeypatch.setattr(planner, "GLOSSY_SET_FACTOR", 1)

    view, projection = demo.camera.view_matrix(), demo.camera.projection_matrix()
    size = (192, 144)
    pipeline = ViewPipeline(preview_lights=False)  # the coarse image of the light passes compared to
    renderer = FrameRenderer()
    lights = SceneLights.build(demo, SETTINGS)
    try:
        pipeline.request_view(view, projection, size)
        pipeline.step(lambda: demo, SETTINGS, 0.25, 0)
        upsampled = _draw(pipeline, "combined", size)[..., :3]
        full = renderer.render_view(lights, SETTINGS, *size, view, projection)
        low = renderer.render_view(lights, SETTINGS, size[0] // 4, size[1] // 4, view, projection)
        # Bilinear upsampling of the same coarse image (texel centres, clamped at the border).
        ys = np.clip((np.arange(size[1]) + 0.5) / 4 - 0.5, 0, size[1] // 4 - 1)
        xs = np.clip((np.arange(size[0]) + 0.5) / 4 - 0.5, 0, size[0] // 4 - 1)
        rows = np.array([np.interp(xs, np.arange(size[0] // 4), r) for r in low.combined.transpose(2, 0, 1).reshape(-1, size[0] // 4)])
        rows = rows.reshape(3, size[1] // 4, size[0]).transpose(1, 2, 0)
        bilinear = np.stack([np.array([np.interp(ys, np.arange(size[1] // 4), rows[:, x, c]) for x in range(size[0])]).T
                             for c in range(3)], -1)
        guide = renderer.guide(lights, *size, view, projection)
        position = read_texture(guide.textures["position"], *size)
        guide.free()
        depth = np.linalg.norm(position[..., :3] - demo.camera.matrix_world[:3, 3], axis=-1)
        edge = np.zeros(size[::-1], bool)
        jump = (np.abs(np.diff(depth, axis=0)) > 0.2) | (np.abs(np.diff(position[..., 3], axis=0)) > 0)
        edge[:-1] |= jump
        edge[1:] |= jump
        jump = (np.abs(np.diff(depth, axis=1)) > 0.2) | (np.abs(np.diff(position[..., 3], axis=1)) > 0)
        edge[:, :-1] |= jump
        edge[:, 1:] |= jump
        assert edge.mean() > 0.01
        error_jbu = np.abs(upsampled - full.combined)[edge].mean()
        error_bilinear = np.abs(bilinear - full.combined)[edge].mean()
        print(f"mean error at edges: joint bilateral {error_jbu:.4g}, bilinear {error_bilinear:.4g}")
        assert error_jbu < 0.65 * error_bilinear
    finally:
        lights.free()
        pipeline.free()
        renderer.free()


def test_free_leaves_no_gpu_object(demo):
    view, projection = demo.camera.view_matrix(), demo.camera.projection_matrix()
    pipeline = ViewPipeline()
    pipeline.request_view(view, projection, (64, 48))
    pipeline.step(lambda: demo, SETTINGS, 0.5, 2)  # compile the shaders outside the tracker
    pipeline.free()
    with GPUResourceTracker() as tracker:
        pipeline.request_view(view, projection, (64, 48))
        _run(pipeline, lambda: demo, 0.5, 2)
        made = len(tracker.made)
        pipeline.free()
    assert made > 0 and pipeline.gpu_resource_count() == 0
    assert tracker.alive() == []


def test_coarse_preview_thins_the_vpls_and_the_samples_shade_them_all(demo, monkeypatch):
    """The coarse image's glossy VPL pass shades one VPL of each block of S = RSM texels / 1024
    (16 with demo.blend's 128 x 128 RSMs, here with 32 VSGLs), weighted S: at the window's coarse size its combined
    image is within 0.5 % relative RMSE of shading them all (measured 0.30 %; 0.78 % at 328 x 197),
    unbiased on average. The samples shade every VPL: the converged image is the one without the
    preview, bit for bit."""
    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.reference import vpl_culling as reference
    from vsgl_addon.renderer import SceneLights

    settings = VSGLSettings(vsgl_count=32, rsm_size=128)  # demo.blend's RSMs
    assert reference.preview_stride(settings.rsm_size ** 2) == 16
    view, projection = demo.camera.view_matrix(), demo.camera.projection_matrix()
    renderer = FrameRenderer()
    lights = SceneLights.build(demo, settings)
    size = (82, 49)
    try:
        assert lights.vpls is not None

        def combined(stride):
            textures = renderer.render_view_textures(lights, settings, *size, view, projection, vpl_stride=stride)
            images = {name: read_texture(textures.textures[name], *size)[..., :3].astype(np.float64)
                      for name in ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular",
                                   "indirect_caustics")}
            textures.free()
            return sum(images[name] for name in list(images)[:4]), images["indirect_caustics"]

        full, full_caustics = combined(1)
        thinned, caustics = combined(16)
        error = np.sqrt(((thinned - full) ** 2).mean() / (full ** 2).mean())
        print(f"preview relative RMSE {error:.4f}")
        assert np.isfinite(thinned).all() and 0.0 < error <= 0.005
        assert abs(caustics.mean() / full_caustics.mean() - 1.0) < 0.05
    finally:
        lights.free()
        renderer.free()

    def converged():
        # One band per sample whatever the machine's load: the bands' rows follow the coarse step's
        # measured time per pixel, and a split band gives the VPL filter a different image.
        pipeline = ViewPipeline(step_budget=1e9)
        try:
            pipeline.view_pass = "indirect_caustics"  # a viewport showing the VPLs' pass: the preview keeps them
            pipeline.request_view(view, projection, REGION)
            assert pipeline.step(lambda: demo, SETTINGS, 0.25, 2) == "lights"
            assert pipeline.lights_preview and pipeline.lights.vpls is not None
            _run(pipeline, lambda: demo, 0.25, 2)
            return _draw(pipeline)
        finally:
            pipeline.free()

    import vsgl_addon.reference.vpl_culling as module

    with_preview = converged()
    monkeypatch.setattr(module, "preview_stride", lambda texels: 1)
    assert np.array_equal(with_preview, converged())


def test_preview_light_passes_light_only_the_coarse_image_and_the_converged_image_is_unchanged(demo):
    """The coarse image after a change is lit by preview_light_settings' passes (here 16 VSGLs of 32²
    RSMs with 32² shadow maps, in one set that keeps the VPLs' and MRP-ASG's light); the samples
    rebuild them at the settings' own, so two samples converge to the very image of a pipeline
    without the preview, bit for bit, every pass."""
    from vsgl_addon.view_pipeline import preview_light_settings

    view, projection = demo.camera.view_matrix(), demo.camera.projection_matrix()
    preview = preview_light_settings(SETTINGS)
    assert (preview.vsgl_count, preview.rsm_size) == (16, 32)
    images = {}
    for preview_lights in (True, False):
        pipeline = ViewPipeline(step_budget=1e9, preview_lights=preview_lights)
        try:
            pipeline.request_view(view, projection, REGION)
            assert pipeline.step(lambda: demo, SETTINGS, 0.25, 2) == "lights"
            assert pipeline.history[-1]["preview_lights"] == preview_lights
            # The preview leaves the VPLs' and MRP-ASG's light in the one VSGL set of every reflector.
            lights = pipeline.lights
            assert (lights.vpls is None and not lights.proxies and lights.glossy_vsgls is None) == preview_lights
            coarse = _draw(pipeline)
            assert np.isfinite(coarse).all() and coarse[..., :3].max() > 0.0
            _run(pipeline, lambda: demo, 0.25, 2)
            assert pipeline.samples == 2 and not pipeline.lights_preview
            images[preview_lights] = {view_pass: _draw(pipeline, view_pass)
                                      for view_pass in ("combined", "indirect_diffuse", "indirect_specular")}
            images[preview_lights]["coarse"] = coarse
        finally:
            pipeline.free()
    for view_pass in ("combined", "indirect_diffuse", "indirect_specular"):
        np.testing.assert_array_equal(images[True][view_pass], images[False][view_pass], err_msg=view_pass)
    # The preview's coarse image is another one (fewer, wider VSGLs), not the same passes twice.
    assert not np.array_equal(images[True]["coarse"], images[False]["coarse"])


def test_a_staged_light_build_with_other_gpu_work_between_its_stages_lights_the_frame_of_one_build(demo):
    """The viewport spreads a light build over steps (SceneLights.build_stages), and Blender draws,
    other viewports render, between them: with a view rendered and drawn after every stage, the
    light passes give the frame of SceneLights.build exactly (the demo: three VSGL sets with shadow
    maps, the VPLs)."""
    from vsgl_addon.passes.scene_gpu import PointTextureCache
    from vsgl_addon.renderer import SceneLights

    settings = VSGLSettings(vsgl_count=32, rsm_size=64, pdf="light", seed=3)
    camera = demo.camera
    view, projection = camera.view_matrix(), camera.projection_matrix()
    renderer = FrameRenderer()
    cache = PointTextureCache()
    whole = SceneLights.build(demo, settings, point_cache=cache)
    other = SceneLights.build(demo, settings.overridden(seed=9, rsm_size=32), point_cache=cache)
    staged = None
    try:
        stages = SceneLights.build_stages(demo, settings, point_cache=cache)
        count = 0
        while staged is None:
            try:
                next(stages)
                count += 1
            except StopIteration as done:
                staged = done.value
            # Other work in between: a view of other light passes, as another step would render.
            renderer.render_view(other, settings.overridden(seed=9, rsm_size=32), 40, 30, view, projection)
        assert count >= 5  # the sets' RSMs and tables, their shadow maps' parts, the VPLs
        a = renderer.render_view(whole, settings, 80, 60, view, projection)
        b = renderer.render_view(staged, settings, 80, 60, view, projection)
        for name in ("direct_diffuse", "indirect_diffuse", "indirect_specular", "indirect_caustics",
                     "indirect_glossy_reflectors"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        assert float(a.indirect_diffuse.max()) > 0.0
    finally:
        for lights in (whole, other, staged):
            if lights is not None:
                lights.free()
        cache.free()
        renderer.free()


def test_coarse_images_after_light_edits_reuse_the_guides_weights_and_equal_the_one_pass_resolve(demo):
    """Light edits through a kept guide: a coarse image whose size differs from the last one's is
    resolved in one pass, the next of that size computes its weights and later ones reuse them
    (view_gpu.ViewGuide); each coarse
    image is bit for bit the one-pass resolve's (a backend whose guide is the bare G-buffer), so the
    render's G-buffer of the same view, triangles and size is the same one the weights came from."""
    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.view_gpu import IMAGES, GPUViewBackend, ViewGuide

    class OnePass(GPUViewBackend):
        def guide(self, *arguments):
            return super().guide(*arguments).gbuffer

    light = next(o for o in bpy.context.scene.objects if o.type == "LIGHT")
    location = light.location.copy()

    def describe():
        return extract_scene(bpy.context.evaluated_depsgraph_get())

    pipelines = [ViewPipeline(), ViewPipeline(OnePass())]
    try:
        for pipeline in pipelines:
            pipeline.request_view(demo.camera.view_matrix(), demo.camera.projection_matrix(), REGION)
        for move, factor in enumerate((0.5, 0.5, 0.5, 0.25, 0.25, 0.5)):
            light.location.x += 0.1 * (1 if move % 2 == 0 else -1)
            bpy.context.view_layer.update()
            images = []
            for pipeline in pipelines:
                pipeline.mark_scene_dirty()
                pipeline.coarse_factor = factor  # not the measured times: both render the same size
                pipeline.step(describe, SETTINGS, 0.5, 2)
                assert pipeline.history[-1]["level"] == "coarse"
                images.append({name: read_texture(pipeline.target.textures[name], *REGION) for name in IMAGES})
            for name in IMAGES:
                np.testing.assert_array_equal(images[0][name], images[1][name], err_msg=f"move {move}: {name}")
            assert images[0]["indirect_diffuse"][..., :3].max() > 0
        guide = pipelines[0].guide
        assert isinstance(guide, ViewGuide) and pipelines[0].guide_builds == 1
        # Moves 1 and 4 compute the weights of their size (0.5, then 0.25) as the second of it in a
        # row, 2 reuses move 1's; 3 and 5 (a size unlike the last one's) are resolved in one pass.
        assert guide.weight_builds == 2 and guide.renders == 6
        # A view change: the new guide's weights are the old one's textures (view_gpu.WeightsPool),
        # and its first coarse image is resolved in one pass.
        weights = guide.weights
        view = demo.camera.view_matrix().copy()
        view[0, 3] += 0.05
        pipelines[0].request_view(view, demo.camera.projection_matrix(), REGION)
        pipelines[0].step(describe, SETTINGS, 0.5, 2)
        assert pipelines[0].guide is not guide and pipelines[0].guide.weights is weights
        assert pipelines[0].guide.weight_builds == 0 and len(pipelines[0].backend.weights_pool) == 0
    finally:
        for pipeline in pipelines:
            pipeline.free()
        light.location = location
        bpy.context.view_layer.update()
