# SPDX-License-Identifier: GPL-3.0-or-later
"""The view PDF on the GPU (vsgl_addon/passes/brsm.py, glsl/lib/brsm.glsl) against its float64
reference (vsgl_addon/reference/brsm.py, itself tested against a double loop in
test_reference_brsm.py), at the extremes, and in the pipeline against the reference evaluated on
the same RSM view.

Tolerance: I(y) sums up to 256 terms, each a few float32 roundings (2^-24 relative), and the two
normalizers sum 16384 texels in a strided-then-tree order; p = (1 - β) wI/ΣwI + β w/Σw inherits
them: |Δp| <= 1e-4 p + 1e-6 max p (measured: see the assertions' messages on failure).
"""

from __future__ import annotations

import numpy as np
import pytest

from vsgl_addon.layouts import RSM
from vsgl_addon.reference import brsm

pytestmark = pytest.mark.gpu

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


def _random_rsm(rng, size: int, covered: float = 0.8, lit: float = 0.7) -> dict:
    position = rng.normal(size=(size, size, 3)) * [2.0, 2.0, 0.3]
    normal = rng.normal(size=(size, size, 3)) + [0.0, 0.0, 2.0]
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    on = rng.random((size, size)) < lit
    flux_diffuse = rng.random((size, size, 3)) * on[..., None]
    flux_specular = rng.random((size, size, 3)) * on[..., None] * 0.3
    coverage = (rng.random((size, size)) < covered).astype(np.float64)
    return {"position": position, "normal": normal, "flux_diffuse": flux_diffuse,
            "flux_specular": flux_specular, "coverage": coverage,
            "specular_axis": normal, "specular_sharpness": np.full((size, size), 10.0)}


def _receivers(rng, count: int, radius: float = 0.1) -> dict:
    position = rng.normal(size=(count, 3)) * [2.0, 2.0, 0.5] + [0.0, 0.0, 3.0]
    normal = rng.normal(size=(count, 3)) - [0.0, 0.0, 2.0]
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    return {"position": position, "normal": normal, "weight": rng.random(count), "radius": radius}


def _reference(fields: dict, receivers: dict, defensive=None) -> np.ndarray:
    weight = (np.asarray(fields["flux_diffuse"]) + np.asarray(fields["flux_specular"])) @ LUMINANCE
    importance = brsm.view_importance(fields["position"], fields["normal"], receivers["position"],
                                      receivers["normal"], receivers["weight"], receivers["radius"])
    return brsm.view_pdf(np.where(np.asarray(fields["coverage"]) > 0.5, weight, 0.0), importance, defensive)


def _gpu(fields: dict, receivers: dict, defensive=None) -> np.ndarray:
    from vsgl_addon.passes import brsm as brsm_pass
    from vsgl_addon.passes.gpu_util import read_texture, texture_from_array
    from vsgl_addon.passes.vsgl_generation import RSMTextures

    size = np.shape(fields["coverage"])[0]
    with np.errstate(over="ignore", invalid="ignore"):
        texels = RSM.pack_slots(fields, (size, size))
    textures = RSMTextures(size=size, **{name: texture_from_array(texels[name]) for name in RSM.slot_names})
    uploaded = brsm_pass.upload_receivers(receivers)
    try:
        pdf = brsm_pass.run(textures, uploaded, defensive)
        return read_texture(pdf, size, size)[..., 0].astype(np.float64)
    finally:
        uploaded.free()


def _assert_close(gpu, reference, what: str):
    assert np.all(np.isfinite(gpu)), what
    scale = max(float(np.max(reference)), 1e-300)
    error = np.abs(gpu - reference)
    assert np.all(error <= 1e-4 * reference + 1e-6 * scale), \
        f"{what}: worst |Δp| {error.max():.3e} (max p {scale:.3e}, relative {np.max(error / np.maximum(reference, 1e-300)):.3e})"


@pytest.mark.parametrize("size, receivers", [(1, 1), (16, 7), (64, 256), (128, 256)])
def test_view_pdf_matches_the_reference(size, receivers):
    rng = np.random.default_rng(size + receivers)
    fields = _random_rsm(rng, size, covered=1.0 if size == 1 else 0.8, lit=1.0 if size == 1 else 0.7)
    chosen = _receivers(rng, receivers)
    reference = _reference(fields, chosen)
    gpu = _gpu(fields, chosen)
    _assert_close(gpu, reference, f"{size}² RSM, {receivers} receivers")
    if reference.sum() > 0.0:
        assert gpu.sum() == pytest.approx(1.0, rel=1e-4)


def test_the_defensive_share_is_read_when_called(monkeypatch):
    """The reference's DEFENSIVE_SHARE at the time of the call (benchmarks/view_pdf.py's sweep sets it)."""
    rng = np.random.default_rng(13)
    fields, chosen = _random_rsm(rng, 16), _receivers(rng, 32)
    monkeypatch.setattr(brsm, "DEFENSIVE_SHARE", 0.9)
    _assert_close(_gpu(fields, chosen), _reference(fields, chosen, 0.9), "β = 0.9 by the module's share")


@pytest.mark.parametrize("defensive", [0.0, 0.25, 1.0])
def test_every_defensive_share(defensive):
    rng = np.random.default_rng(11)
    fields, chosen = _random_rsm(rng, 32), _receivers(rng, 64)
    gpu = _gpu(fields, chosen, defensive)
    _assert_close(gpu, _reference(fields, chosen, defensive), f"β = {defensive}")
    if defensive == 1.0:  # the light PDF itself
        weight = np.where(fields["coverage"] > 0.5, (fields["flux_diffuse"] + fields["flux_specular"]) @ LUMINANCE, 0)
        np.testing.assert_allclose(gpu, weight / weight.sum(), rtol=1e-4, atol=1e-9)


def test_extremes_stay_finite_and_fall_back_as_the_reference_does():
    rng = np.random.default_rng(17)
    fields = _random_rsm(rng, 16)
    weight = np.where(fields["coverage"] > 0.5, (fields["flux_diffuse"] + fields["flux_specular"]) @ LUMINANCE, 0)
    light = weight / weight.sum()
    # No receivers: nothing in view, the light PDF.
    none = {"position": np.zeros((0, 3)), "normal": np.zeros((0, 3)), "weight": np.zeros(0), "radius": 0.1}
    np.testing.assert_allclose(_gpu(fields, none), light, rtol=1e-5, atol=1e-12)
    # Receivers that all face away from every texel: the light PDF.
    away = _receivers(rng, 32)  # above every texel (z >= 1.5 against |z| of a few 0.3), facing up
    away["position"][:, 2] = np.maximum(away["position"][:, 2], 1.5)
    away["normal"] = np.tile([0.0, 0.0, 1.0], (32, 1))
    np.testing.assert_allclose(_gpu(fields, away), light, rtol=1e-5, atol=1e-12)
    # Nothing lit: zeros.
    dark = dict(fields, flux_diffuse=np.zeros((16, 16, 3)), flux_specular=np.zeros((16, 16, 3)))
    assert not np.any(_gpu(dark, _receivers(rng, 8)))
    # A receiver on a texel, a zero pole radius, texels without geometry at infinity, huge and tiny
    # distances: finite, and the reference's values.
    chosen = _receivers(rng, 16, radius=0.0)
    chosen["position"][0] = fields["position"][3, 4]
    odd = dict(fields)
    odd["position"] = fields["position"].copy()
    odd["position"][fields["coverage"] < 0.5] = np.inf
    odd["position"][0, 0] = [1e4, -1e4, 0.0]
    odd["coverage"] = fields["coverage"].copy()
    odd["coverage"][0, 0] = 1.0
    for case, (rsm, receivers) in {"on a texel, r = 0": (fields, chosen), "far and unbounded": (odd, chosen),
                                   "tiny radius": (fields, dict(chosen, radius=1e-20))}.items():
        gpu = _gpu(rsm, receivers)
        reference = _reference({**rsm, "position": np.where(np.isfinite(rsm["position"]), rsm["position"], 0.0)},
                               receivers)
        _assert_close(gpu, reference, case)


def test_the_pipeline_view_pdf_is_the_reference_on_a_real_view():
    """pipeline._view_pdf_texture on a room's RSM views (the GPU pass) against the reference evaluated
    on the same views read back."""
    from test_planner import _camera, _room
    from test_proxies import point_light
    from vsgl_addon.passes import brsm as brsm_pass
    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.passes.rsm import SceneGPU, render_rsm_views
    from vsgl_addon.pipeline import _view_pdf_texture, view_receivers
    from vsgl_addon.scene_description import SceneDescription

    room = _room([point_light((0.0, 0.0, 3.5), power=800.0)])
    camera = _camera(position=(2.5, -1.0, 0.6), looking=(1.0, 0.3, -0.4))
    scene = SceneDescription(room.geometry, room.materials, room.lights, camera, room.object_names)
    scene_gpu = SceneGPU(scene)
    views = []
    try:
        receivers = view_receivers(scene_gpu, camera.view_matrix(), camera.projection_matrix())
        uploaded = brsm_pass.upload_receivers(receivers)
        views = render_rsm_views(scene_gpu, 0, 64)
        assert len(views) > 1
        for view in views:
            arrays = view.to_numpy()
            fields = {"position": arrays.rsm.position, "normal": arrays.rsm.normal,
                      "flux_diffuse": arrays.rsm.flux_diffuse, "flux_specular": arrays.rsm.flux_specular,
                      "coverage": arrays.coverage.astype(np.float64)}
            gpu = read_texture(_view_pdf_texture(view, uploaded), 64, 64)[..., 0].astype(np.float64)
            _assert_close(gpu, _reference(fields, receivers), "room view")
        uploaded.free()
    finally:
        for view in views:
            view.free()
        scene_gpu.free()
