# SPDX-License-Identifier: GPL-3.0-or-later
"""The view-dependent PDF (vsgl_addon/reference/brsm.py, 000 §5): the importance against a direct
double loop, the defensive mixture's bounds, and, on the GPU, that VSGL generation with it keeps
every view's summed VSGL power equal to its RSM total (000 Eq. 5)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vsgl_addon.scene_description import SceneDescription

from vsgl_addon.reference import brsm


def _loop_importance(p, n, rx, rn, rw, radius):
    out = np.zeros(len(p))
    for i in range(len(p)):
        for j in range(len(rx)):
            d = rx[j] - p[i]
            dist = math.sqrt(d @ d)
            w = d / dist
            out[i] += rw[j] * max(n[i] @ w, 0.0) * max(-(rn[j] @ w), 0.0) / (dist * dist + radius * radius)
    return out


def test_importance_equals_the_double_loop_and_faces_matter():
    rng = np.random.default_rng(3)
    p = rng.normal(size=(40, 3))
    n = rng.normal(size=(40, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    rx = rng.normal(size=(25, 3)) + [0.0, 0.0, 3.0]
    rn = rng.normal(size=(25, 3))
    rn /= np.linalg.norm(rn, axis=1, keepdims=True)
    rw = rng.random(25)
    for radius in (1e-3, 0.3, 10.0):
        np.testing.assert_allclose(brsm.view_importance(p, n, rx, rn, rw, radius),
                                   _loop_importance(p, n, rx, rn, rw, radius), rtol=1e-12, atol=1e-300)
    # A texel facing away from every receiver, or receivers facing away, weigh nothing.
    up, down = np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, -1.0]])
    above = np.array([[0.0, 0.0, 2.0]])
    assert brsm.view_importance([[0, 0, 0]], up, above, down, [1.0], 0.1)[0] == pytest.approx(1.0 / 4.01)
    assert brsm.view_importance([[0, 0, 0]], down, above, down, [1.0], 0.1)[0] == 0.0
    assert brsm.view_importance([[0, 0, 0]], up, above, up, [1.0], 0.1)[0] == 0.0
    # No geometry (zero normal), a receiver on the texel, no receivers: finite, no NaN.
    values = brsm.view_importance([[0, 0, 0], [1, 1, 1]], [[0, 0, 0], [0, 0, 1]], [[1, 1, 1]], down, [1.0], 1e-6)
    assert np.all(np.isfinite(values)) and values[0] == 0.0
    assert brsm.view_importance(p, n, np.zeros((0, 3)), np.zeros((0, 3)), [], 0.1).tolist() == [0.0] * 40


def test_the_defensive_mixture_keeps_every_lit_texel_and_sums_to_one():
    rng = np.random.default_rng(5)
    w = rng.random((8, 8)) * (rng.random((8, 8)) > 0.3)
    i = rng.random((8, 8)) * (rng.random((8, 8)) > 0.5)
    p = brsm.view_pdf(w, i)
    assert p.sum() == pytest.approx(1.0, abs=1e-12)
    light = w / w.sum()
    assert np.all(p >= brsm.DEFENSIVE_SHARE * light - 1e-15)  # no texel with bounce power at zero
    assert np.all(p[w == 0] == 0.0)
    np.testing.assert_allclose(brsm.view_pdf(w, i, 1.0), light)
    # Nothing in view is lit: the light PDF; nothing lit at all: zeros.
    np.testing.assert_allclose(brsm.view_pdf(w, np.zeros_like(w)), light)
    assert brsm.view_pdf(np.zeros((4, 4)), np.ones((4, 4))).sum() == 0.0
    assert np.all(np.isfinite(brsm.view_pdf([np.nan, 1.0, np.inf], [1.0, np.nan, 1.0])))


def _planned_vsgls(scene, scene_gpu, settings, view, receivers) -> dict:
    """The export table of the frame the planner plans for ``view``, its view PDF run exactly when
    settings.pdf is "view" (the test scenes' lights are of the types it weighs)."""
    from vsgl_addon.pipeline import render_scene_vsgls
    from vsgl_addon.planner import plan_frame

    plan = plan_frame(scene, settings, view_projection=view[1] @ view[0])
    assert plan.runs("view_pdf") == (settings.pdf == "view")
    vsgls = render_scene_vsgls(scene_gpu, settings, plan=plan, receivers=receivers)
    try:
        return vsgls.read()
    finally:
        vsgls.free()


@pytest.mark.gpu
def test_generation_with_the_view_pdf_keeps_the_rsm_total(monkeypatch):
    """The view PDF's generation on a point light (the planner gives it to suns only; the mechanism is
    the same): summed VSGL power equals the RSM total with either PDF (000 Eq. 5; with the view PDF
    and pipeline.NORMALIZE_VIEW_PDF_POWERS each view's powers are normalized to it, Eq. 5 alone
    falls short there), and the view PDF moves the kernels towards the reflectors that light what
    the camera sees."""
    from test_planner import _camera, _room
    from test_proxies import point_light
    from vsgl_addon import pipeline, planner
    from vsgl_addon.passes.rsm import SceneGPU
    from vsgl_addon.pipeline import view_receivers
    from vsgl_addon.scene_description import SceneDescription
    from vsgl_addon.settings import VSGLSettings

    monkeypatch.setattr(planner, "VIEW_PDF_LIGHT_TYPES", ("POINT",))
    monkeypatch.setattr(pipeline, "NORMALIZE_VIEW_PDF_POWERS", True)
    room = _room([point_light((0.0, 0.0, 3.5), power=800.0)])
    camera = _camera(position=(2.5, -1.0, 0.6), looking=(1.0, 0.3, -0.4))  # a corner of the floor
    scene = SceneDescription(room.geometry, room.materials, room.lights, camera, room.object_names)
    view = (camera.view_matrix(), camera.projection_matrix())
    scene_gpu = SceneGPU(scene)
    try:
        receivers = view_receivers(scene_gpu, *view)
        assert len(receivers["weight"]) > 16
        centres = {}
        for pdf in ("light", "view"):
            settings = VSGLSettings(vsgl_count=64, rsm_size=64, visibility=False, pdf=pdf)
            table = _planned_vsgls(scene, scene_gpu, settings, view, receivers)
            assert len(table["power"]) == 64 and np.all(np.isfinite(table["power"]))
            np.testing.assert_allclose(table["power"].sum(axis=0), table["rsm_total_power"][0], rtol=0.05)
            if pdf == "view":  # each view normalized to its total's luminance (pipeline.SceneVSGLs.merge)
                lum = np.array([0.2126, 0.7152, 0.0722])
                assert table["power"].sum(axis=0) @ lum == pytest.approx(table["rsm_total_power"][0] @ lum, rel=1e-5)
            # How much the VSGLs matter to the view's receivers (at their means, facing their diffuse axes).
            centres[pdf] = brsm.view_importance(table["mean"], table["diffuse_axis"], receivers["position"],
                                                receivers["normal"], receivers["weight"], receivers["radius"]).mean()
    finally:
        scene_gpu.free()
    # The floor corner in view is lit by the wall above it, not by the floor around it: the view PDF
    # moves the kernels to the texels that light what the camera sees.
    assert centres["view"] > 1.5 * centres["light"]


@pytest.mark.gpu
def test_the_default_view_pdf_weighs_a_sun_and_keeps_its_near_power():
    """The defaults (pdf "view", no per-view normalization) on a sun over a 40 m ground with a wall,
    seen from a few metres: the plan weighs the sun's kernels by the view, more of them land within
    3 m of what the camera sees, and 000 Eq. 5's shortfall (the power it sums short, README
    "View-dependent PDF") lies away from the view: the VSGL power within 10 m of the view's
    receivers is the light PDF's within 10 %, the summed power at least 0.6 of the RSM total at
    N = 64."""
    from test_planner import _camera
    from test_proxies import point_light
    from vsgl_addon.passes.rsm import SceneGPU
    from vsgl_addon.pipeline import view_receivers
    from vsgl_addon.scene_description import SceneDescription
    from vsgl_addon.settings import VSGLSettings
    from test_proxies import grid, material, scene_of

    sun = point_light((0.0, 0.0, 10.0), power=3.0, kind="SUN", direction=(0.3, 0.2, -1.0))
    ground = grid(8, 8, 40.0, 40.0, origin=(-20, -20, 0))
    wall = grid(2, 2, 3.0, 2.0, origin=(-1.5, 2, 0), u=(1, 0, 0), v=(0, 0, 1))
    mats = (material("Ground", 0.7, metallic=0.0, color=(0.6, 0.6, 0.6)),
            material("Wall", 0.7, metallic=0.0, color=(0.8, 0.8, 0.8)))
    built = scene_of([(ground, 1, 0), (wall, 2, 1)], mats, [sun])
    camera = _camera(position=(0.0, -2.0, 1.5), looking=(0.0, 1.0, -0.3))  # the wall and the ground before it
    scene = SceneDescription(built.geometry, built.materials, built.lights, camera, built.object_names)
    view = (camera.view_matrix(), camera.projection_matrix())
    scene_gpu = SceneGPU(scene)
    near, totals, counts = {}, {}, {}
    try:
        receivers = view_receivers(scene_gpu, *view)
        centre = receivers["position"].mean(axis=0)
        for pdf in ("light", "view"):
            settings = VSGLSettings(vsgl_count=64, rsm_size=64, visibility=False, pdf=pdf)
            assert VSGLSettings().pdf == "view"
            table = _planned_vsgls(scene, scene_gpu, settings, view, receivers)
            assert np.all(np.isfinite(table["power"]))
            lum = table["power"] @ np.array([0.2126, 0.7152, 0.0722])
            close = np.linalg.norm(table["mean"] - centre, axis=1) < 3.0
            near[pdf] = lum[np.linalg.norm(table["mean"] - centre, axis=1) < 10.0].sum()
            totals[pdf] = lum.sum() / (table["rsm_total_power"][0] @ np.array([0.2126, 0.7152, 0.0722]))
            counts[pdf] = int(close.sum())
    finally:
        scene_gpu.free()
    assert counts["view"] > 2 * counts["light"]
    assert near["view"] == pytest.approx(near["light"], rel=0.10)
    assert totals["light"] == pytest.approx(1.0, rel=1e-4)
    assert 0.6 <= totals["view"] <= 1.0 + 1e-4


def test_only_the_sets_that_light_diffuse_lobes_follow_the_view_pdf():
    """renderer.SceneLights.build: the first set lights the diffuse lobes (and the specular ones no
    other set takes); "glossy", and "all" as the third set, light specular lobes only."""
    from vsgl_addon.pipeline import view_pdf_serves

    assert view_pdf_serves("all", ("all",))
    assert view_pdf_serves("diffuse", ("diffuse", "glossy"))
    assert not view_pdf_serves("glossy", ("diffuse", "glossy"))
    assert view_pdf_serves("diffuse", ("diffuse", "glossy", "all"))
    assert not view_pdf_serves("glossy", ("diffuse", "glossy", "all"))
    assert not view_pdf_serves("all", ("diffuse", "glossy", "all"))


@pytest.mark.gpu
def test_receivers_weigh_their_diffuse_reflectance_and_a_metal_none():
    from test_planner import _camera
    from test_proxies import grid, material, point_light, scene_of
    from vsgl_addon.passes.rsm import SceneGPU
    from vsgl_addon.pipeline import view_receivers

    floor = grid(2, 2, 8.0, 8.0, origin=(-4, -4, 0))
    wall = grid(2, 2, 8.0, 4.0, origin=(-4, 3, 0), u=(1, 0, 0), v=(0, 0, 1))
    mats = (material("Metal floor", 0.2, metallic=1.0, color=(0.9, 0.9, 0.9)),
            material("Wall", 0.7, metallic=0.0, color=(0.8, 0.2, 0.1)))
    scene = scene_of([(floor, 1, 0), (wall, 2, 1)], mats, [point_light((0.0, 0.0, 3.0), power=500.0)])
    camera = _camera()
    scene_gpu = SceneGPU(SceneDescription(scene.geometry, scene.materials, scene.lights, camera, scene.object_names))
    try:
        receivers = view_receivers(scene_gpu, camera.view_matrix(), camera.projection_matrix())
    finally:
        scene_gpu.free()
    on_floor = receivers["position"][:, 2] < 1e-3
    assert on_floor.any() and (~on_floor).any()
    assert np.all(receivers["weight"][on_floor] == 0.0)
    lum = np.array([0.2126, 0.7152, 0.0722]) @ [0.8, 0.2, 0.1]
    np.testing.assert_allclose(receivers["weight"][~on_floor], lum, rtol=1e-5)
