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
    """The viewport overlay's cache on the same scenes: light passes, coarse image, refined bands;
    every image it uploads is finite, nothing fails, and freeing it leaves no GPU resource."""
    from vsgl_addon import passes
    from vsgl_addon.overlay_cache import REFINE_DELAY, GPUBackend, OverlayCache

    generated = scene_generator.build(seed)
    scene = bpy.context.scene
    sb.depsgraph(scene)
    before = scene_generator.rna_dump()
    uploaded = []

    class RecordingBackend(GPUBackend):
        def texture(self, rgba):
            uploaded.append(np.array(rgba))
            return super().texture(rgba)

    with scene_generator.GPUResourceTracker() as tracker:
        description = extract_scene(sb.depsgraph(scene))
        camera = description.camera
        cache = OverlayCache(backend=RecordingBackend())
        try:
            cache.request_view(1, camera.view_matrix(), camera.projection_matrix(), (40, 30), now=0.0)
            done = []
            for now in (0.0, REFINE_DELAY + 1.0):
                for _ in range(64):
                    work = cache.step(lambda: description, _settings(seed), 0.5, now=now)
                    if work is None:
                        break
                    done.append(work)
            assert cache.error is None, f"{cache.error} in {generated}"
            assert done[:2] == ["lights", "coarse"] and "refined" in done, done
        finally:
            cache.free()
        assert cache.gpu_resource_count() == 0
        del cache
        passes.free_all_shaders()
    assert uploaded and all(np.all(np.isfinite(image)) for image in uploaded), str(generated)
    assert tracker.alive() == [], f"GPU resources alive after the overlay of {generated}"
    assert scene_generator.dump_differences(before, scene_generator.rna_dump()) == []
