# SPDX-License-Identifier: GPL-3.0-or-later
"""The overlay's scheduling without Blender (vsgl_addon/overlay_cache.py): a fake backend and clock.

The fake renderer advances the fake clock by SECONDS_PER_PIXEL per pixel it renders, so the
cache measures render times as it would on a GPU and sizes the refined image's bands from them,
deterministically. Every image it returns is filled with the number of its render call, which
shows where each band landed. The same cache on the real passes: test_overlay.py.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from vsgl_addon import overlay_cache
from vsgl_addon.overlay_cache import (COARSE, LIGHTS, REFINE_DELAY, REFINED, STEP_BUDGET, OverlayCache,
                                      overlay_size)
from vsgl_addon.views import band_projection
from vsgl_addon.settings import VSGLSettings

REPO = Path(__file__).resolve().parents[1]
REGION = (160, 120)  # at scale 0.5: coarse 20 x 15, refined 80 x 60
SCALE = 0.5
SETTINGS = VSGLSettings(vsgl_count=64, rsm_size=64)
SECONDS_PER_PIXEL = 1e-4
VIEW = np.eye(4)
PROJECTION = np.array([[1.2, 0, 0, 0], [0, 1.6, 0, 0], [0, 0, -1.002, -0.2], [0, 0, -1, 0]])


class FakeClock:
    def __init__(self, t: float = 0.0):
        self.t = t

    def __call__(self) -> float:
        return self.t


class FakeGPUObject:
    """Counts itself in `live` until freed."""

    def __init__(self, live: set):
        self.live = live
        live.add(self)

    def free(self) -> None:
        self.live.discard(self)


class FakeRenderer(FakeGPUObject):
    def __init__(self, backend):
        super().__init__(backend.live)
        self.backend = backend

    def render_view(self, lights, settings, width, height, view_matrix, projection_matrix):
        assert lights in self.live, "rendered with freed light passes"
        calls = self.backend.renders
        calls.append(SimpleNamespace(settings=settings, size=(width, height), view_matrix=view_matrix,
                                     projection_matrix=projection_matrix))
        seconds = SECONDS_PER_PIXEL * width * height
        self.backend.clock.t += seconds
        value = np.float32(len(calls))
        rgb = np.full((height, width, 3), value, np.float32)
        return SimpleNamespace(indirect_diffuse=rgb, indirect_specular=2 * rgb, direct=3 * rgb,
                               indirect_glossy_reflectors=0.5 * rgb, coverage=np.ones((height, width), np.float32),
                               proxies=[{"object": "Floor", "lit_by": ["Spot"]}],
                               timings={**lights.timings, "gbuffer": seconds / 2, "vsgl_shading": seconds / 2},
                               counts={"vsgls": settings.vsgl_count})


class FakeBackend:
    """overlay_cache.GPUBackend's interface, with Python objects instead of GPU ones."""

    def __init__(self, clock):
        self.clock = clock
        self.live: set = set()  # every fake GPU object not yet freed
        self.builds: list = []  # (description, settings) of every light-pass build
        self.renders: list = []
        self.programs = 0

    def frame_renderer(self):
        return FakeRenderer(self)

    def scene_lights(self, description, settings):
        self.builds.append((description, settings))
        lights = FakeGPUObject(self.live)
        lights.timings = {"rsm_and_vsgl_generation": 0.01}
        return lights

    def texture(self, rgba):
        return np.array(rgba)  # a texture's pixels, to check what was uploaded

    def program(self):
        self.programs += 1
        return FakeProgram()


class FakeProgram:
    """Records what it was asked to draw (overlay_cache.OverlayProgram.draw's arguments)."""

    def __init__(self):
        self.draws = []

    def draw(self, textures, display, scale, gamma, encode_srgb):
        self.draws.append((textures, display, scale, gamma, encode_srgb))


def describe():
    return SimpleNamespace(warnings=["a material approximated"])


def make_cache(t: float = 0.0):
    clock = FakeClock(t)
    backend = FakeBackend(clock)
    return OverlayCache(backend=backend, clock=clock), backend, clock


def run(cache, settings=SETTINGS, scale=SCALE, limit=50):
    """Step until nothing is pending at the clock's time; the list of work done."""
    done = []
    for _ in range(limit):
        work = cache.step(describe, settings, scale)
        if work is None:
            return done
        done.append(work)
    raise AssertionError(f"still busy after {limit} steps: {done}")


def expected_bands(width: int, height: int) -> list[tuple[int, int]]:
    """The bands the cache should cut: rows fitting STEP_BUDGET at SECONDS_PER_PIXEL."""
    rows = int(STEP_BUDGET / (SECONDS_PER_PIXEL * width))
    return [(first, min(height, first + rows)) for first in range(0, height, rows)]


def test_dirty_scene_light_passes_then_coarse_then_refined_bands_after_the_delay():
    cache, backend, clock = make_cache(t=5.0)
    cache.request_view(1, VIEW, PROJECTION, REGION)
    assert cache.pending(SCALE) == LIGHTS
    assert run(cache) == [LIGHTS, COARSE]  # then nothing: the last change was just now
    assert len(backend.builds) == 1 and backend.builds[0][1] == SETTINGS
    assert cache.warnings == ("a material approximated",)
    assert cache.views[1].level == COARSE and cache.views[1].size == overlay_size(REGION, SCALE, COARSE) == (20, 15)
    assert backend.renders[0].size == (20, 15)
    np.testing.assert_array_equal(backend.renders[0].projection_matrix, PROJECTION)
    clock.t = 5.0 + REFINE_DELAY - 0.01
    assert run(cache) == []
    clock.t = 5.0 + REFINE_DELAY + 1e-6  # (5.3 - 5.0 < 0.3 in floating point)
    bands = expected_bands(80, 60)
    assert len(bands) == 9 and bands[-1] == (56, 60)  # 7 rows of 80 pixels fit in 0.06 s at 1e-4 s each
    assert run(cache) == [REFINED] * len(bands)
    view = cache.views[1]
    assert view.level == REFINED and view.size == (80, 60) and cache.is_current(1)
    for call, (first, end) in zip(backend.renders[1:], bands):
        assert call.size == (80, end - first)
        np.testing.assert_array_equal(call.projection_matrix, band_projection(PROJECTION, first, end, 60))
    # Each band's rows hold that band's render (call numbers 2, 3, ...), alpha the coverage.
    for number, (first, end) in enumerate(bands, start=2):
        np.testing.assert_array_equal(view.textures["indirect_diffuse"][first:end, :, :3], number)
        np.testing.assert_array_equal(view.textures["indirect_specular"][first:end, :, :3], 2 * number)
        np.testing.assert_array_equal(view.textures["direct_light"][first:end, :, :3], 3 * number)
        np.testing.assert_array_equal(view.textures["glossy_reflectors"][first:end, :, :3], 0.5 * number)
    np.testing.assert_array_equal(view.textures["direct_light"][..., 3], 1.0)
    statistics = cache.statistics
    assert statistics["proxies"] == [{"object": "Floor", "lit_by": ["Spot"]}]  # the statistics panel's list
    assert statistics["level"] == REFINED and statistics["bands"] == len(bands)
    assert statistics["max_step_seconds"] == pytest.approx(SECONDS_PER_PIXEL * 80 * 7)
    assert statistics["seconds"] == pytest.approx(SECONDS_PER_PIXEL * 80 * 60)
    assert set(statistics["timings"]) == {"gbuffer", "vsgl_shading"}  # the light passes' are apart
    assert set(statistics["light_timings"]) == {"scene_extraction", "rsm_and_vsgl_generation"}
    assert [entry["level"] for entry in cache.history] == [LIGHTS, COARSE] + ["refining"] * 8 + [REFINED]
    assert [entry["index"] for entry in cache.history] == list(range(cache.updates)) and cache.updates == 11


def test_a_view_change_reruns_only_the_view_passes():
    cache, backend, clock = make_cache()
    cache.request_view(1, VIEW, PROJECTION, REGION)
    run(cache)
    clock.t = 1.0
    run(cache)
    lights = cache.lights
    turned = VIEW @ np.array([[1, 0, 0, 0.5], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    assert cache.request_view(1, turned, PROJECTION, REGION)
    assert not cache.request_view(1, turned, PROJECTION, REGION)  # the same again: no change
    assert not cache.is_current(1)
    assert run(cache) == [COARSE]
    clock.t = 2.0
    assert set(run(cache)) == {REFINED}
    assert len(backend.builds) == 1 and cache.lights is lights
    np.testing.assert_array_equal(backend.renders[-1].view_matrix, turned)
    # A second viewport shares the light passes; another resolution scale redoes the views only.
    cache.request_view(2, VIEW, PROJECTION, (100, 80))
    clock.t = 3.0
    assert run(cache)[0] == COARSE and len(backend.builds) == 1
    clock.t = 4.0
    assert set(run(cache, scale=0.25)) == {COARSE, REFINED} and len(backend.builds) == 1
    assert {view.size for view in cache.views.values()} == {(40, 30), (25, 20)}
    # Another pass setting or a scene change: the light passes again (the old ones freed).
    other = VSGLSettings(vsgl_count=8, rsm_size=64)
    assert run(cache, settings=other, scale=0.25)[:1] == [LIGHTS]
    assert backend.builds[-1][1] == other and lights not in backend.live
    cache.mark_scene_dirty()
    assert not cache.is_current(1)
    assert run(cache, settings=other, scale=0.25) == [LIGHTS, COARSE, COARSE]
    assert len(backend.builds) == 3


def test_a_view_change_while_refining_starts_over_coarse():
    cache, backend, clock = make_cache()
    cache.request_view(1, VIEW, PROJECTION, REGION)
    run(cache)
    clock.t = 1.0
    assert cache.step(describe, SETTINGS, SCALE) == REFINED
    assert cache.statistics["level"] == "refining" and cache.statistics["rows"] == (0, 7, 60)
    cache.request_view(1, 2 * VIEW, PROJECTION, REGION)  # moved (at the clock's time: just now)
    assert run(cache) == [COARSE]
    clock.t = 2.0
    assert run(cache) == [REFINED] * 9  # a full refinement of the new view, not the old one's rest
    np.testing.assert_array_equal(cache.views[1].request.view_matrix, 2 * VIEW)


def test_retain_and_forget_views():
    cache, backend, clock = make_cache()
    for key in (1, 2, 3):
        cache.request_view(key, VIEW, PROJECTION, REGION)
    run(cache)
    assert set(cache.views) == {1, 2, 3}
    cache.retain_views({2, 3, 99})  # viewport 1 closed; 99 is open but never drew
    assert set(cache.views) == set(cache.requests) == {2, 3}
    cache.forget_view(3)
    cache.forget_view(42)  # unknown: harmless
    assert set(cache.views) == set(cache.requests) == {2}
    renders = len(backend.renders)
    clock.t = 1.0
    assert run(cache) == [REFINED] * 9  # viewport 2 only
    assert len(backend.renders) == renders + 9
    cache.retain_views(set())
    assert cache.pending(SCALE) is None and not cache.views


def test_free_releases_every_gpu_resource_it_counts():
    cache, backend, clock = make_cache()
    assert cache.gpu_resource_count() == 0
    cache.request_view(1, VIEW, PROJECTION, REGION)
    cache.request_view(2, VIEW, PROJECTION, REGION)
    run(cache)
    # 4 textures per view, the light passes, the renderer, the draw shader and its triangle.
    assert cache.gpu_resource_count() == 2 * 4 + 1 + 1 + 2
    assert len(backend.live) == 2  # lights and renderer
    cache.free()
    assert cache.gpu_resource_count() == 0 and not backend.live
    assert not cache.requests and not cache.statistics and not cache.history and cache.warnings == ()
    assert cache.pending(SCALE) is None  # nothing to render until a viewport draws again
    cache.request_view(1, VIEW, PROJECTION, REGION)
    assert run(cache) == [LIGHTS, COARSE] and backend.programs == 2  # from scratch


def test_a_failing_pass_stops_updates_until_the_scene_changes():
    cache, backend, clock = make_cache()
    cache.request_view(1, VIEW, PROJECTION, REGION)

    def broken():
        raise RuntimeError("no scene today")

    assert cache.step(broken, SETTINGS, SCALE) == LIGHTS
    assert cache.error == "RuntimeError: no scene today"
    clock.t = 10.0
    assert cache.pending(SCALE) is None and cache.step(describe, SETTINGS, SCALE) is None
    cache.mark_scene_dirty()
    assert cache.error is None
    clock.t = 20.0
    assert run(cache) == [LIGHTS, COARSE] + [REFINED] * 9


def test_draw_hands_the_display_choice_to_the_program():
    cache, backend, clock = make_cache()
    assert not cache.draw(1, "indirect", 1.0)  # nothing rendered yet
    cache.request_view(1, VIEW, PROJECTION, REGION)
    run(cache)
    assert cache.draw(1, "added", 2.0, gamma=1.5)
    textures, display, scale, gamma, encode_srgb = cache._program.draws[-1]
    assert set(textures) == {"indirect_diffuse", "indirect_specular", "direct_light", "glossy_reflectors"}
    assert (display, scale, gamma, encode_srgb) == ("added", 2.0, 1.5, False)
    assert not cache.draw(2, "added", 1.0)  # a viewport without images


def test_the_scheduler_runs_without_bpy_or_gpu(tmp_path):
    """overlay_cache imports and schedules in plain Python with Blender's modules unavailable."""
    blockers = tmp_path / "blockers"
    blockers.mkdir()
    for name in ("bpy", "gpu", "gpu_extras", "mathutils", "blf", "bpy_extras"):
        (blockers / f"{name}.py").write_text(f"raise ImportError('{name} is blocked for this test')\n")
    code = textwrap.dedent(
        """
        import sys
        import test_overlay_cache as t
        t.test_dirty_scene_light_passes_then_coarse_then_refined_bands_after_the_delay()
        t.test_free_releases_every_gpu_resource_it_counts()
        loaded = sorted(m for m in ("bpy", "gpu", "gpu_extras", "blf") if sys.modules.get(m) is not None)
        assert not loaded, loaded
        print("scheduled without bpy")
        """
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60,
        env={"PYTHONPATH": f"{blockers}:{REPO}:{REPO / 'tests'}", "PATH": "/usr/bin:/bin",
             "PYTHONDONTWRITEBYTECODE": "1"})
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "scheduled without bpy" in proc.stdout


def test_step_budget_is_read_when_cutting_bands(monkeypatch):
    """The budget is the module's STEP_BUDGET at the time of the step (tests and tuning change it)."""
    monkeypatch.setattr(overlay_cache, "STEP_BUDGET", 1e9)
    cache, backend, clock = make_cache()
    cache.request_view(1, VIEW, PROJECTION, REGION)
    run(cache)
    clock.t = 1.0
    assert run(cache) == [REFINED] and cache.statistics["bands"] == 1
