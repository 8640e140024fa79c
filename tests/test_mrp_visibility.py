# SPDX-License-Identifier: GPL-3.0-or-later
"""MRP-ASG's proxy-to-receiver visibility (vsgl_addon/passes/mrp_visibility.py): the mirror view
sends every receiver along the ray through its specular peak (float64), and on llvmpipe an occluder
standing between a mirror-like floor and a glossy wall takes the floor's reflected light off exactly
the wall pixels whose peak-to-receiver segment it crosses (a CPU ray test), and off no other."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from vsgl_addon.passes.mrp_visibility import mirror_view
from vsgl_addon.reference.mrp_asg import mrp_peak_distant, mrp_peak_local


def _rect():
    return SimpleNamespace(center=np.array([0.5, -0.2, 0.3]), normal=np.array([0.0, 0.0, 1.0]),
                           axis_u=np.array([math.cos(0.3), math.sin(0.3), 0.0]),
                           axis_v=np.array([-math.sin(0.3), math.cos(0.3), 0.0]), half_u=2.0, half_v=1.0)


def _ndc(view, point):
    clip = view.view_projection @ np.r_[point, 1.0]
    return clip[:3] / clip[3], clip[3]


@pytest.mark.parametrize("kind", ["POINT", "SUN"])
def test_a_receiver_and_its_peak_fall_on_one_texel_ray(kind):
    rect = _rect()
    light = SimpleNamespace(type=kind, position=np.array([-1.0, 0.5, 3.0]),
                            direction=np.array([0.3, -0.2, -1.0]) / np.linalg.norm([0.3, -0.2, -1.0]))
    bounds = (np.array([-4.0, -4.0, 0.0]), np.array([4.0, 4.0, 4.0]))
    view = mirror_view(rect, light, bounds, margin=0.1)
    assert view is not None and view.perspective == (kind == "POINT")
    # The widened rectangle's corners are the frustum's edges.
    for a in (-1, 1):
        for b in (-1, 1):
            corner = rect.center + a * 2.1 * rect.axis_u + b * 1.1 * rect.axis_v
            ndc, _ = _ndc(view, corner)
            assert np.abs(ndc[:2]).max() == pytest.approx(1.0, abs=1e-9) and abs(ndc[2]) <= 1.0
    rng = np.random.default_rng(3)
    checked = 0
    for x in rng.uniform([-3, -3, 0.4], [3, 3, 3.5], (200, 3)):
        if kind == "POINT":
            peak, ok = mrp_peak_local(x, rect.center, rect.normal, light.position)
        else:
            peak, ok = mrp_peak_distant(x, rect.center, rect.normal, -light.direction)
        d = peak - rect.center
        if not ok or abs(d @ rect.axis_u) > 2.0 or abs(d @ rect.axis_v) > 1.0:
            continue
        ndc_x, w_x = _ndc(view, x)
        ndc_p, w_p = _ndc(view, peak)
        np.testing.assert_allclose(ndc_x[:2], ndc_p[:2], atol=1e-9)  # the same texel
        assert w_x > w_p > 0.0 if kind == "POINT" else ndc_x[2] > ndc_p[2]  # x beyond the peak
        assert np.abs(ndc_x).max() <= 1.0
        checked += 1
    assert checked > 20
    # A light behind the lit side has no mirror view.
    below = SimpleNamespace(type=kind, position=np.array([0.0, 0.0, -1.0]), direction=np.array([0.0, 0.0, 1.0]))
    assert mirror_view(rect, below, bounds) is None


def _segment_hits_box(a, b, lo, hi):
    """Whether the segments a -> b (rows) cross the axis-aligned box [lo, hi] (slab test)."""
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (lo - a) / d
        t1 = (hi - a) / d
    near = np.nanmax(np.where(d != 0, np.minimum(t0, t1), np.where((a >= lo) & (a <= hi), -np.inf, np.inf)), axis=1)
    far = np.nanmin(np.where(d != 0, np.maximum(t0, t1), np.where((a >= lo) & (a <= hi), np.inf, -np.inf)), axis=1)
    return (near <= far) & (far > 0.0) & (near < 1.0)


OCCLUDER = dict(center=(0.0, 1.4, 0.4), size=(0.8, 0.2, 0.8))


def occluded_wall_scene(with_occluder=True):
    """A mirror-like metal floor (roughness 0.1, GGX α 0.01) under a point light, a glossy metal wall
    (roughness 0.4, α 0.16: in MRP-ASG's receiver range) facing it, and a matte box standing between
    the floor's specular peaks and the wall. Also the validation suite's occluded_reflector scene."""
    import scene_builders as sb

    scene = sb.reset()
    sb.plane("Floor", size=6.0, subdivisions=2,
             material=sb.principled("Mirror", base_color=(0.9, 0.9, 0.9), roughness=0.1, metallic=1.0))
    sb.plane("Wall", size=(6.0, 3.0), location=(0.0, 2.0, 1.5), rotation=(math.pi / 2, 0.0, 0.0),
             material=sb.principled("Glossy wall", base_color=(0.9, 0.7, 0.4), roughness=0.4, metallic=1.0))
    if with_occluder:
        sb.box("Occluder", size=OCCLUDER["size"], location=OCCLUDER["center"],
               material=sb.principled("Matte", base_color=(0.2, 0.2, 0.2), roughness=0.9))
    sb.point_light(power=1500.0, location=(0.0, -2.0, 2.5))
    sb.camera(location=(2.5, -2.5, 1.6), look_at_point=(0.0, 2.0, 0.7))
    return scene


@pytest.mark.gpu
def test_an_occluder_between_proxy_and_receiver_shadows_exactly_its_segments():
    import scene_builders as sb
    from vsgl_addon.layouts import GBUFFER
    from vsgl_addon.passes import gbuffer as gbuffer_pass
    from vsgl_addon.renderer import FrameRenderer, SceneLights
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    description = extract_scene(sb.depsgraph(occluded_wall_scene()))
    settings = VSGLSettings(vsgl_count=16, rsm_size=128)
    width, height = 64, 48
    view, projection = description.camera.view_matrix(), description.camera.projection_matrix()
    renderer = FrameRenderer()
    lights = SceneLights.build(description, settings)
    try:
        assert len(lights.proxies) == 1 and lights.mirror_maps is not None and lights.mirror_maps.atlases
        shadowed = renderer.render_view(lights, settings, width, height, view, projection)
        gbuffer = gbuffer_pass.PASS.run(lights.scene_gpu, view, projection, (width, height))
        fields = GBUFFER.unpack_slots(gbuffer.to_numpy(), ["position", "coverage"])
        gbuffer.free()
        maps, lights.mirror_maps = lights.mirror_maps, None
        unshadowed = renderer.render_view(lights, settings, width, height, view, projection)
        lights.mirror_maps = maps
    finally:
        lights.free()
        renderer.free()
    assert "mrp_visibility" in shadowed.timings
    on = shadowed.indirect_glossy_reflectors.sum(axis=-1)
    off = unshadowed.indirect_glossy_reflectors.sum(axis=-1)
    assert np.isfinite(on).all() and (on <= off * (1 + 1e-5) + 1e-9).all()  # shadows only take light away
    position = fields["position"].astype(np.float64)
    wall = (fields["coverage"] > 0.5) & (np.abs(position[..., 1] - 2.0) < 1e-3) & (off > 1e-3 * off.max())
    x = position[wall]
    light = np.asarray(description.lights[0].position, np.float64)
    peaks = mrp_peak_local(x, np.zeros(3), np.array([0.0, 0.0, 1.0]), light)[0]
    lo = np.asarray(OCCLUDER["center"]) - 0.5 * np.asarray(OCCLUDER["size"])
    hi = np.asarray(OCCLUDER["center"]) + 0.5 * np.asarray(OCCLUDER["size"])
    blocked = _segment_hits_box(peaks, x, lo, hi)
    # Away from the shadow's edge (a texel or two of the mirror map): grow / shrink the box by 4 cm.
    surely = _segment_hits_box(peaks, x, lo + 0.04, hi - 0.04)
    surely_not = ~_segment_hits_box(peaks, x, lo - 0.04, hi + 0.04)
    assert surely.sum() > 30 and surely_not.sum() > 100, (surely.sum(), surely_not.sum(), blocked.sum())
    ratio = on[wall] / off[wall]
    assert np.all(ratio[surely] < 1e-3), np.sort(ratio[surely])[-5:]
    assert np.mean(ratio[surely_not] > 0.999) > 0.98, np.sort(ratio[surely_not])[:5]
