# SPDX-License-Identifier: GPL-3.0-or-later
"""Every one-bounce light path is counted exactly once among the frame's techniques
(../shared/reference/light-paths.md): on a scene whose glossy floor is a rectangle proxy and a
sharp reflector, beside a sharp non-proxy reflector, the renderer builds three VSGL sets, the
glossy VPLs and MRP-ASG; the RSM texels of each set, the VPL table and the proxies' cell are read
back and checked texel by texel against the whole RSM, the float64 brute force of one bounce
restricted to each cell sums to the whole, the techniques' inputs composed as the frame composes
them are the whole, and the frame's images are its passes' images composed so.
A second scene checks that no light whose texels the glossy receivers' set gives to MRP-ASG is left
out of MRP-ASG's lights (a narrow spot between the proxy test's sample points)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import scene_builders as sb
from vsgl_addon.passes.gpu_util import read_texture
from vsgl_addon.passes.vpl_culling import read_vpls
from vsgl_addon.reference.path_partition import (CELLS, brute_force_one_bounce, cell_fluxes, match_vpl_flux,
                                                 rsm_on_proxy, set_texels)
from vsgl_addon.reference.principled import principled_alpha
from vsgl_addon.renderer import RECEIVER_ALPHA_RANGE, FrameRenderer, SceneLights
from vsgl_addon.scene import extract_scene
from vsgl_addon.settings import VSGLSettings

pytestmark = pytest.mark.gpu

# Visibility off (the brute force has none), every VPL kept at δ's smallest with no filter: the
# frame's images are then its passes' inputs composed, nothing else.
SETTINGS = VSGLSettings(vsgl_count=32, rsm_size=32, visibility=False, delta=1e-6, vpl_filter_radius=0,
                        vpl_interleave="1")
WIDTH, HEIGHT = 48, 36


def _scene():
    scene = sb.reset()
    # The demo's case: a glossy dielectric floor, GGX α 0.04 < α_c: a proxy and a sharp reflector.
    sb.plane("Floor", size=6.0, subdivisions=4,
             material=sb.principled("Glossy red", base_color=(0.8, 0.1, 0.1), roughness=0.2))
    # A sharp reflector that is no proxy (smooth shaded: its normals are not its faces').
    sb.box("Gold", size=0.8, location=(-0.8, 0.6, 0.4), smooth=True,
           material=sb.principled("Gold", base_color=(1.0, 0.7, 0.3), roughness=0.25, metallic=1.0))
    # Receivers in MRP-ASG's range (α 0.2) and outside it (α 0.49).
    sb.box("Glossy", size=(0.8, 0.8, 1.2), location=(0.8, 1.0, 0.6),
           material=sb.principled("Glossy blue", base_color=(0.2, 0.3, 0.8), roughness=0.45))
    sb.plane("Wall", size=6.0, location=(0.0, 3.0, 3.0), rotation=(math.radians(90), 0.0, 0.0),
             material=sb.principled("Rough wall", base_color=(0.8, 0.8, 0.8), roughness=0.7))
    sb.spot_light(power=2000.0, location=(-2.0, -1.5, 3.0), look_at_point=(0.0, 0.5, 0.0), spot_size=1.4)
    sb.camera(location=(3.0, -4.0, 2.5), look_at_point=(0.0, 0.8, 0.7))
    return extract_scene(sb.depsgraph(scene))


def _receivers(lights, view_matrix, projection):
    """The frame's pixels as receivers: (covered (h, w) mask, position, normal, view, Rd, F0, GGX α)."""
    from vsgl_addon.passes.gbuffer import render_gbuffer
    from vsgl_addon.passes.shading_inputs import shading_gbuffer

    gbuffer = render_gbuffer(lights.scene_gpu, view_matrix, projection, (WIDTH, HEIGHT))
    try:
        inputs = shading_gbuffer(gbuffer)
        arrays = gbuffer.to_numpy()
        rd = read_texture(inputs.diffuse_reflectance, WIDTH, HEIGHT)[..., :3]
        f0 = read_texture(inputs.specular_f0, WIDTH, HEIGHT)[..., :3]
        camera = np.asarray(gbuffer.camera_vector, np.float64).reshape(-1)
    finally:
        gbuffer.free()
    covered = arrays["position"][..., 3] > 0.5
    position = arrays["position"][..., :3][covered].astype(np.float64)
    normal = arrays["normal"][..., :3][covered].astype(np.float64)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    alpha = arrays["normal"][..., 3][covered].astype(np.float64) ** 2
    view = camera[:3] - position
    view /= np.linalg.norm(view, axis=-1, keepdims=True)
    return covered, position, normal, view, rd[covered].astype(np.float64), f0[covered].astype(np.float64), alpha


def _relative(value, whole):
    return float(np.max(np.abs(value - whole))) / max(float(np.max(np.abs(whole))), 1e-30)


def test_every_path_counted_once():
    description = _scene()
    camera = description.camera
    view_matrix, projection = camera.view_matrix(), camera.projection_matrix()
    renderer = FrameRenderer()
    lights = SceneLights.build(description, SETTINGS, view=(view_matrix, projection))
    try:
        assert lights.plan.receiver_sets == ("diffuse", "glossy", "all")
        assert len(lights.proxies) == 1 and lights.vpls is not None
        frame = renderer.render_view(lights, SETTINGS, WIDTH, HEIGHT, view_matrix, projection)
        first_diffuse = renderer._shading.read()[0][..., :3]
        glossy_specular = renderer._glossy_shading.read()[1][..., :3]
        whole_specular = renderer._whole_shading.read()[1][..., :3]
        served = read_texture(renderer._mrp.texture, WIDTH, HEIGHT)[..., 3] > 0.0
        first, glossy, whole = (set_texels(s, description.lights)
                                for s in (lights.vsgls, lights.glossy_vsgls, lights.whole_vsgls))
        vpls = read_vpls(lights.vpls)
        receivers = _receivers(lights, view_matrix, projection)
    finally:
        lights.free()
        renderer.free()

    # Texels: the sets are the same views (same texels) and differ only where light-paths.md says.
    sharp = principled_alpha(whole["roughness"]) < SETTINGS.caustic_roughness
    proxy = rsm_on_proxy(whole["position"], whole["normal"], whole["roughness"], lights.proxies)
    lit = whole["flux_specular"].max(axis=-1) > 0.0
    assert (lit & sharp & proxy).sum() > 50 and (lit & sharp & ~proxy).sum() > 10 and (lit & ~sharp).sum() > 50
    for texels in (first, glossy):
        np.testing.assert_array_equal(texels["position"], whole["position"])
        np.testing.assert_array_equal(texels["flux_diffuse"], whole["flux_diffuse"])
    vpl_flux, unmatched = match_vpl_flux(whole, vpls["position"], vpls["flux"])
    assert unmatched == 0 and len(vpls["flux"]) == int((lit & sharp).sum())
    # Diffuse receivers: the first set's Φ Rs and the VPLs' are each texel's once.
    np.testing.assert_allclose(first["flux_specular"] + vpl_flux, whole["flux_specular"], rtol=1e-6, atol=0.0)
    assert np.all(first["flux_specular"][sharp] == 0.0) and np.all(vpl_flux[~sharp] == 0.0)
    # Glossy receivers MRP-ASG serves: the glossy set's Φ Rs and the proxy cell's.
    cells = cell_fluxes(whole, lights.proxies, SETTINGS.caustic_roughness)
    np.testing.assert_array_equal(glossy["flux_specular"] + cells[CELLS[2]][1], whole["flux_specular"])

    # Cells: the brute force restricted to each sums to the unrestricted one.
    covered, *points = receivers
    pixel_served = served[covered]
    assert 20 < pixel_served.sum() < len(pixel_served) - 20
    brute = {name: brute_force_one_bounce(whole, *flux, *points) for name, flux in cells.items()}
    whole_d, whole_s = brute_force_one_bounce(whole, whole["flux_diffuse"], whole["flux_specular"], *points)
    np.testing.assert_allclose(sum(b[0] for b in brute.values()), whole_d, rtol=1e-9, atol=1e-12 * whole_d.max())
    np.testing.assert_allclose(sum(b[1] for b in brute.values()), whole_s, rtol=1e-9, atol=1e-12 * whole_s.max())
    # The techniques' inputs, composed as the frame composes them, are the whole once.
    zero = np.zeros_like(vpl_flux)
    composed_d = (brute_force_one_bounce(whole, first["flux_diffuse"], first["flux_specular"], *points)[0]
                  + brute_force_one_bounce(whole, zero, vpl_flux, *points)[0])
    glossy_s = brute_force_one_bounce(whole, glossy["flux_diffuse"], glossy["flux_specular"], *points)[1]
    composed_s = np.where(pixel_served[:, None], glossy_s + brute[CELLS[2]][1], whole_s)
    assert _relative(composed_d, whole_d) < 1e-5 and _relative(composed_s, whole_s) < 1e-5
    assert brute[CELLS[2]][1][pixel_served].sum() > 0.05 * whole_s[pixel_served].sum()

    # The frame's images are the passes' images composed so: MRP-ASG only where it serves, there
    # over the glossy set (no proxy flux), the whole set elsewhere; the VPLs over the first set.
    alpha = np.zeros((HEIGHT, WIDTH))
    alpha[covered] = points[-1]
    in_range = covered & (alpha >= RECEIVER_ALPHA_RANGE[0]) & (alpha <= RECEIVER_ALPHA_RANGE[1])
    np.testing.assert_array_equal(served, in_range)
    reflectors = frame.indirect_glossy_reflectors
    assert np.all(reflectors[~served] == 0.0)
    expected_s = np.where(served[..., None], glossy_specular + reflectors, whole_specular)
    np.testing.assert_allclose(frame.indirect_specular, expected_s, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(frame.indirect_diffuse, first_diffuse + frame.indirect_caustics, rtol=1e-5, atol=1e-8)


def test_a_light_between_the_proxy_samples_stays_in_mrp_asg():
    """The glossy set gives MRP-ASG every light's texels on a proxy; a narrow spot that lights the
    floor between the points the proxy test samples must still be one of MRP-ASG's lights, or its
    reflection off the floor would be in neither."""
    scene = sb.reset()
    sb.plane("Floor", size=20.0, subdivisions=4,
             material=sb.principled("Metal", base_color=(0.9, 0.6, 0.3), roughness=0.2, metallic=1.0))
    sb.box("Box", size=(0.8, 0.8, 1.2), location=(0.0, 6.0, 0.6),
           material=sb.principled("Glossy", base_color=(0.2, 0.3, 0.8), roughness=0.45))
    sb.spot_light(name="Wide", power=2000.0, location=(0.0, 0.0, 4.0), look_at_point=(0.0, 0.0, 0.0),
                  spot_size=1.0)
    # Between the 5 x 5 sample points (±8, ±4, 0 m): a 0.5 m wide pool of light at (6, 2).
    sb.spot_light(name="Narrow", power=500.0, location=(6.0, 2.0, 3.0), look_at_point=(6.0, 2.0, 0.0),
                  spot_size=math.radians(8.0))
    sb.camera(location=(6.0, -6.0, 4.0), look_at_point=(3.0, 3.0, 0.5))
    description = extract_scene(sb.depsgraph(scene))
    narrow = [light.name for light in description.lights].index("Narrow")
    lights = SceneLights.build(description, SETTINGS.overridden(caustics=False))
    try:
        glossy, whole = (set_texels(s, description.lights) for s in (lights.glossy_vsgls, lights.whole_vsgls
                                                                   if lights.whole_vsgls is not None else lights.vsgls))
        proxies = lights.proxies
    finally:
        lights.free()
    assert proxies
    lit = whole["flux_specular"].max(axis=-1) > 0.0
    on_floor = rsm_on_proxy(whole["position"], whole["normal"], whole["roughness"], proxies)
    assert (lit & on_floor & (whole["light"] == narrow)).sum() > 3  # the narrow spot's pool is on the floor
    cut = lit & (glossy["flux_specular"].max(axis=-1) == 0.0)
    assert cut.sum() > 50
    cells = cell_fluxes(whole, proxies, SETTINGS.caustic_roughness)
    np.testing.assert_array_equal(glossy["flux_specular"] + cells[CELLS[2]][1], whole["flux_specular"])
    for light_index in np.unique(whole["light"][cut]):
        on = cut & (whole["light"] == light_index)
        carried = np.zeros(len(on), bool)
        for proxy, mask in proxies:
            if mask[light_index]:
                carried |= rsm_on_proxy(whole["position"], whole["normal"], whole["roughness"], [proxy])
        assert np.all(carried[on]), f"light {description.lights[light_index].name}: {int((on & ~carried).sum())} texels dropped"
