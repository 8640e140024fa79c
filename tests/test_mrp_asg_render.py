# SPDX-License-Identifier: GPL-3.0-or-later
"""MRP-ASG in the renderer: a polished metal floor lit by a spot becomes a proxy, the pass runs by
default, and the path partition of light-paths.md holds: the RSM of the glossy receivers' VSGLs has
no specular flux on the proxy (its diffuse flux and every other texel unchanged, so the cells sum to
the whole), and the VSGLs no longer carry the proxy's light to specular receivers."""

from __future__ import annotations

import numpy as np
import pytest

import scene_builders as sb
from vsgl_addon.passes import rsm
from vsgl_addon.passes.scene_gpu import SceneGPU
from vsgl_addon.renderer import FrameRenderer, scene_proxies
from vsgl_addon.scene import extract_scene
from vsgl_addon.settings import VSGLSettings

pytestmark = pytest.mark.gpu


def _scene(floor_roughness=0.2, floor_glossy_visible=True):
    scene = sb.reset()
    floor = sb.plane("Floor", size=6.0, subdivisions=4,
                     material=sb.principled("Metal", base_color=(0.9, 0.6, 0.3), roughness=floor_roughness,
                                            metallic=1.0))
    floor.visible_glossy = floor_glossy_visible
    sb.box("Box", size=(0.8, 0.8, 1.2), location=(0.0, 1.2, 0.6),
           material=sb.principled("Glossy", base_color=(0.2, 0.3, 0.8), roughness=0.45))
    sb.spot_light(power=2000.0, location=(-2.0, -1.5, 3.0), look_at_point=(0.0, 0.0, 0.0), spot_size=1.2)
    sb.camera(location=(3.0, -3.0, 2.0), look_at_point=(0.0, 0.5, 0.5))
    return extract_scene(sb.depsgraph(scene))


def test_floor_proxy_and_rsm_partition():
    description = _scene()
    settings = VSGLSettings(vsgl_count=16, rsm_size=32)
    proxies = scene_proxies(description, settings)
    assert len(proxies) == 1
    proxy = proxies[0][0]
    assert proxy.alpha == pytest.approx(0.04, rel=1e-5)
    assert sorted((proxy.half_u, proxy.half_v)) == pytest.approx([3.0, 3.0], rel=1e-5)
    np.testing.assert_allclose(proxy.normal, [0, 0, 1], atol=1e-6)
    scene_gpu = SceneGPU(description)
    try:
        parts = {}
        for lobe, with_proxies in (("all", False), ("glossy", True)):
            views = rsm.render_rsm_views(scene_gpu, 0, 32, lobe, [proxy] if with_proxies else ())
            parts[lobe] = [view.to_numpy() for view in views]
            for view in views:
                view.free()
    finally:
        scene_gpu.free()
    total_spec = on_floor_spec = 0.0
    for whole, glossy in zip(parts["all"], parts["glossy"]):
        on_floor = whole.coverage & (np.abs(whole.rsm.position[..., 2]) < 1e-4)
        assert on_floor.sum() > 50 and (whole.coverage & ~on_floor).sum() > 10
        np.testing.assert_array_equal(glossy.rsm.flux_diffuse, whole.rsm.flux_diffuse)
        assert np.all(glossy.rsm.flux_specular[on_floor] == 0.0)
        np.testing.assert_array_equal(glossy.rsm.flux_specular[~on_floor], whole.rsm.flux_specular[~on_floor])
        # The cells: (diffuse lobe) + (specular, on the proxy) + (specular, elsewhere) = the whole.
        cells = (glossy.rsm.flux_diffuse.sum() + whole.rsm.flux_specular[on_floor].sum()
                 + glossy.rsm.flux_specular[~on_floor].sum())
        assert cells == pytest.approx(whole.rsm.flux_diffuse.sum() + whole.rsm.flux_specular.sum(), rel=1e-6)
        total_spec += whole.rsm.flux_specular.sum()
        on_floor_spec += whole.rsm.flux_specular[on_floor].sum()
    assert on_floor_spec > 0.5 * total_spec  # the metal floor holds most of the specular flux


def test_render_with_and_without_glossy_reflectors(monkeypatch):
    from vsgl_addon import planner
    from vsgl_addon import renderer as renderer_module

    # The partition's exactness: MRP-ASG's glossy set with the N of the sets it is compared with
    # (planner.GLOSSY_SET_FACTOR gives it more VSGLs, another lattice, the same light).
    monkeypatch.setattr(planner, "GLOSSY_SET_FACTOR", 1)
    description = _scene()
    settings = VSGLSettings(vsgl_count=32, rsm_size=32)
    renderer = FrameRenderer()
    try:
        # No receiver in MRP-ASG's range: the VSGLs keep the proxies' light, as with it off.
        monkeypatch.setattr(renderer_module, "RECEIVER_ALPHA_RANGE", (2.0, 3.0))
        none_served = renderer.render(description, settings, 48, 36)
        # Every receiver served, to check the partition everywhere.
        monkeypatch.setattr(renderer_module, "RECEIVER_ALPHA_RANGE", (0.0, 1.0))
        on = renderer.render(description, settings, 48, 36)
        off = renderer.render(description, settings.overridden(glossy_reflectors=False), 48, 36)
        # The metal floor has no diffuse lobe: hidden from glossy rays, its reflector light is exactly
        # its specular flux gone from the glossy receivers' VSGLs (and it is no proxy then).
        hidden = renderer.render(_scene(floor_glossy_visible=False), settings, 48, 36)
    finally:
        renderer.free()
    assert on.counts["proxies"] == 1 and off.counts["proxies"] == 0
    assert "mrp_asg" in on.timings and "mrp_asg" in off.timings
    for frame in (on, off):
        for name in ("indirect_diffuse", "indirect_specular", "indirect_glossy_reflectors", "direct_diffuse"):
            assert np.isfinite(getattr(frame, name)).all()
    reflected = on.indirect_glossy_reflectors
    assert reflected.max() > 0.0 and (reflected >= 0.0).all()
    assert np.all(off.indirect_glossy_reflectors == 0.0)
    # The diffuse receivers' VSGLs are the same light either way.
    np.testing.assert_allclose(on.indirect_diffuse, off.indirect_diffuse, rtol=1e-4, atol=1e-6)
    # With MRP-ASG on, the VSGLs' specular term is that of a scene without the floor's specular light.
    assert hidden.counts["proxies"] == 0
    vsgl_specular_on = on.indirect_specular - reflected
    scale = max(float(hidden.indirect_specular.max()), 1e-30)
    np.testing.assert_allclose(vsgl_specular_on, hidden.indirect_specular, rtol=1e-4, atol=1e-5 * scale)
    assert not np.allclose(off.indirect_specular, hidden.indirect_specular, rtol=1e-2)
    assert np.all(none_served.indirect_glossy_reflectors == 0.0)
    np.testing.assert_allclose(none_served.indirect_specular, off.indirect_specular, rtol=1e-5, atol=1e-7)
