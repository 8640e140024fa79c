# SPDX-License-Identifier: GPL-3.0-or-later
"""The reliability sweep: seeded random scenes (tests/scene_generator.py) rendered by the passes and
by the VSGL engine. For every scene the render completes, no pass holds NaN or Inf, the user's data
is unchanged, and no GPU resource outlives the render."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

import scene_generator
import scene_builders as sb
from vsgl_addon.scene import extract_scene
from vsgl_addon.settings import VSGLSettings

SEEDS = range(24)


def _settings(seed: int) -> VSGLSettings:
    rng = np.random.default_rng(1000 + seed)
    return VSGLSettings(vsgl_count=int(rng.choice([1, 7, 64, 256])), k=float(rng.choice([0.25, 1.0, 16.0])),
                        kernel=str(rng.choice(["modified", "original", "two-vsgl"])),
                        rsm_size=int(rng.choice([1, 16, 64])), seed=int(rng.integers(0, 1000)),
                        positional_distribution=str(rng.choice(["per-lobe", "shared"])))


@pytest.mark.gpu
@pytest.mark.parametrize("seed", SEEDS)
def test_generated_scene_renders_finite_without_touching_user_data_or_leaking(seed):
    from vsgl_addon import passes

    generated = scene_generator.build(seed)
    scene = bpy.context.scene
    sb.depsgraph(scene)  # Blender's own evaluation writes world matrices back to the objects
    before = scene_generator.rna_dump()
    settings = _settings(seed)
    with scene_generator.GPUResourceTracker() as tracker:
        images = sb.render_frame(scene, settings, 32, 24)
        passes.free_all_shaders()
    sb.assert_finite_frame(images, f"of {generated}")
    assert len(tracker.made) >= 3, "the tracker saw no GPU resource: it is not counting"
    assert tracker.alive() == [], f"GPU resources alive after the render of {generated}"
    differences = scene_generator.dump_differences(before, scene_generator.rna_dump())
    assert differences == [], f"user data changed by the render of {generated}: {differences}"


@pytest.mark.gpu
@pytest.mark.parametrize("seed", SEEDS[::4])
def test_generated_scene_renders_through_the_engine(seed, tmp_path):
    """Blender's render pipeline around the same passes: a frame comes out, every pass finite, and
    what the add-on could not model is said in the statistics' warning lines."""
    import OpenEXR

    generated = scene_generator.build(seed)
    statistics = scene_generator.render_through_engine(bpy.context.scene, tmp_path / "frame.exr")
    assert statistics.get("resolution") == [32, 24], f"no frame from {generated}"
    assert all(isinstance(line, str) and "\n" not in line for line in statistics["warnings"])
    with OpenEXR.File(str(tmp_path / "frame.exr"), separate_channels=True) as exr:
        channels = {name: channel.pixels for part in exr.parts for name, channel in part.channels.items()}
    assert any(".Indirect Diffuse." in name for name in channels), sorted(channels)
    for name, pixels in channels.items():
        assert np.all(np.isfinite(pixels)), f"{name} of {generated}"


@pytest.mark.gpu
@pytest.mark.parametrize("seed", SEEDS[1::3])
def test_generated_scene_through_the_overlay_update_path(seed):
    """The viewport overlay's view pipeline on the same scenes: light passes, coarse image,
    full-resolution samples; every accumulated image is finite, nothing fails, and freeing it
    leaves no GPU resource."""
    from vsgl_addon import passes, view_gpu
    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.view_pipeline import LIGHTS, SAMPLE, ViewportSet

    generated = scene_generator.build(seed)
    scene = bpy.context.scene
    sb.depsgraph(scene)
    before = scene_generator.rna_dump()
    accumulated = []
    with scene_generator.GPUResourceTracker() as tracker:
        description = extract_scene(sb.depsgraph(scene))
        camera = description.camera
        views = ViewportSet()
        try:
            views.request_view(1, camera.view_matrix(), camera.projection_matrix(), (40, 30))
            views.set_step_args(_settings(seed), 0.5, 2)
            done = []
            for _ in range(64):
                pipeline = views.step(lambda: description)
                if pipeline is None:
                    break
                done.append(pipeline.statistics["work"])
            assert views.error is None, f"{views.error} in {generated}"
            assert done[0] == LIGHTS and SAMPLE in done and views.pipelines[1].samples == 2, done
            target = views.pipelines[1].target
            accumulated = [read_texture(target.textures[name], *target.size) for name in view_gpu.IMAGES]
        finally:
            views.free()
        assert views.gpu_resource_count() == 0
        del views
        view_gpu.free_shaders()
        passes.free_all_shaders()
    assert accumulated and all(np.all(np.isfinite(image)) for image in accumulated), str(generated)
    assert tracker.alive() == [], f"GPU resources alive after the overlay of {generated}"
    assert scene_generator.dump_differences(before, scene_generator.rna_dump()) == []
