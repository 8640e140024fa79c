# SPDX-License-Identifier: GPL-3.0-or-later
"""The texture layouts declared once (vsgl_addon/layouts.py): numpy packing, and that every GPU
writer and reader follows the declaration (reordered rows and attachments give the same numbers)."""

from __future__ import annotations

import numpy as np
import pytest

import scene_builders as sb
from vsgl_addon import layouts
from vsgl_addon.layouts import GBUFFER, RSM, RSM_VIEW, SHADING_INPUTS, VSGL_TABLE
from vsgl_addon.reference import vsgl as reference
from vsgl_addon.settings import VSGLSettings


def _swapped(layout, first, second):
    slots = list(layout.slots)
    i, j = layout.index(first), layout.index(second)
    slots[i], slots[j] = slots[j], slots[i]
    return tuple(slots)


def _random_record_fields(layout, count, seed=0):
    rng = np.random.default_rng(seed)
    values = {}
    for name in layout.fields:
        shape = layout.field_shape(name)
        if name in layout.per_table_fields():
            values[name] = rng.random(shape)
        elif name in layout.integer_fields:
            values[name] = rng.integers(0, 512, (count, *shape))
        else:
            values[name] = rng.random((count, *shape))
    return values


# --- numpy ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("layout", list(layouts.LAYOUTS.values()), ids=list(layouts.LAYOUTS))
def test_slots_fit_a_texel_and_fields_are_named_once_per_slot(layout):
    for slot in layout.slots:
        names = [name for name, _ in slot.fields]
        assert len(names) == len(set(names)), slot.name
        assert sum(count for _, count in slot.fields) <= 4
    assert len(set(layout.slot_names)) == len(layout.slots)


def test_vsgl_table_round_trips_through_pack_and_unpack():
    values = _random_record_fields(VSGL_TABLE, 7)
    table = VSGL_TABLE.pack(values, 7, width=9)
    assert table.shape == (len(VSGL_TABLE.slots), 9, 4)
    out = VSGL_TABLE.unpack(table.astype(np.float64), 7)
    assert set(out) == set(VSGL_TABLE.fields)
    for name, value in values.items():
        np.testing.assert_array_equal(out[name], np.asarray(value, np.float32).astype(np.float64)
                                      if name not in VSGL_TABLE.integer_fields else value, err_msg=name)
    assert out["kernel_texel"].dtype == np.int64
    assert np.all(table[:, 7:] == 0.0)


def test_a_field_spread_over_two_rows_is_read_in_order():
    values = {"kernel_center": np.array([[0.25, 0.75]])}
    table = VSGL_TABLE.pack(values, 1)
    assert table[VSGL_TABLE.index("specular_axis"), 0, 3] == 0.25
    assert table[VSGL_TABLE.index("power"), 0, 3] == 0.75


def test_attachments_round_trip_through_pack_slots_and_unpack_slots():
    values = {name: np.random.default_rng(3).random((4, 5, *RSM.field_shape(name))) for name in RSM.fields}
    texels = RSM.pack_slots(values, (4, 5))
    assert list(texels) == list(RSM.slot_names)
    out = RSM.unpack_slots(texels)
    for name, value in values.items():
        np.testing.assert_array_equal(out[name], value.astype(np.float32).astype(np.float64), err_msg=name)
    assert set(RSM.unpack_slots(texels, ["coverage"])) == {"coverage"}


def test_glsl_names_every_slot_by_its_declared_index(monkeypatch):
    code = VSGL_TABLE.glsl("image_store")
    for index, slot in enumerate(VSGL_TABLE.slots):
        assert f"#define VSGL_ROW_{slot.name.upper()} {index}\n" in code
    monkeypatch.setitem(VSGL_TABLE.__dict__, "slots", _swapped(VSGL_TABLE, "diffuse_lobe", "specular_position"))
    code = VSGL_TABLE.glsl("image_store")
    assert "#define VSGL_ROW_DIFFUSE_LOBE 9\n" in code
    assert "ivec2(column, 9), vsgl_table_pack_diffuse_lobe(r)" in code
    assert "rsm_total_power" not in code.split("void vsgl_table_store")[1]  # written once per table
    with pytest.raises(ValueError):
        VSGL_TABLE.glsl("nowhere")


# --- GPU: reordered declarations, same numbers ---------------------------------------------------


def _smooth_rsm(size=16, seed=0):
    rng = np.random.default_rng(seed)
    v, u = np.meshgrid((np.arange(size) + 0.5) / size, (np.arange(size) + 0.5) / size, indexing="ij")
    position = np.stack([4.0 * u - 2.0, 4.0 * v - 2.0, 0.3 * np.sin(5.0 * u) * np.cos(3.0 * v)], -1)
    normal = np.stack([0.3 * np.cos(5.0 * u), -0.2 * np.sin(3.0 * v), np.ones_like(u)], -1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    flux_diffuse = np.stack([0.2 + u, 0.2 + v, 0.1 + u * v], -1)
    flux_specular = 0.3 * np.stack([0.1 + v, 0.3 + u, 0.2 + 0.0 * u], -1)
    axis = normal + 0.2 * rng.normal(size=normal.shape)
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    sharpness = 5.0 + 50.0 * rng.random((size, size))
    return reference.RSM(position, normal, flux_diffuse, flux_specular, axis, sharpness)


def _gbuffer_arrays(size=8, seed=5):
    rng = np.random.default_rng(seed)
    v, u = np.meshgrid(np.linspace(0.05, 0.95, size), np.linspace(-0.45, 0.45, size), indexing="ij")
    position = np.stack([u, v - 0.5, np.full_like(u, 0.9)], -1)
    normal = np.broadcast_to([0.0, 0.0, -1.0], position.shape) + 0.1 * rng.normal(size=position.shape)
    coverage = np.ones((size, size))
    coverage[0, :2] = 0.0
    return {"position": position, "coverage": coverage, "normal": normal,
            "roughness": rng.choice([0.05, 0.3, 1.0], (size, size)),
            "diffuse_reflectance": rng.random((size, size, 3)), "specular_f0": rng.uniform(0.02, 1, (size, size, 3))}


def _frame_scene():
    scene = sb.reset()
    floor = sb.plane("Floor", size=6.0)
    floor.data.materials.append(sb.principled("Red", base_color=(0.8, 0.2, 0.1), roughness=0.3))
    sb.plane("Wall", size=6.0, location=(0, 2, 1.5), rotation=(np.radians(90), 0, 0))
    sb.spot_light(power=800.0, location=(0, -1, 3), look_at_point=(0, 0.5, 0))
    sb.camera()
    from vsgl_addon.scene import extract_scene

    return extract_scene(sb.depsgraph(scene))


def _everything(description):
    """Generation, shading (from numpy and from the generation's own GPU table), the pipeline's
    export and a whole frame, all as numpy arrays."""
    from vsgl_addon.passes import vsgl_generation, vsgl_shading
    from vsgl_addon.pipeline import generate_scene_vsgls
    from vsgl_addon.renderer import FrameRenderer

    rsm = _smooth_rsm()
    settings = VSGLSettings(vsgl_count=24, rsm_size=32)
    out = {}
    generation = vsgl_generation.PASS.run(rsm, 24, rotation=(0.3, 0.6))
    try:
        out["generation"] = generation.read_table()
        gbuffer = vsgl_shading.upload_gbuffer(**_gbuffer_arrays())
        camera = np.array([-1.5, 0.3, 0.4])
        out["shading_from_gpu_table"] = vsgl_shading.shade_gpu(
            gbuffer, camera, vsgl_shading.VSGLTable.from_generation(generation))
        out["shading_from_numpy"] = vsgl_shading.shade_gpu(gbuffer, camera, out["generation"])
    finally:
        generation.free()
    out["export"] = generate_scene_vsgls(description, settings)
    renderer = FrameRenderer()
    try:
        frame = renderer.render(description, settings, 40, 30)
    finally:
        renderer.free()
    out["frame"] = {name: getattr(frame, name) for name in
                    ("direct_diffuse", "direct_specular", "indirect_diffuse", "indirect_specular", "coverage")}
    return out


def _assert_same(actual, expected, where=""):
    if isinstance(expected, dict):
        assert set(actual) == set(expected), where
        for key in expected:
            _assert_same(actual[key], expected[key], f"{where}/{key}")
    elif isinstance(expected, tuple):
        for index, (a, e) in enumerate(zip(actual, expected)):
            _assert_same(a, e, f"{where}[{index}]")
    else:
        np.testing.assert_array_equal(actual, expected, err_msg=where)


@pytest.fixture(scope="module")
def declared(gpu_context):
    from vsgl_addon.passes import free_all_shaders

    free_all_shaders()
    description = _frame_scene()
    return description, _everything(description)


SWAPS = {
    "vsgl rows diffuse_lobe/specular_position": (VSGL_TABLE, "diffuse_lobe", "specular_position"),
    "vsgl rows power/rsm_total_power": (VSGL_TABLE, "power", "rsm_total_power"),
    "rsm attachments position/flux_specular": (RSM, "position", "flux_specular"),
    "gbuffer attachments position/material": (GBUFFER, "position", "material"),
    "shading inputs diffuse_reflectance/specular_f0": (SHADING_INPUTS, "diffuse_reflectance", "specular_f0"),
    "rsm view rows view_to_world_row1/light_params": (RSM_VIEW, "view_to_world_row1", "light_params"),
}


@pytest.mark.gpu
@pytest.mark.parametrize("swap", list(SWAPS))
def test_reordered_declaration_gives_the_same_numbers(declared, monkeypatch, swap):
    from vsgl_addon.passes import free_all_shaders, vsgl_generation

    description, expected = declared
    layout, first, second = SWAPS[swap]
    monkeypatch.setitem(layout.__dict__, "slots", _swapped(layout, first, second))
    free_all_shaders()  # the cached shaders were built from the declared order
    try:
        actual = _everything(description)
        if layout is VSGL_TABLE:
            # The GPU table really is in the new order: the raw texture's row of `first` holds it.
            from vsgl_addon.passes.gpu_util import read_texture

            generation = vsgl_generation.PASS.run(_smooth_rsm(), 24, rotation=(0.3, 0.6))
            try:
                raw = read_texture(generation.table, 24, len(VSGL_TABLE.slots)).astype(np.float64)
            finally:
                generation.free()
            name, count = VSGL_TABLE.slots[VSGL_TABLE.index(first)].fields[0]
            row = raw[VSGL_TABLE.index(first)]
            got = row[0, :count] if name in VSGL_TABLE.per_table_fields() else row[:, :count]
            want = expected["generation"][name]
            np.testing.assert_array_equal(got.reshape(np.shape(want)), want)
    finally:
        free_all_shaders()
    _assert_same(actual, expected, swap)


@pytest.mark.gpu
def test_generation_under_the_declared_layout_agrees_with_the_reference(declared):
    _, expected = declared
    table = expected["generation"]
    ref = reference.generate_vsgls(_smooth_rsm(), 24, rotation=(0.3, 0.6))
    np.testing.assert_allclose(table["rsm_total_power"], ref["rsm_total_power"], rtol=1e-5)
    np.testing.assert_allclose(table["power"].sum(axis=0), ref["power"].sum(axis=0), rtol=1e-3)
    np.testing.assert_allclose(table["mean"], ref["mean"], rtol=1e-3, atol=1e-3)
