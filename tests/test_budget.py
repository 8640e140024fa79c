# SPDX-License-Identifier: GPL-3.0-or-later
"""Budget mode (vsgl_addon/budget.py): the cost model's fit on synthetic timings, its cache in the
user's cache directory (round trip, one warning and the built-in model for a bad file), and the
choice: monotone in the target, the cheapest and the richest setting at the two ends. No GPU, no
clock: timings here are made up."""

from __future__ import annotations

import json

import numpy as np
import pytest

from test_planner import _room
from test_proxies import point_light
from vsgl_addon import budget as B
from vsgl_addon import planner as P
from vsgl_addon.proxies import ProxyCache
from vsgl_addon.settings import SettingsError, VSGLSettings

SIZE = (240, 180)


def _plan(sharp=False, settings=VSGLSettings()):
    light = point_light((0.0, 0.0, 2.0), power=500.0)
    room = _room([light], floor_roughness=0.1, wall_roughness=0.3) if sharp else _room([light])
    camera = room.camera
    return room, P.plan_frame(room, settings, ProxyCache(), camera.projection_matrix() @ camera.view_matrix())


def _synthetic_samples(theta, count=24, noise=0.0, seed=0):
    """Frames with random features per step and timings = features · theta (+ relative noise)."""
    rng = np.random.default_rng(seed)
    samples = []
    for _ in range(count):
        features, timings = {}, {}
        for step, names in B.STEP_FEATURES.items():
            values = rng.uniform(0.1, 10.0, len(names))
            if "one" in names:
                values[names.index("one")] = 1.0
            features[step] = values.tolist()
            timings[step] = float(np.dot(theta[step], values)) * (1.0 + noise * rng.standard_normal())
        samples.append({"features": features, "timings": timings})
    return samples


# --- The cost model ------------------------------------------------------------------------------


def test_the_fit_recovers_synthetic_coefficients_and_keeps_them_non_negative():
    # Another machine: the built-in coefficients times 0.5 to 2, one feature that costs nothing.
    rng = np.random.default_rng(3)
    theta = {step: np.maximum(np.asarray(B.FALLBACK_COEFFICIENTS[step]), 1e-3) * rng.uniform(0.5, 2.0, len(names))
             for step, names in B.STEP_FEATURES.items()}
    theta["vsgl_shading"][0] = 0.0
    fitted = B.fit(_synthetic_samples(theta, count=48))
    for step in B.STEP_FEATURES:
        # The prior's pull (PRIOR_WEIGHT samples' worth) is small against 48 exact frames: each
        # coefficient within 5 % of the step's largest, and predictions of new frames within 3 % (the
        # prior is up to 2x off each coefficient here, and pulls the correlated ones together).
        np.testing.assert_allclose(fitted[step], theta[step], atol=0.05 * max(theta[step]))
    for sample in _synthetic_samples(theta, count=8, seed=9):
        for step, values in sample["features"].items():
            assert np.dot(fitted[step], values) == pytest.approx(sample["timings"][step], rel=0.03)
    noisy = B.fit(_synthetic_samples(theta, count=48, noise=0.2, seed=1))
    assert all(min(values) >= 0.0 for values in noisy.values())
    predicted = np.dot(noisy["vsgl_shading"], [1.0, 5.0, 5.0])
    assert predicted == pytest.approx(np.dot(theta["vsgl_shading"], [1.0, 5.0, 5.0]), rel=0.15)


def test_a_step_the_samples_never_ran_keeps_the_built_in_coefficients():
    theta = {step: np.full(len(names), 0.01) for step, names in B.STEP_FEATURES.items()}
    samples = _synthetic_samples(theta, count=8)
    for sample in samples:
        del sample["features"]["mrp_asg"]
        sample["features"]["vpl_culling"] = [0.0, 0.0, 0.0]
    fitted = B.fit(samples)
    assert fitted["mrp_asg"] == list(B.FALLBACK_COEFFICIENTS["mrp_asg"])
    assert fitted["vpl_culling"] == list(B.FALLBACK_COEFFICIENTS["vpl_culling"])


def test_nnls_is_exact_and_never_negative():
    matrix = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    np.testing.assert_allclose(B.nnls(matrix, [2.0, 3.0, 5.0]), [2.0, 3.0], atol=1e-12)
    # The unconstrained solution has a negative coefficient: NNLS sets it to zero instead.
    assert B.nnls(matrix, [2.0, -3.0, -1.0]).tolist() == pytest.approx([0.5, 0.0])
    assert B.nnls(matrix, [-1.0, -1.0, -2.0]).tolist() == [0.0, 0.0]


def test_a_scene_s_correction_moves_its_prediction_towards_what_it_measured():
    room, plan = _plan()
    features = B.frame_features(plan, VSGLSettings(), SIZE, SIZE, room.geometry.triangle_count)
    model = B.CostModel.fallback()
    before = model.predict_steps(features)
    timings = {step: 2.0 * seconds for step, seconds in before.items()}
    corrected = model.add_frame(features, timings, "scene-a")
    # Refitted to that one frame (plus the prior), then corrected towards it: closer than before.
    assert abs(corrected.predict(features, "scene-a") - sum(timings.values())) < 0.5 * sum(before.values())
    assert corrected.predict(features, "other") == pytest.approx(corrected.predict(features))
    wild = model.add_frame(features, {step: 1e3 * s for step, s in before.items()}, "scene-b")
    assert max(wild.corrections["scene-b"].values()) <= B.CORRECTION_RANGE[1]


# --- The cache -----------------------------------------------------------------------------------


def test_the_cache_lives_in_the_user_s_cache_directory(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert B.cache_path() == tmp_path / "vsgl-addon" / B.CACHE_NAME


def test_the_cache_round_trips_and_keeps_other_gpus_models(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert B.load_model("gpu A").source.startswith("built-in") and B.load_model("gpu A").warning is None
    theta = {step: np.full(len(names), 0.02) for step, names in B.STEP_FEATURES.items()}
    model = B.CostModel.fallback().with_samples(_synthetic_samples(theta, count=5), "fitted to this machine's frames")
    model.correct({"vsgl_shading": np.array([1.0, 0.2, 2.0])}, {"vsgl_shading": 0.3}, "scene-a")
    model.set_vpl_fraction("scene-a", 0.125)
    B.save_model("gpu A", model)
    B.save_model("gpu B", B.CostModel.fallback())
    loaded = B.load_model("gpu A")
    assert loaded.warning is None and loaded.source == model.source
    assert loaded.coefficients == model.coefficients  # JSON keeps a float64 exactly
    assert loaded.samples == json.loads(json.dumps(model.samples))
    assert loaded.corrections == model.corrections and loaded.vpl_fraction("scene-a") == 0.125
    assert B.load_model("gpu B").coefficients == B.CostModel.fallback().coefficients
    assert B.load_model("gpu C").samples == []  # a GPU without a model: the built-in one, silently


@pytest.mark.parametrize("content", ["{not json", json.dumps({"format": 99, "models": {}}),
                                     json.dumps({"format": B.CACHE_FORMAT, "models": {"gpu": {"coefficients": {
                                         "vsgl_shading": [-1.0, 0.1, 0.1]}}}}),
                                     json.dumps({"format": B.CACHE_FORMAT, "models": {"gpu": {"coefficients": {
                                         "read_back": [1.0, 2.0]}}}}),
                                     json.dumps([1, 2, 3])])
def test_a_bad_cache_file_gives_one_clear_warning_and_the_built_in_model(tmp_path, content):
    path = tmp_path / B.CACHE_NAME
    path.write_text(content)
    model = B.load_model("gpu", path)
    assert model.coefficients == B.CostModel.fallback().coefficients and model.samples == []
    assert model.warning is not None and "\n" not in model.warning
    assert str(path) in model.warning and "built-in cost model" in model.warning
    # Saving over it replaces the bad file with a readable one.
    B.save_model("gpu", model, path)
    assert B.load_model("gpu", path).warning is None


def test_a_cache_of_an_earlier_format_is_replaced_silently(tmp_path):
    """An earlier version's cache (fewer features) gives the built-in model without a warning, so the
    caller recalibrates (budget_render.model_for), and saving replaces the file."""
    path = tmp_path / B.CACHE_NAME
    path.write_text(json.dumps({"format": B.CACHE_FORMAT - 1, "models": {"gpu": {"coefficients": {
        "vpl_culling": [2.4, 1.53]}, "samples": [{"features": {}, "timings": {}}]}}}))
    model = B.load_model("gpu", path)
    assert model.warning is None and model.samples == [] and model.coefficients == B.CostModel.fallback().coefficients
    B.save_model("gpu", model, path)
    assert json.loads(path.read_text())["format"] == B.CACHE_FORMAT


def test_the_vpl_pass_features_test_every_vpl_and_shade_the_sub_image_s_share():
    """Each tile tests every VPL's spheroid whatever the interleave; a pixel shades the listed VPLs
    of its sub-image, 1/N² of them (vpl_cull_shade.comp.glsl)."""
    room, plan = _plan(sharp=True)
    triangles = room.geometry.triangle_count
    rows = {n: B.frame_features(plan, VSGLSettings(vpl_interleave=n), SIZE, SIZE, triangles, 0.5)["vpl_culling"]
            for n in ("1", "2", "8")}
    assert rows["1"][2] > 0.0 and rows["2"][2] == rows["1"][2] == rows["8"][2]
    assert rows["2"][1] == pytest.approx(rows["1"][1] / 4) and rows["8"][1] == pytest.approx(rows["1"][1] / 64)


# --- The choice ----------------------------------------------------------------------------------

TARGETS = np.geomspace(1.0, 1e6, 25)


@pytest.mark.parametrize("sharp", [False, True])
def test_the_choice_is_monotone_in_the_budget(sharp):
    room, plan = _plan(sharp)
    model = B.CostModel.fallback()
    choices = [B.choose(plan, VSGLSettings(), *SIZE, target, model, room.geometry.triangle_count)
               for target in TARGETS]
    # Higher is richer: N, RSM side, scale up; δ and the interleave factor down (the user's "auto"
    # where no VPL pass runs, the same at every target).
    keys = [(c.candidate.vsgl_count, c.candidate.rsm_size, -c.candidate.delta,
             -int(c.candidate.vpl_interleave) if sharp else 0, c.candidate.scale) for c in choices]
    for low, high in zip(keys, keys[1:]):
        assert all(a <= b for a, b in zip(low, high)), (low, high)
    assert [c.step for c in choices] == sorted(c.step for c in choices)
    # N between the path's levels: filled towards the next level only, never reaching it.
    steps = B.path(plan, VSGLSettings(), *SIZE, model, room.geometry.triangle_count)
    for choice in choices:
        if choice.fits and choice.step + 1 < len(steps):
            assert choice.candidate.vsgl_count < max(steps[choice.step + 1][0].vsgl_count, steps[choice.step][0].vsgl_count + 1)
    assert any(c.candidate.vsgl_count not in B.VSGL_COUNTS for c in choices)
    for choice in choices:
        if choice.fits:
            assert choice.predicted_seconds <= choice.target_seconds
    assert len({key for key in keys}) > 5  # the targets span most of the path


def test_the_ends_of_the_budget_give_the_cheapest_and_the_richest_settings():
    room, plan = _plan(sharp=True)
    assert plan.runs("vpl_pass")
    model = B.CostModel.fallback()
    tight = B.choose(plan, VSGLSettings(), *SIZE, 1e-3 * 1e3, model, room.geometry.triangle_count)
    assert not tight.fits and tight.step == 0
    assert (tight.candidate.vsgl_count, tight.candidate.rsm_size, tight.candidate.delta,
            tight.candidate.vpl_interleave, tight.candidate.scale) == (
        B.VSGL_COUNTS[0], B.RSM_SIZES[0], B.DELTAS[0], B.INTERLEAVES[0], B.SCALES[0])
    assert tight.size == B.scaled_size(*SIZE, B.SCALES[0])
    assert "cannot be met" in tight.line()
    loose = B.choose(plan, VSGLSettings(), *SIZE, 6e5, model, room.geometry.triangle_count)
    assert loose.fits and loose.step == loose.steps - 1
    assert (loose.candidate.vsgl_count, loose.candidate.rsm_size, loose.candidate.delta,
            loose.candidate.vpl_interleave, loose.candidate.scale) == (
        B.VSGL_COUNTS[-1], B.RSM_SIZES[-1], B.DELTAS[-1], B.INTERLEAVES[-1], 1.0)
    assert loose.size == SIZE and loose.settings.vsgl_count == 4096
    # Without a VPL pass δ and the interleave are not the budget's: the user's stay.
    room, rough = _plan(settings=VSGLSettings(delta=0.02, vpl_interleave="2"))
    assert not rough.runs("vpl_pass")
    choice = B.choose(rough, VSGLSettings(delta=0.02, vpl_interleave="2"), *SIZE, 6e5, model)
    assert choice.settings.delta == 0.02 and choice.settings.vpl_interleave == "2"


def test_a_step_the_plan_does_not_run_costs_nothing():
    room, plan = _plan()
    off = P.plan_frame(room, VSGLSettings(visibility=False), ProxyCache())
    on = B.frame_features(plan, VSGLSettings(), SIZE, SIZE)
    without = B.frame_features(off, VSGLSettings(visibility=False), SIZE, SIZE)
    assert "ism" in on and "ism" not in without and "vpl_culling" not in on
    assert B.CostModel.fallback().predict(without) < B.CostModel.fallback().predict(on)
    assert on["upscale"].tolist() == [0.0]
    half = B.frame_features(plan, VSGLSettings(), (120, 90), SIZE)
    assert half["upscale"][0] > 0.0 and half["vsgl_shading"][2] == pytest.approx(0.25 * on["vsgl_shading"][2])


def test_budget_runs_the_passes_auto_would_and_pins_them_in_its_settings():
    """The dielectric floor of test_planner's Auto test: Budget's plan weighs the VPL pass and
    MRP-ASG as Auto's does and leaves both out, so the budget goes to N, RSM and resolution (no δ or
    interleave on its path); the chosen settings turn their toggles off and are Manual, so the frame
    runs the passes the path was timed for. A metal floor keeps both, toggles as the user set them."""
    light = point_light((0.0, 0.0, 2.0), power=500.0)
    for floor_metallic, kept in ((0.0, False), (1.0, True)):
        room = _room([light], floor_roughness=0.1, wall_roughness=0.5, floor_metallic=floor_metallic)
        settings = VSGLSettings(quality_mode="budget", delta=0.02, vpl_interleave="2")
        plan = P.plan_frame(room, settings, ProxyCache())
        auto = P.plan_frame(room, settings.overridden(quality_mode="auto"), ProxyCache())
        assert {k: d.run for k, d in plan.decisions.items()} == {k: d.run for k, d in auto.decisions.items()}
        assert set(plan.weighed) == set(P.AUTO_OPTIONAL)
        assert plan.runs("vpl_pass") is kept and plan.runs("mrp_asg") is kept
        for target in (50.0, 6e5):
            choice = B.choose(plan, settings, *SIZE, target, B.CostModel.fallback(), room.geometry.triangle_count)
            assert choice.settings.quality_mode == "manual"
            assert (choice.settings.caustics, choice.settings.glossy_reflectors) == (kept, kept)
            pinned = P.plan_frame(room, choice.settings, ProxyCache())
            assert {k: d.run for k, d in pinned.decisions.items()} == {k: d.run for k, d in plan.decisions.items()}
            if not kept:  # δ and the interleave are not the budget's without a VPL pass
                assert (choice.settings.delta, choice.settings.vpl_interleave) == (0.02, "2")


def test_the_plan_reports_the_budget():
    room, plan = _plan()
    choice = B.choose(plan, VSGLSettings(), *SIZE, 200.0, B.CostModel.fallback(), room.geometry.triangle_count)
    choice.measured_seconds = 0.21
    plan.budget = choice
    report = json.loads(json.dumps(plan.to_dict()))
    assert report["budget"]["target_ms"] == pytest.approx(200.0) and report["budget"]["measured_ms"] == pytest.approx(210.0)
    assert report["budget"]["predicted_ms"] == pytest.approx(choice.predicted_seconds * 1e3)
    assert report["summary"][0].startswith("Budget: on — target 200 ms, predicted ")
    assert "measured 210 ms" in report["summary"][0]


def test_delta_listed_follows_the_measured_table_and_falls_with_delta():
    assert B.delta_listed(1e-3) == pytest.approx(1.0)
    assert B.delta_listed(1e-2) == pytest.approx(346.0 / 1242.0)
    values = [B.delta_listed(d) for d in np.geomspace(1e-6, 1e-1, 30)]
    assert all(a > b for a, b in zip(values, values[1:])) and all(np.isfinite(values))


def test_upscale_is_bilinear_and_keeps_constants():
    image = np.full((9, 12, 3), 0.5, np.float32)
    out = B.upscale(image, 48, 36)
    assert out.shape == (36, 48, 3) and out.dtype == np.float32 and np.all(out == 0.5)
    ramp = np.tile(np.arange(4, dtype=np.float32), (2, 1))
    wide = B.upscale(ramp, 8, 2)
    assert wide[0].tolist() == pytest.approx([0.0, 0.25, 0.75, 1.25, 1.75, 2.25, 2.75, 3.0])
    assert B.upscale(ramp, 4, 2) is ramp
    assert B.upscale(np.ones((1, 1)), 5, 3).shape == (3, 5)


def test_quality_settings_are_validated():
    assert VSGLSettings().quality_mode == "manual"
    assert VSGLSettings(quality_mode="budget", time_budget_ms=1.0).time_budget_ms == 1.0
    with pytest.raises(SettingsError, match="quality mode"):
        VSGLSettings(quality_mode="ultra")
    for bad in (0.5, 1e9, float("nan")):
        with pytest.raises(SettingsError, match="time budget"):
            VSGLSettings(time_budget_ms=bad)


# --- The viewport's coarse step ------------------------------------------------------------------


def test_the_coarse_factor_is_the_largest_the_model_predicts_within_the_step_budget():
    room, plan = _plan()
    model = B.CostModel.fallback()
    triangles = room.geometry.triangle_count
    factors = [B.coarse_factor(plan, VSGLSettings(), (400, 300), 1.0, seconds, model, triangles)
               for seconds in np.geomspace(1e-4, 100.0, 20)]
    assert [f for f, _ in factors] == sorted(f for f, _ in factors)  # monotone in the step budget
    assert factors[0][0] == B.COARSE_FACTORS[-1] and factors[-1][0] == 1.0
    for (factor, predicted), seconds in zip(factors, np.geomspace(1e-4, 100.0, 20)):
        if factor < 1.0 and factor != B.COARSE_FACTORS[-1]:
            bigger = B.COARSE_FACTORS[B.COARSE_FACTORS.index(factor) - 1]
            size = B.scaled_size(400, 300, bigger)
            assert predicted <= seconds < B.view_seconds(plan, VSGLSettings(), size, (400, 300), model, triangles)


def test_the_viewport_s_first_coarse_image_follows_the_cost_model():
    import test_view_pipeline as V
    from vsgl_addon.view_pipeline import COARSE, COARSE_SHARE, ViewPipeline

    room, plan = _plan()

    class ModelBackend(V.FakeBackend):
        def cost_model(self):
            return B.CostModel.fallback()

        def scene_lights(self, description, settings):
            lights = super().scene_lights(description, settings)
            lights.plan, lights.scene = plan, room
            return lights

    sizes = {}
    budgeted = VSGLSettings(quality_mode="budget")
    for budget in (0.01, 10.0):
        clock = V.Clock()
        backend = ModelBackend(clock)
        pipeline = ViewPipeline(backend, clock, step_budget=budget)
        pipeline.request_view(np.eye(4), np.eye(4), (400, 300))
        pipeline.step(lambda: room, budgeted, 1.0)
        entry = pipeline.statistics
        # The step's light passes took light_seconds of it: the coarse image gets a share of the rest.
        available = COARSE_SHARE * max(budget - entry["light_seconds"], budget / 4)
        expected, predicted = B.coarse_factor(plan, budgeted, (400, 300), 1.0, available, B.CostModel.fallback(),
                                              room.geometry.triangle_count)
        assert entry["level"] == COARSE and entry["predicted_view_seconds"] == pytest.approx(predicted)
        assert backend.renders[0] == B.scaled_size(400, 300, expected)
        sizes[budget] = backend.renders[0]
        pipeline.free()
    assert sizes[10.0] == (400, 300) and sizes[0.01][0] < 400
    # Below full size the coarse image is lit by the preview's passes: the prediction is of those.
    from vsgl_addon.reference.vpl_culling import preview_stride
    from vsgl_addon.view_pipeline import preview_light_settings

    clock = V.Clock()
    pipeline = ViewPipeline(ModelBackend(clock), clock, step_budget=0.05)
    pipeline.request_view(np.eye(4), np.eye(4), (400, 300))
    pipeline.step(lambda: room, budgeted, 0.5)
    preview = preview_light_settings(budgeted)
    assert pipeline.lights_preview and preview != budgeted
    available = COARSE_SHARE * max(0.05 - pipeline.statistics["light_seconds"], 0.05 / 4)
    _, predicted = B.coarse_factor(plan, preview, (400, 300), 0.5, available, B.CostModel.fallback(),
                                   room.geometry.triangle_count, None, preview_stride(preview.rsm_size ** 2))
    assert pipeline.statistics["predicted_view_seconds"] == pytest.approx(predicted)
    pipeline.free()
    # Manual mode: the first coarse image at the asked scale, whatever the model says.
    clock = V.Clock()
    backend = ModelBackend(clock)
    pipeline = ViewPipeline(backend, clock, step_budget=0.01)
    pipeline.request_view(np.eye(4), np.eye(4), (400, 300))
    pipeline.step(lambda: room, VSGLSettings(), 1.0)
    assert backend.renders[0] == (400, 300) and "predicted_view_seconds" not in pipeline.statistics
    pipeline.free()


def test_the_view_prediction_counts_the_resolve_the_kept_guide_and_the_preview_stride():
    """view_seconds: the joint bilateral resolve at the region's pixels (VIEW_RESOLVE_SECONDS per
    10⁵), the full-resolution guide G-buffer only when the viewport has none kept, and the coarse
    preview's VPL pass over one VPL of each block of S."""
    room, plan = _plan(sharp=True)
    assert plan.runs("vpl_pass")
    model = B.CostModel.fallback()
    settings = VSGLSettings(quality_mode="budget")
    triangles = room.geometry.triangle_count
    low, full = (20, 12), (800, 480)
    bare = B.view_seconds(plan, settings, low, low, model, triangles)
    features = B.frame_features(plan, settings, low, low, triangles)
    steps = model.predict_steps({step: features[step] for step in B.VIEW_STEPS if step in features})
    assert bare == pytest.approx(sum(steps.values()) + B.VIEW_RESOLVE_SECONDS * 20 * 12 / 1e5)
    kept = B.view_seconds(plan, settings, low, full, model, triangles, guide=False)
    assert kept == pytest.approx(sum(steps.values()) + B.VIEW_RESOLVE_SECONDS * 800 * 480 / 1e5)
    guide = model.predict({"gbuffer": B.frame_features(plan, settings, full, full, triangles)["gbuffer"]})
    assert B.view_seconds(plan, settings, low, full, model, triangles) == pytest.approx(kept + guide)
    strided = B.view_seconds(plan, settings, low, full, model, triangles, vpl_fraction=0.5, vpl_stride=16)
    every = B.view_seconds(plan, settings, low, full, model, triangles, vpl_fraction=0.5)
    culled = B.frame_features(plan, settings, low, low, triangles, 0.5)["vpl_culling"]
    per_vpl = np.dot(model.coefficients["vpl_culling"][1:], culled[1:])
    assert every - strided == pytest.approx(per_vpl * 15 / 16)
    # At full size the coarse image is a sample: the stride is not applied there.
    assert B.coarse_factor(plan, settings, full, 1.0, 1e3, model, triangles, 0.5, 16) == (
        1.0, pytest.approx(B.view_seconds(plan, settings, full, full, model, triangles, 0.5)))
