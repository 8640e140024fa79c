# SPDX-License-Identifier: GPL-3.0-or-later
"""The glossy VPLs made from the RSM on the GPU (passes/vpl_culling.py extract_view / extract_vpls,
glsl/vpl_culling/vpl_extract*.comp.glsl, glsl/lib/vpl_extraction.glsl) against the float64 twin
(reference/vpl_culling.py glossy_vpl_from_texel, extract_glossy_vpls): the same VPLs as a set and in
the reference's row-major order (so each keeps its xi), bit-identical on a second run (nothing
resampled), with no read-back or upload; extremes: no sharp texel, every texel sharp, a one-texel
RSM, sizes that are no multiple of a run, a table too small, a sun's directional w_i; and culling
from the GPU's set equals culling from the CPU's."""

from __future__ import annotations

import numpy as np
import pytest

from glsl_harness import Accuracy, as_gpu_floats, evaluate_glsl
from test_vpl_culling_pass_gpu import run_pass, wall_gbuffer
from test_vpl_render import SETTINGS, _scene
from vsgl_addon.passes import vpl_culling as pass_
from vsgl_addon.passes.gpu_util import RoundTrips, texture_from_array
from vsgl_addon.passes.scene_gpu import SceneGPU
from vsgl_addon.reference import vpl_culling as vc

pytestmark = pytest.mark.gpu
ALPHA_C = 0.1
POINT_LIGHT = np.array([0.3, -2.0, 2.5, 1.0])
SUN = np.array([0.0, 0.6, 0.8, 0.0])


def _rsm(rng, size, sharp_fraction=0.5, lit_fraction=0.8):
    """(position, normal, flux_specular) RSM slots (size, size, 4), float32-exact: roughness either
    side of the alpha_c boundary (never within float32 rounding of it), some texels unlit, fluxes
    from 1e-30 to 10."""
    shape = (size, size)
    position = np.concatenate([rng.normal(size=shape + (3,)), rng.uniform(0, 1, shape + (1,))], -1)
    normal = rng.normal(size=shape + (3,))
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    sharp = rng.uniform(size=shape) < sharp_fraction
    # alpha = roughness^2 < 0.1: roughness below 0.3162; rough texels from 0.33 on.
    roughness = np.where(sharp, rng.uniform(0.0, 0.31, shape), rng.uniform(0.33, 1.0, shape))
    flux = 10.0 ** rng.uniform(-30, 1, shape + (3,))
    flux[rng.uniform(size=shape) >= lit_fraction] = 0.0
    measure = rng.uniform(1e-5, 1e-3, shape + (1,))
    slots = (position, np.concatenate([normal, roughness[..., None]], -1), np.concatenate([flux, measure], -1))
    return tuple(as_gpu_floats(slot) for slot in slots)


def _extract(views, capacity=None, light=POINT_LIGHT):
    """extract_view of each view's slots into one set; the set's VPLs read back, and its count."""
    size_total = sum(view[0].shape[0] ** 2 for view in views)
    vpl_set = pass_.empty_vpl_set(size_total if capacity is None else capacity)
    try:
        for slots in views:
            textures = {name: texture_from_array(slot) for name, slot in zip(pass_.EXTRACTION_SLOTS, slots)}
            pass_.extract_view(vpl_set, textures, slots[0].shape[0], light, ALPHA_C)
        return pass_.read_vpls(vpl_set), vpl_set.count
    finally:
        vpl_set.free()


def _reference(views, light=POINT_LIGHT):
    parts = [vc.extract_glossy_vpls(*slots, light, ALPHA_C)[0] for slots in views]
    return np.concatenate(parts) if parts else np.zeros((0, 4, 4))


def _records(vpls) -> np.ndarray:
    """(K, 4, 4) records of a read-back VPL dict, as the table holds them (the VPL set's 16 floats)."""
    records = np.zeros((len(vpls["roughness"]), 4, 4))
    records[:, 0, :3], records[:, 0, 3] = vpls["position"], vpls["roughness"]
    records[:, 1, :3], records[:, 1, 3] = vpls["normal"], np.max(vpls["flux"], axis=-1)
    records[:, 2, :3], records[:, 3, :3] = vpls["incoming"], vpls["flux"]
    return records


def _assert_same_vpls(gpu, reference):
    """The same VPLs as a set (rows sorted by their 16 values, w_i within float32 rounding) and in
    the same order."""
    assert gpu.shape == reference.shape
    if len(reference) == 0:
        return
    flat_gpu, flat_ref = gpu.reshape(len(gpu), -1), reference.reshape(len(reference), -1)
    # Sorted by position, normal and flux (exact copies of the RSM's floats), not by the computed w_i.
    exact = [0, 1, 2, 4, 5, 6, 7, 12, 13, 14]
    order_gpu = np.lexsort(flat_gpu[:, exact].T[::-1])
    order_ref = np.lexsort(flat_ref[:, exact].T[::-1])
    for a, b in ((flat_gpu[order_gpu], flat_ref[order_ref]), (flat_gpu, flat_ref)):
        np.testing.assert_array_equal(a[:, exact], b[:, exact])
        np.testing.assert_allclose(a[:, 3], b[:, 3], rtol=1e-6)  # max(alpha, 1e-3) in float32
        np.testing.assert_allclose(a[:, 8:11], b[:, 8:11], atol=1e-6)  # unit w_i
    assert np.all(np.isfinite(gpu))


def test_texel_to_vpl_twin():
    """glossy_vpl_from_texel (GLSL) against its twin: the decision and the four records, for point and
    sun lights, roughness 0 ... 1, unlit texels and fluxes down to 1e-30, a light on the surface."""
    rng = np.random.default_rng(11)
    position, normal, flux = (slot.reshape(-1, 4) for slot in _rsm(rng, 64))
    n = len(position)
    light = np.where((np.arange(n) % 2 == 0)[:, None], POINT_LIGHT, SUN)
    light[0] = np.append(position[0, :3], 1.0)  # w_i undefined: the fallback axis, finite
    inputs = {"position": position, "normal": normal, "flux": flux, "light": as_gpu_floats(light)}
    body = """
    vec4 r0, r1, r2, r3;
    kept = glossy_vpl_from_texel(position, normal, flux, light, 0.1, r0, r1, r2, r3) ? 1.0 : 0.0;
    record0 = r0; record1 = r1; record2 = r2; record3 = r3;
    """
    out = evaluate_glsl(body, inputs, {"kept": 1, "record0": 4, "record1": 4, "record2": 4, "record3": 4},
                        libraries=["lib/vpl_extraction.glsl"])
    keep, records = vc.glossy_vpl_from_texel(position, normal, flux, light, ALPHA_C)
    np.testing.assert_array_equal(out["kept"] > 0.5, keep)
    assert 0 < keep.sum() < n
    for k in range(4):
        acc = Accuracy(out[f"record{k}"], records[:, k], relative=1e-6)
        assert acc.ok, f"record {k}: worst relative {acc.worst_relative:.3g}"
    np.testing.assert_allclose(np.linalg.norm(out["record2"][:, :3], axis=-1), 1.0, atol=1e-6)


@pytest.mark.parametrize("size", [1, 3, 16, 64, 100])
def test_extraction_equals_reference(size):
    """Sizes of one texel, under one run (16 texels), a run's multiple and neither."""
    rng = np.random.default_rng(size)
    views = [_rsm(rng, size)]
    gpu, count = _extract(views)
    reference = _reference(views)
    assert count == len(reference)
    _assert_same_vpls(_records(gpu), reference)


def test_views_append_in_order_and_extremes():
    """Three views into one set: all sharp, none sharp (count unchanged), a one-texel view (kept); the
    set is their concatenation in order. A sun's w_i is its direction everywhere."""
    rng = np.random.default_rng(3)
    views = [_rsm(rng, 32, sharp_fraction=1.0, lit_fraction=1.0), _rsm(rng, 32, sharp_fraction=0.0),
             _rsm(rng, 1, sharp_fraction=1.0, lit_fraction=1.0)]
    gpu, count = _extract(views)
    reference = _reference(views)
    assert count == 32 * 32 + 0 + 1 == len(reference)
    _assert_same_vpls(_records(gpu), reference)
    gpu, count = _extract(views[1:2])
    assert count == 0 and len(gpu["roughness"]) == 0
    gpu, count = _extract(views[:1], light=SUN)
    np.testing.assert_allclose(gpu["incoming"], np.broadcast_to(SUN[:3], gpu["incoming"].shape), atol=1e-7)


def test_a_full_table_keeps_its_first_vpls():
    """Room for 5 of 64 sharp texels: the first 5 in order, nothing written past the table."""
    from vsgl_addon.passes.gpu_util import read_texture

    rng = np.random.default_rng(5)
    views = [_rsm(rng, 8, sharp_fraction=1.0, lit_fraction=1.0)]
    gpu, count = _extract(views, capacity=5)
    assert count == 5
    _assert_same_vpls(_records(gpu), _reference(views)[:5])
    vpl_set = pass_.empty_vpl_set(5)
    try:
        vpl_set.table.clear(format="FLOAT", value=(0.0, 0.0, 0.0, 0.0))
        textures = {name: texture_from_array(slot) for name, slot in zip(pass_.EXTRACTION_SLOTS, views[0])}
        pass_.extract_view(vpl_set, textures, 8, POINT_LIGHT, ALPHA_C)
        table = read_texture(vpl_set.table, pass_.TABLE_WIDTH, 4)
    finally:
        vpl_set.free()
    assert np.all(table[:, :5, :3] != 0.0) and np.all(table[:, 5:] == 0.0)


def test_scene_vpls_on_the_gpu_equal_the_read_back_ones_with_no_round_trip():
    """extract_vpls of the caustic scene (a spot on a metal panel): scene_vpls' VPLs, in its order,
    bit-identical on a second extraction (the set is as stable as the RSM); making them reads nothing
    back and uploads only the RSM's per-view constants; the count is one 4-byte read, once."""
    description = _scene(panel_roughness=0.2)
    scene_gpu = SceneGPU(description)
    try:
        cpu = pass_.scene_vpls(scene_gpu, 32, ALPHA_C)
        read_backs, upload_bytes = RoundTrips.read_backs, RoundTrips.upload_bytes
        first = pass_.extract_vpls(scene_gpu, 32, ALPHA_C)
        second = pass_.extract_vpls(scene_gpu, 32, ALPHA_C)
        assert RoundTrips.read_backs == read_backs
        assert RoundTrips.upload_bytes - upload_bytes <= 2 * 1024
        assert first.count == len(cpu["roughness"]) > 50
        assert RoundTrips.read_backs == read_backs + 1 and first.count == len(cpu["roughness"])
        gpu = pass_.read_vpls(first)
        _assert_same_vpls(_records(gpu), _records(cpu))
        again = pass_.read_vpls(second)
        for key in gpu:
            np.testing.assert_array_equal(gpu[key], again[key])
        first.free()
        second.free()
    finally:
        scene_gpu.free()


def test_culling_reads_the_count_on_the_gpu():
    """The culled image of an extracted set equals that of the same VPLs uploaded, and a set of no
    VPLs (count 0 on the GPU, room for many) gives black."""
    rng = np.random.default_rng(9)
    position, normal, albedo, w2v, proj, _, _ = wall_gbuffer(48, 32)
    slots = list(_rsm(rng, 16, sharp_fraction=1.0, lit_fraction=1.0))
    # A panel at x = 1 facing the wall (x = 2) the camera sees, lit by a light between them: its
    # mirror directions reach the wall in view.
    slots[0][..., :3] = as_gpu_floats(np.stack([np.ones((16, 16)), 0.3 * rng.normal(size=(16, 16)),
                                                1.5 + 0.3 * rng.normal(size=(16, 16))], -1))
    slots[1][..., :3] = np.array([1.0, 0.0, 0.0])
    slots[2][..., :3] = as_gpu_floats(rng.uniform(1e-3, 2e-3, slots[2][..., :3].shape))
    light = np.array([1.6, 0.0, 1.5, 1.0])
    vpl_set = pass_.empty_vpl_set(16 * 16)
    empty = pass_.empty_vpl_set(1024)
    try:
        textures = {name: texture_from_array(slot) for name, slot in zip(pass_.EXTRACTION_SLOTS, slots)}
        pass_.extract_view(vpl_set, textures, 16, light, ALPHA_C)
        extracted, _, _ = run_pass(position, normal, albedo, vpl_set, w2v, proj, 1e-3)
        uploaded, _, _ = run_pass(position, normal, albedo, pass_.read_vpls(vpl_set), w2v, proj, 1e-3)
        black, _, _ = run_pass(position, normal, albedo, empty, w2v, proj, 1e-3)
    finally:
        vpl_set.free()
        empty.free()
    assert extracted[..., :3].max() > 0.0
    np.testing.assert_array_equal(extracted, uploaded)
    assert np.all(black == 0.0)
