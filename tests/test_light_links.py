# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender's per-light and per-object controls in the passes: the light's diffuse and specular
factors, light and shadow linking, and ray visibility (the RSM, the direct light and the two VSGL
sets of the receivers' lobes). Against the same scenes without the control, exactly; the Cycles
comparison of each control is tests/test_light_controls.py."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from test_rsm import make_camera, make_light, make_scene, material, rectangle
from vsgl_addon.passes import rsm as R
from vsgl_addon.passes.direct_light import render_direct_light
from vsgl_addon.passes.gbuffer import render_camera_gbuffer
from vsgl_addon.passes.scene_gpu import LIGHT_LINKS_WIDTH, SceneGPU, light_links_array, light_links_rows
from vsgl_addon.renderer import FrameRenderer
from vsgl_addon.scene_description import Geometry, SceneDescription
from vsgl_addon.settings import VSGLSettings

pytestmark = pytest.mark.gpu

FLOOR, CARD = 0, 1  # object indices: a floor, and a small card above it that shades part of it


def _scene(light_changes=None, visibility=None):
    """A spot over a glossy floor (object 0) and a card (object 1) at z = 0.5 between them."""
    light = make_light("SPOT", 400.0, (0.0, 0.0, 2.0), spot_size=np.radians(70.0), spot_blend=0.1)
    light = dataclasses.replace(light, **(light_changes or {}))
    base = make_scene([rectangle(1.5), rectangle(0.3, z=0.5)], [light],
                      materials=[material("Floor", (0.8, 0.3, 0.1), roughness=0.3)], material_of_set=[1, 1],
                      camera=make_camera((0.0, -3.0, 2.5), (0.0, 0.0, 0.0), resolution=(48, 36)))
    geometry = dataclasses.replace(base.geometry, object_index=np.array([FLOOR] * 2 + [CARD] * 2, np.int32))
    return dataclasses.replace(base, geometry=geometry, object_names=("Floor", "Card"),
                               object_visibility=visibility)


def _rsm(scene, receiver_lobe="all"):
    scene_gpu = SceneGPU(scene)
    try:
        views = R.render_rsm_views(scene_gpu, 0, 64, receiver_lobe)
        arrays = [view.to_numpy() for view in views]
    finally:
        scene_gpu.free()
    assert len(arrays) == 1
    return arrays[0]


def _on_card(arrays):
    return arrays.coverage & (np.abs(arrays.rsm.position[..., 2] - 0.5) < 1e-4)


def test_light_factors_scale_the_reflected_flux_exactly():
    plain = _rsm(_scene())
    scaled = _rsm(_scene({"diffuse_factor": 0.25, "specular_factor": 3.0}))
    np.testing.assert_allclose(scaled.rsm.flux_diffuse, 0.25 * plain.rsm.flux_diffuse, rtol=1e-6, atol=0)
    np.testing.assert_allclose(scaled.rsm.flux_specular, 3.0 * plain.rsm.flux_specular, rtol=1e-6, atol=0)
    np.testing.assert_array_equal(scaled.flux, plain.flux)  # the light arrives all the same


def test_an_object_outside_the_light_s_receivers_reflects_none_of_it():
    plain = _rsm(_scene())
    linked = _rsm(_scene({"receivers": np.array([True, False])}))
    card = _on_card(plain)
    assert card.sum() > 20
    assert np.all(linked.rsm.flux_diffuse[card] == 0.0) and np.all(linked.rsm.flux_specular[card] == 0.0)
    np.testing.assert_array_equal(linked.rsm.flux_diffuse[~card], plain.rsm.flux_diffuse[~card])
    np.testing.assert_array_equal(linked.depth, plain.depth)  # it still blocks the light


@pytest.mark.parametrize("how", ["shadow linking", "no shadow-ray visibility"])
def test_an_object_that_does_not_block_is_a_reflector_but_not_in_the_shadow_map(how):
    if how == "shadow linking":
        scene = _scene({"blockers": np.array([True, False])})
    else:
        scene = _scene(visibility=np.array([[True, True, True], [True, True, False]]))
    plain, unblocked = _rsm(_scene()), _rsm(scene)
    floor_only = _rsm(dataclasses.replace(_scene(), geometry=dataclasses.replace(
        _scene().geometry, positions=_scene().geometry.positions[:2], normals=_scene().geometry.normals[:2],
        uvs=_scene().geometry.uvs[:2], material_index=_scene().geometry.material_index[:2],
        object_index=_scene().geometry.object_index[:2])))
    card = _on_card(plain)
    # The shadow map holds the floor alone; the colour attachments still see the card.
    np.testing.assert_array_equal(unblocked.depth, floor_only.depth)
    assert np.array_equal(_on_card(unblocked), card)
    np.testing.assert_array_equal(unblocked.rsm.flux_diffuse, plain.rsm.flux_diffuse)


def _direct(scene):
    scene_gpu = SceneGPU(scene)
    views = {0: R.render_rsm_views(scene_gpu, 0, 64)}
    gbuffer = render_camera_gbuffer(scene_gpu)
    try:
        direct = render_direct_light(gbuffer, scene.lights, views, scene_gpu=scene_gpu)
        diffuse, glossy = direct.to_numpy()
        direct.free()
        object_index = gbuffer.to_numpy()["material"][..., 3]
        coverage = gbuffer.to_numpy()["position"][..., 3] > 0.5
    finally:
        gbuffer.free()
        for view in views[0]:
            view.free()
        scene_gpu.free()
    return diffuse[..., :3] + glossy[..., :3], np.where(coverage, np.rint(object_index), -1)


def test_direct_light_reaches_only_the_light_s_receivers_and_only_blockers_shadow():
    plain, objects = _direct(_scene())
    assert {FLOOR, CARD} <= set(np.unique(objects).tolist())
    only_floor, _ = _direct(_scene({"receivers": np.array([True, False])}))
    card, floor = objects == CARD, objects == FLOOR
    assert plain[card].max() > 0 and np.all(only_floor[card] == 0.0)
    np.testing.assert_array_equal(only_floor[floor], plain[floor])
    # The card shadows part of the floor; not blocking, it shadows nothing.
    unblocked, _ = _direct(_scene({"blockers": np.array([True, False])}))
    shadowed = floor & (plain.sum(-1) == 0.0) & (unblocked.sum(-1) > 0.0)
    assert shadowed.sum() > 10
    assert np.all(unblocked[floor] >= plain[floor])


def test_objects_hidden_from_one_ray_type_leave_that_lobe_s_vsgls():
    visibility = np.array([[True, True, True], [False, True, True]])  # the card: no diffuse rays
    scene = _scene(visibility=visibility)
    assert scene.receiver_lobe_split and not _scene().receiver_lobe_split
    diffuse_set, glossy_set = _rsm(scene, "diffuse"), _rsm(scene, "glossy")
    plain = _rsm(_scene())
    card = _on_card(plain)
    assert np.all(diffuse_set.rsm.flux_diffuse[card] == 0.0)
    np.testing.assert_array_equal(glossy_set.rsm.flux_diffuse, plain.rsm.flux_diffuse)
    np.testing.assert_array_equal(diffuse_set.rsm.flux_diffuse[~card], plain.rsm.flux_diffuse[~card])
    # A frame shades each receiver lobe from its own set: glossy as without the control, diffuse less.
    # (MRP-ASG and the glossy VPLs off: a proxy or a sharp reflector would split the sets of both scenes;
    # the light PDF: with the view PDF the one set of the whole scene follows it, and a glossy set not.)
    settings = VSGLSettings(vsgl_count=64, rsm_size=64, glossy_reflectors=False, caustics=False, pdf="light")
    renderer = FrameRenderer()
    try:
        split, whole = renderer.render(scene, settings, 48, 36), renderer.render(_scene(), settings, 48, 36)
    finally:
        renderer.free()
    assert split.counts["vsgls"] == 2 * whole.counts["vsgls"]
    np.testing.assert_allclose(split.indirect_specular, whole.indirect_specular, rtol=1e-6, atol=1e-9)
    assert split.indirect_diffuse.sum() < 0.99 * whole.indirect_diffuse.sum()


def test_light_links_texture_wraps_rows_of_objects():
    objects, lights = LIGHT_LINKS_WIDTH + 7, 2
    rng = np.random.default_rng(3)
    receivers = [rng.random(objects) < 0.5 for _ in range(lights)]
    base = _scene()
    scene = SceneDescription(Geometry.empty(), base.materials,
                             tuple(dataclasses.replace(base.lights[0], receivers=r) for r in receivers),
                             None, tuple(f"o{i}" for i in range(objects)))
    rows = light_links_rows(scene)
    array = light_links_array(scene)
    assert rows == 2 and array.shape == (lights * rows, LIGHT_LINKS_WIDTH, 4)
    table = scene.light_links()
    o = np.arange(objects)
    for light in range(lights):
        np.testing.assert_array_equal(array[light * rows + o // LIGHT_LINKS_WIDTH, o % LIGHT_LINKS_WIDTH],
                                      table[light])
    assert light_links_rows(dataclasses.replace(scene, lights=(base.lights[0],))) == 0
