# SPDX-License-Identifier: GPL-3.0-or-later
"""The frame planner (vsgl_addon/planner.py): N as the frame's VSGL budget, which lights get RSM
views, which passes run and why; and, on the GPU, that the budget split keeps every light's summed
VSGL power equal to its RSM total and that skipping MRP-ASG where it serves no receiver changes nothing."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from test_proxies import grid, material, point_light, scene_of
from vsgl_addon import planner as P
from vsgl_addon.proxies import ProxyCache
from vsgl_addon.scene_description import Camera, SceneDescription
from vsgl_addon.settings import VSGLSettings


# --- The budget split ----------------------------------------------------------------------------


def _flat(counts):
    return np.concatenate([np.asarray(c) for c in counts.values()]) if counts else np.zeros(0)


@pytest.mark.parametrize("budget", [1, 7, 24, 256, 4096])
def test_the_budget_is_the_frame_s_and_every_light_with_bounce_gets_one_where_it_allows(budget):
    rng = np.random.default_rng(budget)
    powers = {light: rng.random(rng.integers(1, 7)) * 10.0 ** rng.uniform(-1, 2) for light in range(24)}
    counts, dropped = P.allocate_vsgls(budget, powers)
    assert _flat(counts).sum() == budget  # all of N, never more
    per_light = {light: int(np.sum(c)) for light, c in counts.items()}
    total = sum(p.sum() for p in powers.values())
    # "Real" bounce: more than the negligible share (the dimmest views, summed, may drop below it).
    lit = [light for light in powers if powers[light].sum() > P.NEGLIGIBLE_BOUNCE * total]
    if budget >= len(lit):
        assert all(per_light[light] >= 1 for light in lit)
    else:  # the brightest lights first
        order = sorted(lit, key=lambda light: -powers[light].max())
        assert all(per_light[light] == 1 for light in order[:budget])
    assert 0.0 <= dropped <= 1.0
    if budget >= sum(len(p) for p in powers.values()):
        assert dropped <= P.NEGLIGIBLE_BOUNCE


def test_counts_follow_the_power_so_every_vsgl_carries_about_the_same():
    powers = {0: [400.0, 100.0], 1: [300.0], 2: [200.0, 0.0]}
    counts, dropped = P.allocate_vsgls(100, powers)
    assert [c.tolist() for c in counts.values()] == [[40, 10], [30], [20, 0]]
    assert dropped == 0.0
    # A view far below one VSGL's worth still gets one (held at one, the rest shared again).
    counts, _ = P.allocate_vsgls(10, {0: [1000.0], 1: [20.0]})
    assert counts[0].tolist() == [9] and counts[1].tolist() == [1]


def test_negligible_and_powerless_views_get_none_and_the_loss_is_bounded():
    powers = {0: [1.0e6], 1: [1.0, 5.0e2], 2: [0.0], 3: [2.0e3]}
    counts, dropped = P.allocate_vsgls(64, powers)
    # The dimmest views first, while their sum stays within 1e-3 of the bounce: 1 and 500 of ~1e6.
    assert counts[1].tolist() == [0, 0] and counts[2].tolist() == [0]
    assert counts[3].tolist() == [1] and counts[0].tolist() == [63]  # 2e-3: real bounce, one VSGL
    assert dropped == pytest.approx(501.0 / (1.0e6 + 2501.0))
    assert dropped <= P.NEGLIGIBLE_BOUNCE
    empty, lost = P.allocate_vsgls(64, {0: [0.0, 0.0], 1: []})
    assert _flat(empty).sum() == 0 and lost == 0.0
    nan, _ = P.allocate_vsgls(8, {0: [np.nan], 1: [np.inf], 2: [1.0]})
    assert nan[0].tolist() == [0] and nan[2].tolist() == [8]


# --- Plans of CPU scene descriptions -------------------------------------------------------------


def _camera(position=(0.0, -6.0, 2.0), looking=(0.0, 1.0, -0.3)):
    forward = np.asarray(looking, np.float64) / np.linalg.norm(looking)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    matrix = np.eye(4)
    matrix[:3, 0], matrix[:3, 1], matrix[:3, 2], matrix[:3, 3] = right, up, -forward, position
    return Camera("Camera", matrix, "PERSP", 30.0, 36.0, 24.0, "AUTO", 6.0, 0.0, 0.0, 0.1, 100.0, (64, 48), (1.0, 1.0))


def _room(lights, floor_roughness=0.7, wall_roughness=0.7, receivers=None, floor_metallic=0.0, floor_color=0.6):
    """A floor and a back wall (materials 1, 2), the camera in front."""
    floor = grid(2, 2, 8.0, 8.0, origin=(-4, -4, 0))
    wall = grid(2, 2, 8.0, 4.0, origin=(-4, 3, 0), u=(1, 0, 0), v=(0, 0, 1))
    mats = (material("Floor", floor_roughness, metallic=floor_metallic, color=(floor_color,) * 3),
            material("Wall", wall_roughness, metallic=0.0, color=(0.8, 0.2, 0.1)))
    scene = scene_of([(floor, 1, 0), (wall, 2, 1)], mats, lights)
    return SceneDescription(scene.geometry, scene.materials, scene.lights, _camera(), scene.object_names)


def _named(light, name):
    return type(light)(**{**light.__dict__, "name": name})


def test_lights_that_reach_nothing_get_no_rsm_and_the_others_are_planned():
    down = _named(point_light((0.0, 0.0, 2.0), power=500.0), "Down")
    away = _named(point_light((0.0, 0.0, 20.0), kind="SPOT", direction=(0, 0, 1.0), spot_size=0.5,
                              matrix_world=_spot_matrix((0.0, 0.0, 20.0), up=True)), "Away")
    unlinked = _named(point_light((1.0, 0.0, 2.0), power=300.0), "Unlinked")
    unlinked = type(unlinked)(**{**unlinked.__dict__, "receivers": np.zeros(2, bool)})
    plan = P.plan_frame(_room([down, away, unlinked]), VSGLSettings(vsgl_count=64), ProxyCache())
    by_name = {light.name: light for light in plan.lights}
    assert by_name["Down"].gets_rsm and by_name["Down"].bounce_estimate > 0.0
    assert not by_name["Away"].gets_rsm and "see no triangle" in by_name["Away"].reason
    assert not by_name["Unlinked"].gets_rsm and "light linking" in by_name["Unlinked"].reason
    assert plan.rsm_lights() == [by_name["Down"].index]
    # The RSM pass renders the views the plan found: as many as it counts (the cube face looking up
    # above the floor and the wall sees no triangle), none for the others.
    assert [len(light.view_specs) for light in plan.lights] == [light.rsm_views for light in plan.lights] == [5, 0, 0]


@pytest.mark.parametrize("rsm_size, share, side", [
    (128, 1.0, 128),  # a lone light: the settings' side
    (128, 0.3, 128),  # √0.3 × 128 = 70, rounded up to a power of two
    (128, 0.2, 64),  # 57
    (128, 0.03, 32),  # 22: a point light's part of 32 lights
    (128, 0.001, P.MIN_RSM_SIZE),  # 4: the floor
    (16, 0.001, 16),  # never above the settings' side
    (128, 0.0, P.MIN_RSM_SIZE),
])
def test_rsm_side_follows_the_square_root_of_the_expected_share(rsm_size, share, side):
    assert P.rsm_size_for_share(rsm_size, share) == side


def test_lights_sharing_n_get_smaller_rsms_and_their_lines_say_why():
    many = [point_light((x, y, 2.0), power=100.0) for x in (-2.0, -1.0, 0.0, 1.0, 2.0) for y in (-1.0, 0.0, 1.0)]
    many += [point_light((x, 0.5, 1.0), power=100.0) for x in (-1.5, -0.5, 0.5, 1.5)]
    settings = VSGLSettings(vsgl_count=256, rsm_size=128)
    plan = P.plan_frame(_room(many), settings, ProxyCache())
    total = sum(light.bounce_estimate for light in plan.lights)
    for light in plan.lights:
        assert light.rsm_size == P.rsm_size_for_share(128, light.bounce_estimate / total) < 128
        assert light.rsm_size >= P.MIN_RSM_SIZE
        line = plan.light_line(light)
        assert f"{light.rsm_size}²" in line and f"× 128 → {light.rsm_size}" in line
    assert min(light.rsm_size for light in plan.lights) == P.MIN_RSM_SIZE  # 19 lights: ≈ 5 % each
    alone = P.plan_frame(_room(many[:1]), settings, ProxyCache())
    assert alone.lights[0].rsm_size == 128 and "√(100 % expected share of N) × 128 → 128" in alone.light_line(
        alone.lights[0])
    report = json.loads(json.dumps(plan.to_dict()))
    assert report["lights"][0]["size_reason"] == plan.lights[0].size_reason


def _spot_matrix(position, up=False):
    """A spot at ``position`` pointing down -Z (or, ``up``, along +Z)."""
    matrix = np.eye(4)
    if up:
        matrix[:3, :3] = np.diag([1.0, -1.0, -1.0])
    matrix[:3, 3] = position
    return matrix


def test_the_bounce_estimate_scales_with_power_and_reflectance():
    light = point_light((0.0, 0.0, 2.0), power=100.0)
    low = P.plan_frame(_room([light]), VSGLSettings(), ProxyCache()).lights[0].bounce_estimate
    high = P.plan_frame(_room([point_light((0.0, 0.0, 2.0), power=400.0)]), VSGLSettings(), ProxyCache())
    assert high.lights[0].bounce_estimate == pytest.approx(4.0 * low, rel=1e-9)
    # Order of magnitude: half of a point light's flux falls on the floor below it, ~0.6 albedo.
    assert 0.1 * 100.0 < low < 100.0


def test_each_decision_has_a_reason_and_follows_the_cells_the_scene_fills():
    light = point_light((0.0, 0.0, 2.0), power=500.0)
    rough = P.plan_frame(_room([light]), VSGLSettings(), ProxyCache())
    assert set(rough.decisions) == set(P.DECISIONS)
    assert rough.runs("vsgls") and rough.runs("visibility")
    assert not rough.runs("mrp_asg") and "no lit rectangle proxy" in rough.decisions["mrp_asg"].reason
    assert not rough.runs("glossy_set") and rough.receiver_sets == ("all",)
    assert not rough.runs("vpl_pass") and not P.vpl_pass_needed(_room([light]), VSGLSettings()).run
    off = P.plan_frame(_room([light]), VSGLSettings(visibility=False, glossy_reflectors=False), ProxyCache())
    assert not off.runs("visibility") and "off in the settings" in off.decisions["visibility"].reason
    assert "off in the settings" in off.decisions["mrp_asg"].reason
    # A mirror-like floor (α 0.01, a rectangle proxy) under the light, glossy wall receivers (α 0.09).
    sharp = _room([light], floor_roughness=0.1, wall_roughness=0.3)
    plan = P.plan_frame(sharp, VSGLSettings(), ProxyCache())
    assert plan.runs("mrp_asg") and len(plan.proxies) >= 1
    needed = P.vpl_pass_needed(sharp, VSGLSettings())
    assert needed.run and "GGX α < α_c" in needed.reason
    # The VPLs take the floor's specular light from the diffuse receivers' set, MRP-ASG from the
    # glossy one, and the receivers MRP-ASG leaves take it from a third (light-paths.md).
    assert plan.runs("vpl_pass") and plan.runs("whole_set") and plan.receiver_sets == ("diffuse", "glossy", "all")
    no_caustics = P.plan_frame(sharp, VSGLSettings(caustics=False), ProxyCache())
    assert not no_caustics.runs("vpl_pass") and "off in the settings" in no_caustics.decisions["vpl_pass"].reason
    assert no_caustics.receiver_sets == ("diffuse", "glossy")
    # Only rough receivers (α 0.49 > 0.35) besides the floor itself, and the floor out of view: no MRP-ASG.
    camera = sharp.camera
    looking_up = _camera(position=(0.0, 2.9, 3.5), looking=(0.0, 0.01, 1.0))
    rough_walls = _room([light], floor_roughness=0.1, wall_roughness=0.7)
    view = looking_up.projection_matrix() @ looking_up.view_matrix()
    unseen = P.plan_frame(rough_walls, VSGLSettings(), ProxyCache(), view_projection=view)
    assert not unseen.runs("mrp_asg") and "no glossy receiver" in unseen.decisions["mrp_asg"].reason
    # The floor stays a sharp reflector for the VPLs: the diffuse receivers' set leaves it to them.
    assert unseen.proxies == [] and unseen.runs("vpl_pass") and unseen.receiver_sets == ("diffuse", "glossy")
    seen = P.plan_frame(rough_walls, VSGLSettings(), ProxyCache(),
                        view_projection=camera.projection_matrix() @ camera.view_matrix())
    assert seen.runs("mrp_asg")  # the floor (α 0.01) is a glossy receiver in the scene camera's view


# --- Auto quality mode: a pass worth its cost ------------------------------------------------------


def test_weigh_passes_runs_a_pass_from_the_threshold_up_and_counts_what_it_adds_to_the_passes_taken():
    """share / added fraction of the frame time against the threshold, both sides; a pass that needs
    the VSGL set another pass already split off costs only its own steps."""
    def frame(passes):  # 1 s without either; each alone doubles it; together 2.25 s (they share a set)
        return {0: 1.0, 1: 2.0, 2: 2.25}[len(passes)]

    for share, runs in ((0.099, False), (0.1, True), (0.101, True)):
        chosen, figures = P.weigh_passes({"vpl_pass": share}, frame, threshold=0.1)
        assert ("vpl_pass" in chosen) is runs
        assert figures["vpl_pass"] == pytest.approx((share, 1.0, 1.0))
    # The second pass alone: 0.05 of the bounce for +100 %, under 0.1; after the first, +12.5 %: 0.4.
    chosen, figures = P.weigh_passes({"vpl_pass": 0.5, "mrp_asg": 0.05}, frame, threshold=0.1)
    assert chosen == {"vpl_pass", "mrp_asg"}
    assert figures["mrp_asg"] == pytest.approx((0.05, 0.25, 2.0))
    chosen, figures = P.weigh_passes({"vpl_pass": 0.09, "mrp_asg": 0.05}, frame, threshold=0.1)
    assert chosen == frozenset() and figures["mrp_asg"] == pytest.approx((0.05, 1.0, 1.0))
    # A pass that adds nothing runs if its cell carries light, not if it carries none.
    assert P.weigh_passes({"mrp_asg": 0.01}, lambda passes: 1.0, threshold=0.1)[0] == {"mrp_asg"}
    assert P.weigh_passes({"mrp_asg": 0.0}, lambda passes: 1.0, threshold=0.1)[0] == frozenset()


def test_cell_powers_are_the_specular_part_of_the_bounce_on_the_sharp_reflectors_and_proxies():
    light = point_light((0.0, 0.0, 2.0), power=500.0)
    for metallic in (0.0, 1.0):
        scene = _room([light], floor_roughness=0.1, wall_roughness=0.5, floor_metallic=metallic)
        plan = P.plan_frame(scene, VSGLSettings(), ProxyCache())
        (proxy, _), = plan.proxies
        floor = scene.geometry.material_index == 1
        assert P.proxy_triangles(scene, proxy).tolist() == floor.tolist()
        _, reached = P.light_reach(scene, light)
        powers = P.cell_powers(scene, VSGLSettings(), plan.lights, [reached], plan.proxies)
        # The floor is the one sharp reflector (α 0.01; the wall's 0.25 is not) and the one proxy.
        f0 = float(np.clip(P.material_f0(scene.materials[1]), 0, 1) @ P.LUMINANCE_WEIGHTS)
        albedo = P._material_albedo(scene.materials[1])
        floor_bounce = P.bounce_estimate(scene, light, reached & floor)
        assert powers["vpl_pass"] == pytest.approx(floor_bounce * f0 / albedo, rel=1e-9)
        assert powers["mrp_asg"] == pytest.approx(powers["vpl_pass"], rel=1e-9)
        assert 0.0 < powers["vpl_pass"] < plan.lights[0].bounce_estimate
    # A light with no glossy factor puts nothing in the specular cells.
    dark = type(light)(**{**light.__dict__, "specular_factor": 0.0})
    scene = _room([dark], floor_roughness=0.1, wall_roughness=0.5, floor_metallic=1.0)
    plan = P.plan_frame(scene, VSGLSettings(), ProxyCache())
    _, reached = P.light_reach(scene, dark)
    assert P.cell_powers(scene, VSGLSettings(), plan.lights, [reached], plan.proxies) == {"vpl_pass": 0.0,
                                                                                         "mrp_asg": 0.0}


def test_auto_leaves_out_a_pass_whose_cell_carries_little_light_for_its_cost_and_manual_keeps_it():
    """A sharp dielectric floor (F0 0.04: its specular lobe is a few per cent of the bounce) under a
    point light, glossy wall receivers: Manual runs the VPL pass and MRP-ASG wherever their cells
    exist; Auto leaves both out (one VSGL set) and says why. A metal floor (its bounce is all specular)
    keeps both in Auto. Either side of the threshold on the same plan flips the decision."""
    light = point_light((0.0, 0.0, 2.0), power=500.0)
    dielectric = _room([light], floor_roughness=0.1, wall_roughness=0.5)
    manual = P.plan_frame(dielectric, VSGLSettings(), ProxyCache())
    assert manual.runs("vpl_pass") and manual.runs("mrp_asg") and manual.weighed == {}
    assert manual.receiver_sets == ("diffuse", "glossy", "all")
    assert "Auto" not in " ".join(manual.summary_lines())
    auto = P.plan_frame(dielectric, VSGLSettings(quality_mode="auto"), ProxyCache())
    assert not auto.runs("vpl_pass") and not auto.runs("mrp_asg") and auto.receiver_sets == ("all",)
    assert auto.proxies == []
    for name in P.AUTO_OPTIONAL:
        share, added, base = auto.weighed[name]
        assert 0.0 < share < 0.1 and added > 0.0
        assert share / (added / base) < P.AUTO_SHARE_PER_COST
        reason = auto.decisions[name].reason
        assert reason.startswith("Auto: its cell carries") and f"{100.0 * share:.3g} % of the bounce" in reason
        assert "its light stays with VSGLs" in reason
    # The other decisions are the ones of those passes switched off.
    off = P.plan_frame(dielectric, VSGLSettings(caustics=False, glossy_reflectors=False), ProxyCache())
    assert {k: d.run for k, d in auto.decisions.items()} == {k: d.run for k, d in off.decisions.items()}
    report = json.loads(json.dumps(auto.to_dict()))
    assert set(report["auto_weighed"]) == set(P.AUTO_OPTIONAL)

    metal = _room([light], floor_roughness=0.1, wall_roughness=0.5, floor_metallic=1.0)
    kept = P.plan_frame(metal, VSGLSettings(quality_mode="auto"), ProxyCache())
    assert kept.runs("vpl_pass") and kept.runs("mrp_asg") and kept.receiver_sets == ("diffuse", "glossy", "all")
    assert "; Auto: its cell carries" in kept.decisions["vpl_pass"].reason
    assert {k: d.run for k, d in kept.decisions.items()} == {
        k: d.run for k, d in P.plan_frame(metal, VSGLSettings(), ProxyCache()).decisions.items()}

    # Both sides of the threshold on the dielectric floor's figures: the pass Auto weighs first.
    value = max(share / (added / base) for share, added, base in auto.weighed.values())
    for factor, runs in ((0.99, True), (1.01, False)):
        original = P.AUTO_SHARE_PER_COST
        P.AUTO_SHARE_PER_COST = factor * value
        try:
            plan = P.plan_frame(dielectric, VSGLSettings(quality_mode="auto"), ProxyCache())
        finally:
            P.AUTO_SHARE_PER_COST = original
        assert (plan.runs("vpl_pass") or plan.runs("mrp_asg")) is runs


def test_auto_keeps_manual_s_passes_without_a_finite_bounce_estimate():
    light = point_light((0.0, 0.0, 2.0), power=500.0)
    scene = _room([light], floor_roughness=0.1, wall_roughness=0.5)
    unbounded = _room([type(light)(**{**light.__dict__, "power": np.inf})], floor_roughness=0.1, wall_roughness=0.5)
    manual = P.plan_frame(unbounded, VSGLSettings(), ProxyCache())
    auto = P.plan_frame(unbounded, VSGLSettings(quality_mode="auto"), ProxyCache())
    assert {k: d.run for k, d in auto.decisions.items()} == {k: d.run for k, d in manual.decisions.items()}
    assert auto.weighed == {} and "no finite bounce estimate" in auto.decisions["mrp_asg"].reason
    assert P.plan_frame(scene, VSGLSettings(quality_mode="auto"), ProxyCache()).weighed  # the same room, weighed


def test_auto_weighs_nothing_where_no_optional_pass_has_a_cell():
    light = point_light((0.0, 0.0, 2.0), power=500.0)
    rough = _room([light])
    auto = P.plan_frame(rough, VSGLSettings(quality_mode="auto"), ProxyCache())
    manual = P.plan_frame(rough, VSGLSettings(), ProxyCache())
    assert auto.weighed == {} and auto.summary_lines() == manual.summary_lines()
    properties = SimpleNamespace(vsgl_count=256, k=1.0, kernel="MODIFIED", rsm_size=128, seed=0,
                                 positional_distribution="PER_LOBE", quality_mode="AUTO")
    assert VSGLSettings.from_properties(properties).quality_mode == "auto"


def test_summary_and_report_say_what_ran():
    lights = [point_light((x, 0.0, 2.0), power=100.0 * (1 + i)) for i, x in enumerate((-2.0, 0.0, 2.0))]
    plan = P.plan_frame(_room(lights), VSGLSettings(vsgl_count=32), ProxyCache())
    plan.allocate({i: [10.0 * (1 + i), 1.0] for i in range(3)})
    lines = plan.summary_lines()
    assert len(lines) == len(P.DECISIONS) + 3
    assert lines[0].startswith("VSGLs: on — N = 32 for the frame")
    assert plan.total_vsgls() == 32 and all(light.vsgls["all"] >= 1 for light in plan.lights)
    report = json.loads(json.dumps(plan.to_dict()))
    assert report["vsgls"] == {"all": 32} and report["summary"] == lines
    assert [light["vsgls"]["all"] for light in report["lights"]] == [light.vsgls["all"] for light in plan.lights]
    assert report["decisions"]["visibility"]["run"] is True


def test_an_empty_scene_plans_nothing():
    light = point_light((0.0, 0.0, 2.0))
    empty = SceneDescription(scene_of([(grid(1, 1, 1.0, 1.0), 1, 0)], (material("M", 0.5),), []).geometry,
                             (material("M", 0.5),), (light,), None, ("object0",))
    empty = SceneDescription(type(empty.geometry).empty(), empty.materials, (light,), None, ())
    plan = P.plan_frame(empty, VSGLSettings(), ProxyCache())
    assert plan.rsm_lights() == [] and not plan.runs("vsgls") and not plan.runs("visibility")
    assert not plan.runs("vpl_pass")
    assert plan.allocate({}) == {} and plan.total_vsgls() == 0


# --- On the GPU ---------------------------------------------------------------------------------


@pytest.mark.gpu
def test_the_budget_split_keeps_each_light_s_summed_vsgl_power_equal_to_its_rsm_total():
    """000 Eq. 5 per view: whatever count a view gets, its VSGLs sum to its RSM total; the lights share
    N = 48 by power (one 20× dimmer than the others), so every light's bounce is still estimated whole."""
    from vsgl_addon.pipeline import generate_scene_vsgls

    lights = [_named(point_light((x, 0.0, 2.0), power=p), f"L{i}")
              for i, (x, p) in enumerate(((-2.0, 600.0), (0.5, 300.0), (2.5, 30.0)))]
    table = generate_scene_vsgls(_room(lights), VSGLSettings(vsgl_count=48, rsm_size=64, visibility=False))
    per_light = np.bincount(table["light_index"], minlength=3)
    assert per_light.sum() == 48 and per_light.min() >= 1
    assert per_light[0] > per_light[1] > per_light[2]
    for light in range(3):
        estimate = table["power"][table["light_index"] == light].sum(axis=0)
        np.testing.assert_allclose(estimate, table["rsm_total_power"][light], rtol=0.05)
    np.testing.assert_allclose(table["power"].sum(axis=0), table["rsm_total_power"].sum(axis=0), rtol=0.02)


@pytest.mark.gpu
def test_mrp_asg_skipped_where_no_receiver_needs_it_changes_no_pixel(monkeypatch):
    """A sharp floor proxy, only rough receivers in view: the plan skips MRP-ASG and the glossy set,
    and the frame equals the one that runs them (every receiver outside MRP-ASG's range takes the
    proxies' light from the VSGLs either way)."""
    from vsgl_addon.renderer import FrameRenderer

    # The glossy set with as many VSGLs as the whole one (P.GLOSSY_SET_FACTOR gives it more, a
    # different lattice), so that the pixels MRP-ASG would serve match to rounding.
    monkeypatch.setattr(P, "GLOSSY_SET_FACTOR", 1)
    scene = _room([point_light((0.0, -1.0, 2.5), power=800.0)], floor_roughness=0.1, wall_roughness=0.7)
    settings = VSGLSettings(vsgl_count=32, rsm_size=64, visibility=False)
    camera = _camera(position=(0.0, -5.0, 3.5), looking=(0.0, 1.0, 0.3))  # the wall's top, not the floor
    scene = SceneDescription(scene.geometry, scene.materials, scene.lights, camera, scene.object_names)
    renderer = FrameRenderer()
    try:
        skipped = renderer.render(scene, settings, 48, 36)
        monkeypatch.setattr(P, "glossy_receivers_in_view", lambda *args, **kwargs: 1)
        forced = renderer.render(scene, settings, 48, 36)
    finally:
        renderer.free()
    assert not skipped.plan.runs("mrp_asg") and skipped.counts["proxies"] == 0
    assert forced.plan.runs("mrp_asg") and forced.counts["proxies"] >= 1
    assert skipped.indirect.max() > 0.0
    np.testing.assert_allclose(skipped.indirect_diffuse, forced.indirect_diffuse, rtol=1e-5, atol=1e-8)
    np.testing.assert_allclose(skipped.indirect_specular, forced.indirect_specular, rtol=1e-4, atol=1e-7)


@pytest.mark.gpu
def test_a_pass_auto_leaves_out_renders_the_frame_of_that_pass_switched_off():
    """The dielectric sharp floor: Auto leaves out the VPL pass and MRP-ASG; its frame is the one of
    caustics and glossy reflectors off (their cells go to the VSGLs), which Manual's differs from.
    The floor is white: its specular cell carries 3.5 % of the bounce, MRP-ASG 0.029 of it per frame
    time added, under AUTO_SHARE_PER_COST (the grey floor's 5.1 % gives 0.043, over it)."""
    from vsgl_addon.renderer import FrameRenderer

    scene = _room([point_light((0.0, -1.0, 2.5), power=800.0)], floor_roughness=0.1, wall_roughness=0.5,
                  floor_color=1.0)
    settings = VSGLSettings(vsgl_count=32, rsm_size=64, visibility=False)
    renderer = FrameRenderer()
    try:
        auto = renderer.render(scene, settings.overridden(quality_mode="auto"), 48, 36)
        off = renderer.render(scene, settings.overridden(caustics=False, glossy_reflectors=False), 48, 36)
        manual = renderer.render(scene, settings, 48, 36)
    finally:
        renderer.free()
    assert not auto.plan.runs("vpl_pass") and not auto.plan.runs("mrp_asg") and manual.plan.runs("vpl_pass")
    assert auto.indirect.max() > 0.0
    np.testing.assert_allclose(auto.indirect_diffuse, off.indirect_diffuse, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(auto.indirect_specular, off.indirect_specular, rtol=1e-6, atol=1e-9)
    assert not np.allclose(manual.indirect, auto.indirect, rtol=1e-3, atol=1e-6)


def test_the_pdf_setting_and_its_command_line_flag():
    from vsgl_addon.cli import build_parser
    from vsgl_addon.settings import SettingsError

    assert VSGLSettings().pdf == "view" and VSGLSettings(pdf="light").pdf == "light"
    with pytest.raises(SettingsError, match="PDF must be one of light, view"):
        VSGLSettings(pdf="eye")
    arguments = build_parser().parse_args(["render", "s.blend", "--out", "o.exr", "--pdf", "view"])
    assert arguments.pdf == "view"
    # The view PDF needs the frame's one view; without it (the viewport) the plan keeps the light PDF.
    sun = _named(point_light((0.0, 0.0, 5.0), power=3.0, kind="SUN"), "Sun")
    camera = _camera()
    scene = _room([sun])
    settings = VSGLSettings(pdf="view")
    view_projection = camera.projection_matrix() @ camera.view_matrix()
    assert not P.plan_frame(scene, settings, ProxyCache()).runs("view_pdf")
    plan = P.plan_frame(scene, settings, ProxyCache(), view_projection=view_projection)
    assert plan.runs("view_pdf") and plan.decisions["view_pdf"].reason.startswith("Sun:")
    # Auto quality mode weighs the optional passes (a sharp floor: the VPL pass, MRP-ASG) and plans
    # them again: the suns keep the view PDF there too.
    sharp = _room([sun], floor_roughness=0.1)
    auto = P.plan_frame(sharp, VSGLSettings(pdf="view", quality_mode="auto"), ProxyCache(),
                        view_projection=view_projection)
    assert auto.weighed and auto.runs("view_pdf") and auto.decisions["view_pdf"].reason.startswith("Sun:")
    assert not P.plan_frame(scene, VSGLSettings(pdf="light"), ProxyCache(), view_projection=view_projection).runs("view_pdf")
    assert not P.plan_frame(scene, VSGLSettings(pdf="view", kernel="two-vsgl"), ProxyCache(),
                            view_projection=np.eye(4)).runs("view_pdf")
    # Local lights keep the light PDF (planner.VIEW_PDF_LIGHT_TYPES): their RSM is their own frustum.
    point = _room([point_light((0.0, 0.0, 2.0), power=500.0)])
    plan = P.plan_frame(point, settings, ProxyCache(), view_projection=view_projection)
    assert not plan.runs("view_pdf") and plan.decisions["view_pdf"].reason.startswith("no sun")


@pytest.mark.gpu
def test_plane_split_point_lights_keep_each_light_s_power_and_its_kernels(monkeypatch):
    """With the point lights' clusters split by plane (pipeline.PLANE_SPLIT_LIGHT_TYPES) in the
    same room: N = 48 kernels still, more VSGLs (the room's corners), each light's VSGL power its
    RSM total as without the split, every field finite; the shading table is the compacted one."""
    from vsgl_addon import pipeline
    from vsgl_addon.pipeline import generate_scene_vsgls

    lights = [_named(point_light((x, 0.0, 2.0), power=p), f"L{i}")
              for i, (x, p) in enumerate(((-2.0, 600.0), (0.5, 300.0), (2.5, 30.0)))]
    settings = VSGLSettings(vsgl_count=48, rsm_size=64, visibility=False)
    whole = generate_scene_vsgls(_room(lights), settings)
    monkeypatch.setattr(pipeline, "PLANE_SPLIT_LIGHT_TYPES", ("POINT",))
    split = generate_scene_vsgls(_room(lights), settings)
    assert 48 < len(split["power"]) <= 48 * 4
    assert not np.any(np.all(split["power"] == 0.0, axis=1))
    for key in ("power", "diffuse_amplitude", "diffuse_mean", "diffuse_variance", "mean", "variance"):
        assert np.all(np.isfinite(split[key])), key
    for light in range(3):
        np.testing.assert_allclose(split["power"][split["light_index"] == light].sum(axis=0),
                                   whole["power"][whole["light_index"] == light].sum(axis=0), rtol=1e-4)


@pytest.mark.gpu
def test_plane_split_frames_render_with_visibility(monkeypatch):
    """A point-lit room with the split on renders with visibility (one shadow map per VSGL of the
    compacted table): finite images, the VSGL count above N, the indirect light within 15 % of
    the frame without the split (the same kernels' power, regrouped)."""
    from vsgl_addon import pipeline
    from vsgl_addon.renderer import FrameRenderer

    scene = _room([point_light((0.0, -1.0, 2.5), power=800.0)])
    camera = _camera(position=(0.0, -5.0, 3.5), looking=(0.0, 1.0, -0.3))
    scene = SceneDescription(scene.geometry, scene.materials, scene.lights, camera, scene.object_names)
    settings = VSGLSettings(vsgl_count=32, rsm_size=64, visibility=True, ism_points=512, ism_size=16)
    renderer = FrameRenderer()
    try:
        whole = renderer.render(scene, settings, 48, 36)
        monkeypatch.setattr(pipeline, "PLANE_SPLIT_LIGHT_TYPES", ("POINT",))
        split = renderer.render(scene, settings, 48, 36)
    finally:
        renderer.free()
    assert np.all(np.isfinite(split.indirect)) and split.indirect.max() > 0.0
    assert split.counts["vsgls"] > whole.counts["vsgls"]
    covered = whole.coverage > 0.5
    ratio = split.indirect[covered].mean() / whole.indirect[covered].mean()
    assert 0.85 < ratio < 1.15, ratio
