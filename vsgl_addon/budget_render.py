# SPDX-License-Identifier: GPL-3.0-or-later
"""Budget mode's frames: the cost model of this GPU (calibrated at first use), the budget's choice
(budget.py), the frame rendered with it, upscaled to the output size, and its measured timings
added to the model. Never touches bpy.context (the engine and the command line call it); needs a
GPU context, as FrameRenderer does."""

from __future__ import annotations

import hashlib
import time

import numpy as np

from .budget import (Candidate, CostModel, cache_path, choose, frame_features, load_model, save_model, scaled_size,
                     upscale)
from .planner import plan_frame

#: The calibration's frames (N, RSM side, δ, interleave, resolution scale): spread so that every
#: feature of budget.STEP_FEATURES varies independently of the others, at most a quarter of the
#: output's pixels but one (the frames cost about as much as two full frames at the default N).
CALIBRATION = (
    Candidate(64, 64, 1e-2, "4", 0.5),
    Candidate(512, 64, 1e-3, "2", 0.25),
    Candidate(128, 256, 1e-3, "1", 0.25),
    Candidate(256, 128, 1e-2, "8", 0.5),
    Candidate(32, 32, 1e-1, "1", 0.5),
    Candidate(1024, 128, 3e-3, "4", 0.25),
    Candidate(128, 64, 1e-3, "2", 1.0),
)

def scene_key(scene) -> str:
    """What tells one scene from another for its cost corrections and VPL count: a hash of its
    triangles, its material and light counts (the cache's key, so no name of the user's is stored)."""
    positions = np.ascontiguousarray(scene.geometry.positions, np.float32)
    digest = hashlib.sha1(positions.tobytes()).hexdigest()[:16]
    return f"{digest}-{len(scene.materials)}m-{len(scene.lights)}l"


def _view_projection(scene, view):
    if view is None:
        return scene.camera.projection_matrix() @ scene.camera.view_matrix()
    return np.asarray(view[1]) @ np.asarray(view[0])


def _remember_vpls(model, scene, plan, settings, counts) -> None:
    """The scene's VPLs per RSM texel (of the VPL pass's views), from a frame that counted them."""
    if not plan.runs("vpl_pass"):
        return
    texels = sum(light.rsm_views for light in plan.lights if light.gets_rsm) * settings.rsm_size ** 2
    if texels > 0:
        model.set_vpl_fraction(scene_key(scene), float(counts.get("vpls", 0)) / texels)


def _features(model, scene, plan, settings, size, full_size):
    return frame_features(plan, settings, size, full_size, int(scene.geometry.triangle_count),
                          model.vpl_fraction(scene_key(scene)))


def _render(renderer, scene, settings, size, full_size, view):
    """(FrameImages at full_size, its timings with the upscale step)."""
    arguments = () if view is None else tuple(view)
    images = renderer.render(scene, settings, *size, *arguments)
    clock = time.perf_counter()
    if tuple(size) != tuple(full_size):
        width, height = full_size
        for name in ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular", "coverage",
                     "indirect_glossy_reflectors", "indirect_caustics"):
            setattr(images, name, upscale(getattr(images, name), width, height))
    images.timings["upscale"] = time.perf_counter() - clock if tuple(size) != tuple(full_size) else 0.0
    return images


def calibrate(renderer, scene, settings, width: int, height: int, model: CostModel | None = None,
              view=None) -> CostModel:
    """The model fitted to CALIBRATION's frames of ``scene`` (and ``model``'s own samples), after one
    warm-up frame (shader compilation) that is not counted."""
    model = CostModel.fallback() if model is None else model
    frames = []
    for index, candidate in enumerate((CALIBRATION[0], *CALIBRATION)):
        chosen = candidate.apply(settings)
        size = scaled_size(width, height, candidate.scale)
        images = _render(renderer, scene, chosen, size, (width, height), view)
        _remember_vpls(model, scene, images.plan, chosen, images.counts)
        if index:
            frames.append((_features(model, scene, images.plan, chosen, size, (width, height)), images.timings))
    for features, timings in frames:
        model = model.add_frame(features, timings)
    # The scene's corrections from the fitted model's residuals on the scene's own frames.
    for features, timings in frames:
        model.correct(features, timings, scene_key(scene))
    return model


def model_for(renderer, scene, settings, width: int, height: int, gpu: str, view=None, log=None) -> CostModel:
    """This GPU's cached model; calibrated on ``scene`` and saved when the cache has none. An
    unreadable cache gives the built-in model and its one warning (not recalibrated: the file is
    replaced by the next budgeted frame's save)."""
    model = load_model(gpu)
    if model.warning is None and not model.samples:
        if log is not None:
            log(f"VSGL: no cost model of this GPU yet: calibrating on this scene ({len(CALIBRATION)} frames), "
                f"kept in {cache_path()}")
        model = calibrate(renderer, scene, settings, width, height, model, view)
        save_model(gpu, model)
    return model


def render_budgeted(renderer, scene, settings, width: int, height: int, model: CostModel, view=None):
    """(FrameImages at width × height, the BudgetChoice with its measured time, the model refitted
    with this frame). The plan (images.plan) reports the choice under ``budget``."""
    plan = plan_frame(scene, settings, None, _view_projection(scene, view))
    key = scene_key(scene)
    choice = choose(plan, settings, width, height, settings.time_budget_ms, model,
                    int(scene.geometry.triangle_count), model.vpl_fraction(key), key)
    images = _render(renderer, scene, choice.settings, choice.size, (width, height), view)
    choice.measured_seconds = float(sum(images.timings.values()))
    features = _features(model, scene, images.plan, choice.settings, choice.size, (width, height))
    _remember_vpls(model, scene, images.plan, choice.settings, images.counts)
    images.plan.budget = choice
    # The frame ran the choice's Manual settings; the passes the budget's plan weighed keep its reasons.
    images.plan.decisions.update({name: plan.decisions[name] for name in plan.weighed})
    images.plan.weighed = plan.weighed
    return images, choice, model.add_frame(features, images.timings, key)
