# SPDX-License-Identifier: GPL-3.0-or-later
"""The glossy VPL pass (004) in the renderer: it runs only where a lit sharp reflector exists
(light_paths.needs_glossy_vpls, which costs nothing elsewhere: no VPLs, no extra VSGL set), the RSM
split of light-paths.md (the diffuse receivers' VSGLs lose exactly the sharp texels' specular flux,
which the VPLs carry, so no caustic is counted twice), the caustic scene's frame against its cached
Cycles truth, and the extremes (δ at both ends, a one-texel RSM)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import scene_builders as sb
from vsgl_addon import light_paths
from vsgl_addon.passes import rsm, vpl_culling
from vsgl_addon.passes.scene_gpu import SceneGPU
from vsgl_addon.reference.principled import principled_alpha
from vsgl_addon.renderer import FrameRenderer, SceneLights
from vsgl_addon.scene import extract_scene
from vsgl_addon.settings import VSGLSettings

REPO = Path(__file__).resolve().parents[1]
SETTINGS = VSGLSettings(vsgl_count=16, rsm_size=32, ism_points=1024, ism_size=16)


def _scene(panel_roughness=0.2, panel_diffuse_visible=True, wall_roughness=0.8, aim=(0.0, 0.0, 0.0),
           occluder=False):
    """A spot on a small metal panel (α = roughness²) in front of a matte wall, a matte floor; the
    occluder stands in the panel's mirror path (benchmarks/vpl_visibility.py's scene)."""
    scene = sb.reset()
    sb.plane("Floor", size=6.0, material=sb.principled("Floor", base_color=(0.3, 0.3, 0.3), roughness=0.8),
             location=(0.0, 0.0, -0.5))
    sb.plane("Wall", size=6.0, material=sb.principled("Wall", base_color=(0.8, 0.8, 0.8), roughness=wall_roughness),
             location=(0.0, 2.0, 1.0), rotation=(np.radians(90.0), 0.0, 0.0))
    panel = sb.plane("Panel", size=1.0, material=sb.principled("Steel", base_color=(0.6, 0.6, 0.6),
                                                               roughness=panel_roughness, metallic=1.0),
                     rotation=(np.radians(-30.0), 0.0, 0.0))
    panel.visible_diffuse = panel_diffuse_visible
    if occluder:
        sb.box("Occluder", size=(0.35, 0.1, 0.3), location=(0.2, 1.0, -0.2),
               material=sb.principled("Occluder", base_color=(0.5, 0.5, 0.5), roughness=0.8))
    sb.spot_light(power=1500.0, location=(0.0, -2.0, 2.0), look_at_point=aim, spot_size=0.5)
    sb.camera(location=(2.5, -3.5, 1.5), look_at_point=(0.0, 1.0, 0.5))
    return extract_scene(sb.depsgraph(scene))


def test_the_pass_is_needed_only_for_a_lit_sharp_reflector():
    settings = VSGLSettings()
    assert light_paths.needs_glossy_vpls(_scene(), settings)
    assert not light_paths.needs_glossy_vpls(_scene(), settings.overridden(caustics=False))
    assert not light_paths.needs_glossy_vpls(_scene(panel_roughness=0.5), settings)  # α 0.25 ≥ α_c 0.1
    assert light_paths.needs_glossy_vpls(_scene(panel_roughness=0.5), settings.overridden(caustic_roughness=0.3))
    assert not light_paths.needs_glossy_vpls(_scene(panel_diffuse_visible=False), settings)
    # The spot aimed away from the panel (its cone misses it): nothing to render.
    assert not light_paths.needs_glossy_vpls(_scene(aim=(0.0, -2.0, 5.0)), settings)


@pytest.mark.gpu
def test_no_sharp_reflector_runs_nothing(monkeypatch):
    """Rough panel: no VPLs, no extra VSGL set, and the VPL pass is never called."""
    description = _scene(panel_roughness=0.6)

    def forbidden(*args, **kwargs):
        raise AssertionError("the VPL pass ran")

    monkeypatch.setattr(vpl_culling, "run", forbidden)
    lights = SceneLights.build(description, SETTINGS)
    try:
        assert lights.vpls is None and lights.glossy_vsgls is None and lights.whole_vsgls is None
    finally:
        lights.free()
    frame = sb.render_frame(description, SETTINGS, 32, 24)
    assert frame.counts["vpls"] == 0 and frame.timings["vpl_culling"] == 0.0
    assert np.all(frame.indirect_caustics == 0.0)


@pytest.mark.gpu
def test_rsm_split_gives_the_sharp_specular_flux_to_the_vpls_alone():
    """light-paths.md: per texel, the diffuse receivers' RSM (sharp_alpha = α_c) keeps every diffuse
    flux and every non-sharp specular flux; the sharp texels' specular flux is exactly the VPLs'. The
    cells sum to the whole RSM, so shading (linear in the flux) counts each path once."""
    description = _scene()
    alpha_c = SETTINGS.caustic_roughness
    scene_gpu = SceneGPU(description)
    try:
        parts = {}
        for name, cut in (("whole", 0.0), ("cut", alpha_c)):
            views = rsm.render_rsm_views(scene_gpu, 0, 32, "diffuse", (), cut)
            parts[name] = [view.to_numpy() for view in views]
            for view in views:
                view.free()
        vpls = vpl_culling.scene_vpls(scene_gpu, 32, alpha_c)
    finally:
        scene_gpu.free()
    vpl_flux = np.zeros(3)
    whole_specular = cut_specular = 0.0
    for whole, cut in zip(parts["whole"], parts["cut"]):
        sharp = principled_alpha(whole.roughness) < alpha_c
        assert (sharp & whole.coverage).sum() > 20 and (~sharp & whole.coverage).sum() > 20
        np.testing.assert_array_equal(cut.rsm.flux_diffuse, whole.rsm.flux_diffuse)
        assert np.all(cut.rsm.flux_specular[sharp] == 0.0)
        np.testing.assert_array_equal(cut.rsm.flux_specular[~sharp], whole.rsm.flux_specular[~sharp])
        vpl_flux += whole.rsm.flux_specular[sharp].reshape(-1, 3).sum(axis=0)
        whole_specular += whole.rsm.flux_specular.sum()
        cut_specular += cut.rsm.flux_specular.sum()
    np.testing.assert_allclose(vpls["flux"].sum(axis=0), vpl_flux, rtol=1e-9)
    assert cut_specular + vpl_flux.sum() == pytest.approx(whole_specular, rel=1e-6)
    assert vpl_flux.sum() > 0.5 * whole_specular  # the panel holds most of the specular flux
    assert np.all(vpls["roughness"] >= vpl_culling.VPL_ALPHA_MIN)


@pytest.mark.gpu
def test_caustic_scene_frame_gets_the_caustic_once():
    """caustic_panel (the suite's scene and its cached Cycles truth): with the pass on, the caustic
    region's mean (Cycles' brightest 2 %) comes within 20 % of Cycles' and the whole image's error
    falls below the VSGLs'; off, the Indirect Caustics pass is black. Unshadowed VPLs here: the
    scene has no occluder between panel and wall."""
    import bpy

    from vsgl_addon import register, unregister

    register()
    try:
        bpy.ops.wm.open_mainfile(filepath=str(REPO / "benchmarks" / "scenes" / "caustic_panel.blend"), load_ui=False)
        settings = VSGLSettings.from_properties(bpy.context.scene.vsgl).overridden(vsgl_count=128)
        description = extract_scene(bpy.context.evaluated_depsgraph_get())
    finally:
        unregister()
    # The cached truth stores Cycles' rows top-down; the passes' row 0 is the bottom.
    truth = {key: value[::-1] for key, value in np.load(REPO / "benchmarks" / "reference"
                                                          / "caustic_panel_indirect_240x180.npz").items()
             if key in ("diffuse_a", "diffuse_b", "glossy_a", "glossy_b", "alpha")}
    target = (truth["diffuse_a"].astype(np.float64) + truth["diffuse_b"] + truth["glossy_a"] + truth["glossy_b"]) / 2
    renderer = FrameRenderer()
    try:
        on = renderer.render(description, settings, 240, 180)
        off = renderer.render(description, settings.overridden(caustics=False), 240, 180)
    finally:
        renderer.free()
    sb.assert_finite_frame(on, "caustics on")
    mask = (on.coverage > 0.5) & (truth["alpha"] > 0.5)
    luminance = target[mask].mean(axis=-1)
    region = np.zeros_like(mask)
    region[mask] = luminance >= np.quantile(luminance, 0.98)
    assert on.counts["vpls"] > 1000 and on.counts["vpls_per_pixel"] > 0.0 and on.timings["vpl_culling"] > 0.0
    assert np.all(off.indirect_caustics == 0.0) and off.counts["vpls"] == 0
    assert on.indirect_caustics[region].mean() > 0.5 * on.indirect_diffuse[region].mean()
    assert np.all(on.indirect_diffuse >= on.indirect_caustics - 1e-6)
    ratio = on.indirect[region].mean() / target[region].mean()
    assert 0.8 <= ratio <= 1.2, ratio

    def rel(image):
        return np.sqrt(np.mean((image[mask] - target[mask]) ** 2)) / target[mask].mean()

    assert rel(on.indirect) < rel(off.indirect)


@pytest.mark.gpu
@pytest.mark.parametrize("extreme", [dict(delta=1e-6), dict(delta=1e-1, vpl_interleave="8", vpl_samples=2),
                                     dict(rsm_size=1), dict(vpl_filter_radius=0, vpl_interleave="2")])
def test_extremes_stay_finite(extreme):
    description = _scene(panel_roughness=0.05)
    frame = sb.render_frame(description, SETTINGS.overridden(**extreme), 40, 30)
    sb.assert_finite_frame(frame, str(extreme))
    if extreme.get("rsm_size") != 1:
        assert frame.counts["vpls"] > 0 and frame.indirect_caustics.max() > 0.0


@pytest.mark.gpu
def test_a_band_differs_from_the_whole_image_only_within_the_filter_radius():
    """The viewport and overlay render in bands of rows: the VPL image of a band equals the whole
    image's rows (culling and ξ do not depend on the band), except that the cross-bilateral filter
    sees only the band's rows, within its radius of the band's edge."""
    from vsgl_addon.views import band_projection

    description = _scene(panel_roughness=0.05)
    view, projection = description.camera.view_matrix(), description.camera.projection_matrix()
    settings = SETTINGS.overridden(vpl_filter_radius=4)
    renderer = FrameRenderer()
    lights = SceneLights.build(description, settings)
    try:
        whole = renderer.render_view(lights, settings, 48, 40, view, projection)
        band = renderer.render_view(lights, settings, 48, 20, view, band_projection(projection, 0, 20, 40))
    finally:
        lights.free()
        renderer.free()
    inner = slice(0, 20 - settings.vpl_filter_radius)
    assert whole.indirect_caustics[:20].max() > 0.0
    np.testing.assert_allclose(band.indirect_caustics[inner], whole.indirect_caustics[inner], rtol=2e-3, atol=1e-6)


@pytest.mark.gpu
def test_vpl_light_is_shadowed():
    """With visibility on, the VPLs' clusters' shadow maps take the occluder's shadow out of the
    caustic (benchmarks/vpl_visibility.py measures it against ray casting: 17 % of the light); without
    an occluder they keep nearly all of it."""
    settings = SETTINGS.overridden(ism_size=64, ism_points=4096, vpl_filter_radius=0, vpl_visibility=True)
    lit = {}
    for occluder in (False, True):
        description = _scene(occluder=occluder)
        for visibility in (False, True):
            frame = sb.render_frame(description, settings.overridden(visibility=visibility), 64, 48)
            sb.assert_finite_frame(frame)
            lit[occluder, visibility] = float(frame.indirect_caustics.sum())
    assert lit[False, True] > 0.85 * lit[False, False]
    assert lit[True, True] < 0.93 * lit[True, False]


@pytest.mark.gpu
def test_shadowed_pass_equals_the_reference_lookup_of_its_own_maps():
    """Brute force (δ = 0, every VPL) with visibility: each VPL's light on each pixel weighted by
    reference.ism.ism_pcf_bilinear of its cluster's map (read back), at its cluster's origin. The
    panel fills 8 blocks of a 64² RSM: 8 maps, so a map looked up at another map's origin shows."""
    from vsgl_addon.passes.gbuffer import render_gbuffer
    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.passes.shading_inputs import shading_gbuffer
    from vsgl_addon.reference import ism as reference_ism
    from vsgl_addon.reference import vpl_culling as reference

    description = _scene(occluder=True)
    settings = SETTINGS.overridden(rsm_size=64, ism_size=32, ism_points=4096)
    width, height = 32, 24
    scene_gpu = SceneGPU(description)
    camera = description.camera
    gbuffer = render_gbuffer(scene_gpu, camera.view_matrix(), camera.projection_matrix(), (width, height))
    inputs = shading_gbuffer(gbuffer)
    vpls = vpl_culling.scene_vpls(scene_gpu, settings.rsm_size, settings.caustic_roughness)
    visible = vpl_culling.upload_visible_vpls(vpls, scene_gpu, settings, settings.rsm_size)
    try:
        result = vpl_culling.run(inputs.position, inputs.normal, inputs.diffuse_reflectance, visible,
                                 camera.view_matrix(), camera.projection_matrix(), 0.0)
        image = result.read()[..., :3].astype(np.float64)
        result.free()
        maps = visible.isms.read()
        position = read_texture(inputs.position, width, height).astype(np.float64)
        normal = read_texture(inputs.normal, width, height)[..., :3].astype(np.float64)
        albedo = read_texture(inputs.diffuse_reflectance, width, height)[..., :3].astype(np.float64)
    finally:
        visible.free()
        gbuffer.free()
        scene_gpu.free()
    cluster, origins = vpl_culling.vpl_clusters(vpls, settings.rsm_size)[:2]
    assert len(origins) > 4
    covered = position[..., 3] > 0.0
    receivers, normals = position[..., :3][covered], normal[covered]
    visibility = [reference_ism.ism_pcf_bilinear(np.where(np.isfinite(m), m, 1e30), o, receivers, normals)
                  for m, o in zip(maps, origins)]
    expected = np.zeros_like(receivers)
    for k in range(len(vpls["roughness"])):
        radiance, _, _ = reference.glossy_vpl_radiance(
            receivers, normals, albedo[covered], vpls["position"][k], vpls["normal"][k], vpls["incoming"][k],
            vpls["roughness"][k], vpls["flux"][k], vpls["rs"][k])
        expected += radiance * visibility[cluster[k]][:, None]
    assert expected.max() > 0.0 and np.isfinite(image).all()
    # Receivers within float32 rounding of a texel's depth test may flip; the sums stay together.
    np.testing.assert_allclose(image[covered].sum(), expected.sum(), rtol=1e-3)
    np.testing.assert_allclose(image[covered], expected, rtol=2e-2, atol=1e-3 * expected.max())


def _flat_cluster(rng, normal, count=64, spread=0.05):
    """``count`` VPLs on a plane through (0.3, -0.2, 0.5) with unit ``normal``, ``spread`` m across."""
    normal = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    tangent = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    tangent /= np.linalg.norm(tangent)
    uv = rng.uniform(-0.5 * spread, 0.5 * spread, size=(count, 2))
    position = np.array([0.3, -0.2, 0.5]) + uv[:, :1] * tangent + uv[:, 1:] * np.cross(normal, tangent)
    return {"position": position, "normal": np.tile(normal, (count, 1)), "flux": np.ones((count, 3)),
            "rs": np.ones((count, 3)), "roughness": np.full(count, 0.01),
            "texel": np.arange(count) % 8 + 64 * (np.arange(count) // 8), "view": np.zeros(count, np.int64)}


@pytest.mark.parametrize("normal", [(0.0, 0.0, 1.0), (0.2, -0.5, 0.8), (1.0, 0.0, 1e-3)])
def test_a_flat_cluster_s_half_space_leaves_out_only_what_cannot_block_its_light(normal):
    """Every VPL of a flat cluster lies outside its map's half-space (its own surface is not
    splatted), and along segments from its VPLs to receivers in their front hemisphere (glossy
    light leaves there), the points outside it are within CLUSTER_PLANE_SLACK of the VPLs' plane:
    a left-out point blocks no such segment but where it leaves the surface."""
    from vsgl_addon.reference import ism as reference_ism

    rng = np.random.default_rng(3)
    vpls = _flat_cluster(rng, normal)
    cluster, origins, _, planes = vpl_culling.vpl_clusters(vpls, 64)
    assert len(origins) == 1 and np.isfinite(planes).all()
    assert not reference_ism.keeps_point(vpls["position"] - origins[0], planes[0]).any()
    n = vpls["normal"][0]
    start = vpls["position"][rng.integers(0, 64, 4000)]
    direction = rng.normal(size=(4000, 3))
    direction *= np.sign(direction @ n)[:, None]
    segment = start[:, None] + rng.uniform(0.0, 3.0, (4000, 1, 1)) * np.linspace(0.0, 1.0, 50)[None, :, None] \
        * direction[:, None]
    left_out = ~reference_ism.keeps_point(segment.reshape(-1, 3) - origins[0], planes[0])
    heights = (segment.reshape(-1, 3) - vpls["position"][0]) @ n
    assert left_out.any() and (~left_out).any()
    assert heights[left_out].max() <= vpl_culling.CLUSTER_PLANE_SLACK + 1e-9


def test_a_mirror_floor_s_own_points_do_not_shadow_the_wall_it_lights():
    """A floor cluster's map (reference splat, gap closing, pull-push at the pass's sizes) and a wall
    3 m away: with the floor's own points splatted, edge-on at the map's horizon, and pulled into
    the texels of the sparse wall above them, some wall receivers are fully shadowed; with the
    cluster's half-space every one is lit (nothing stands between)."""
    from test_reference_ism import _geometry, _quad
    from vsgl_addon import scene_points as sp
    from vsgl_addon.reference import ism as reference_ism

    rng = np.random.default_rng(1)
    scene = _geometry(_quad(-4, -4, 4, 4) + [((-4, 3, 0), (4, 3, 0), (4, 3, 4)), ((-4, 3, 0), (4, 3, 4), (-4, 3, 4))])
    points = sp.scene_point_sets(scene, 4096, 1, seed=0)
    vpls = _flat_cluster(rng, (0.0, 0.0, 1.0))
    vpls["position"] = vpls["position"] * [1.0, 1.0, 0.0]  # on the floor z = 0
    _, origins, sigma, planes = vpl_culling.vpl_clusters(vpls, 64)
    wall = np.stack([rng.uniform(-3, 3, 400), np.full(400, 3.0), rng.uniform(0.05, 3.5, 400)], -1)
    facing = np.tile([0.0, -1.0, 0.0], (400, 1))
    for size in (32, 64):
        lit = {}
        for plane in (None, planes[0]):
            depth = reference_ism.pull_push(reference_ism.close_gaps(reference_ism.splat(
                points.positions[0], origins[0], size, sigma[0], points.normals[0], 96.0 / 4096, plane=plane)))
            lit[plane is not None] = reference_ism.ism_pcf_bilinear(depth, origins[0], wall, facing)
        assert lit[False].min() == 0.0, size
        assert lit[True].min() > 0.999, size
