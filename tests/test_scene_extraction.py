# SPDX-License-Identifier: GPL-3.0-or-later
"""Scene extraction (vsgl_addon.scene): Blender's evaluated depsgraph -> plain numpy description.

Every scene is built in the test (tests/scene_builders.py) on a factory-empty file; expected
values come from an independent computation (mathutils transforms, Blender's own camera matrices,
formulas.md sec. 4 units), never from the extraction code itself.
"""

from __future__ import annotations

import ast
import math
import time
from pathlib import Path

import bpy
import numpy as np
import pytest
from mathutils import Matrix, Vector

import scene_builders as sb
from vsgl_addon.scene import DEFAULT_MATERIAL, SceneDescription, extract_scene


@pytest.fixture(autouse=True)
def empty_file():
    sb.reset()
    yield


def extract(scene=None) -> SceneDescription:
    return extract_scene(sb.depsgraph(scene))


def geometric_normals(positions: np.ndarray) -> np.ndarray:
    p = positions.astype(np.float64)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def transformed(matrix: Matrix, points) -> np.ndarray:
    return np.array([list(matrix @ Vector(p)) for p in points])


# --- geometry -----------------------------------------------------------------------------------


def test_cube_triangles_are_its_faces_in_world_space():
    cube = sb.box(size=(2, 1, 0.5), location=(1, 2, 3), rotation=(0.3, -0.2, 0.7), scale=(1.5, 1, 2))
    desc = extract()
    geo = desc.geometry
    assert geo.positions.shape == (12, 3, 3) and geo.positions.dtype == np.float32
    assert geo.normals.shape == (12, 3, 3) and geo.uvs.shape == (12, 3, 2)
    assert geo.material_index.shape == (12,) and geo.object_index.shape == (12,)
    assert desc.object_names == ("Box",)

    matrix = sb.world_matrix(cube)
    corners = transformed(matrix, [v.co for v in cube.data.vertices])
    # Every triangle corner is one of the 8 transformed box corners ...
    dist = np.linalg.norm(geo.positions.reshape(-1, 1, 3) - corners[None], axis=2)
    assert dist.min(axis=1).max() < 1e-5
    # ... the triangles tile the box's surface (area of the scaled box: sides 3, 1, 1) ...
    p = geo.positions.astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    assert area == pytest.approx(2 * (3 * 1 + 3 * 1 + 1 * 1), rel=1e-5)
    # ... and face outwards, agreeing with the (flat) shading normals.
    centre = np.array(matrix.translation)
    outward = np.einsum("ti,ti->t", geometric_normals(p), p.mean(axis=1) - centre)
    assert (outward > 0).all()
    np.testing.assert_allclose(geo.normals, np.repeat(geometric_normals(p)[:, None], 3, axis=1), atol=1e-5)


def test_array_modifier_multiplies_triangles():
    obj = sb.box(size=1.0)
    mod = obj.modifiers.new("Array", "ARRAY")
    mod.count = 4
    mod.relative_offset_displace = (1.5, 0, 0)
    geo = extract().geometry
    assert geo.triangle_count == 48
    assert geo.positions[..., 0].max() == pytest.approx(0.5 + 3 * 1.5, abs=1e-5)
    assert len(obj.data.polygons) == 6, "the original mesh is untouched"


def test_collection_instances_appear_with_their_transforms():
    scene = bpy.context.scene
    source = bpy.data.collections.new("Source")
    scene.collection.children.link(source)
    sb.box("Part", size=1.0, location=(0.25, 0, 0), collection=source)
    # The source collection itself is excluded: only its instances render.
    bpy.context.view_layer.layer_collection.children["Source"].exclude = True
    placements = [((5, 0, 0), (0, 0, 0), 1.0), ((0, 4, 0), (0, 0, math.pi / 2), 2.0)]
    for i, (location, rotation, scale) in enumerate(placements):
        empty = bpy.data.objects.new(f"Instancer{i}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = source
        empty.location, empty.rotation_euler, empty.scale = location, rotation, (scale,) * 3
        scene.collection.objects.link(empty)

    desc = extract()
    geo = desc.geometry
    assert geo.triangle_count == 24
    for i, (location, rotation, scale) in enumerate(placements):
        tris = geo.positions[geo.object_index == i]
        assert len(tris) == 12
        turn = Matrix.Rotation(rotation[2], 3, "Z").to_quaternion()
        matrix = Matrix.LocRotScale(Vector(location), turn, Vector((scale,) * 3))
        expected_centre = np.array(matrix @ Vector((0.25, 0, 0)))
        np.testing.assert_allclose(tris.reshape(-1, 3).mean(axis=0), expected_centre, atol=1e-5)
        extent = np.ptp(tris.reshape(-1, 3), axis=0)
        np.testing.assert_allclose(extent, [scale] * 3, atol=1e-5)
    assert desc.object_names == ("Instancer0/Part", "Instancer1/Part")


def _instance_on_points(obj: bpy.types.Object, count: int, spacing: float, cube_size: float) -> None:
    tree = bpy.data.node_groups.new("Scatter", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    out = tree.nodes.new("NodeGroupOutput")
    line = tree.nodes.new("GeometryNodeMeshLine")
    line.inputs["Count"].default_value = count
    line.inputs["Offset"].default_value = (spacing, 0, 0)
    to_points = tree.nodes.new("GeometryNodeMeshToPoints")
    cube = tree.nodes.new("GeometryNodeMeshCube")
    cube.inputs["Size"].default_value = (cube_size,) * 3
    instance = tree.nodes.new("GeometryNodeInstanceOnPoints")
    tree.links.new(line.outputs[0], to_points.inputs["Mesh"])
    tree.links.new(to_points.outputs[0], instance.inputs["Points"])
    tree.links.new(cube.outputs[0], instance.inputs["Instance"])
    tree.links.new(instance.outputs[0], out.inputs[0])
    obj.modifiers.new("Scatter", "NODES").node_group = tree


def test_geometry_nodes_instances_appear_with_their_transforms():
    obj = sb.mesh_object("Scatter", [], [], location=(0, 0, 1), uv=False)
    _instance_on_points(obj, count=3, spacing=2.0, cube_size=0.5)
    geo = extract().geometry
    assert geo.triangle_count == 36
    centres = sorted(tuple(geo.positions[geo.object_index == i].reshape(-1, 3).mean(axis=0)) for i in range(3))
    np.testing.assert_allclose(centres, [(0, 0, 1), (2, 0, 1), (4, 0, 1)], atol=1e-5)
    np.testing.assert_allclose(np.ptp(geo.positions.reshape(-1, 3), axis=0), [4.5, 0.5, 0.5], atol=1e-5)


def test_curves_text_and_metaballs_count_once():
    scene = bpy.context.scene
    text = bpy.data.curves.new("Text", "FONT")
    text.body = "Hi"
    curve = bpy.data.curves.new("Curve", "CURVE")
    curve.bevel_depth = 0.1
    spline = curve.splines.new("POLY")
    spline.points.add(2)
    for i, point in enumerate(spline.points):
        point.co = (i, 0, 0, 1)
    balls = bpy.data.metaballs.new("Meta")
    balls.elements.new()
    for name, data in (("Text", text), ("Curve", curve), ("Meta", balls)):
        scene.collection.objects.link(bpy.data.objects.new(name, data))
    graph = sb.depsgraph()
    desc = extract_scene(graph)
    assert desc.object_names == ("Text", "Curve", "Meta")
    for i, name in enumerate(desc.object_names):
        obj = scene.objects[name].evaluated_get(graph)
        expected = len(obj.to_mesh().loop_triangles)
        obj.to_mesh_clear()
        assert expected > 0 and np.count_nonzero(desc.geometry.object_index == i) == expected, name


def test_objects_hidden_from_render_are_left_out():
    scene = bpy.context.scene
    sb.box("Shown", size=1.0)
    sb.box("DisabledInRenders", size=1.0).hide_render = True
    # The eye icon: a render (F12) shows it, but a viewport depsgraph never evaluates it, so
    # the description of a viewport depsgraph cannot hold it (documented in scene_extraction).
    sb.box("HiddenInViewport", size=1.0).hide_set(True)
    hidden = bpy.data.collections.new("HiddenCollection")
    hidden.hide_render = True
    scene.collection.children.link(hidden)
    sb.box("InHiddenCollection", size=1.0, collection=hidden)
    excluded = bpy.data.collections.new("Excluded")
    scene.collection.children.link(excluded)
    sb.box("InExcludedCollection", size=1.0, collection=excluded)
    bpy.context.view_layer.layer_collection.children["Excluded"].exclude = True
    sb.point_light(name="HiddenLamp").hide_render = True

    desc = extract()
    assert desc.object_names == ("Shown",)
    assert desc.geometry.triangle_count == 12
    assert desc.lights == ()
    assert [(s.name, s.reason) for s in desc.skipped_lights] == [("HiddenLamp", "hidden from render")]


def test_flat_smooth_and_custom_normals():
    rotation = (0.4, 0.1, -0.3)
    flat = sb.box("Flat", size=1.0, rotation=rotation, scale=(1, 3, 0.5))
    smooth = sb.box("Smooth", size=1.0, rotation=rotation, smooth=True)
    custom = sb.plane("Custom", size=1.0, rotation=rotation)
    tilt = Vector((0.3, 0.0, 1.0)).normalized()
    custom.data.normals_split_custom_set_from_vertices([tuple(tilt)] * len(custom.data.vertices))
    mirrored = sb.box("Mirrored", size=1.0, scale=(-1, 1, 1))
    desc = extract()
    geo = desc.geometry
    by_name = {name: geo.object_index == i for i, name in enumerate(desc.object_names)}
    assert np.allclose(np.linalg.norm(geo.normals, axis=-1), 1.0, atol=1e-5)

    # Flat under non-uniform scale: the normal stays perpendicular to the (scaled) surface.
    p = geo.positions[by_name["Flat"]]
    expected = np.repeat(geometric_normals(p)[:, None], 3, axis=1)
    np.testing.assert_allclose(geo.normals[by_name["Flat"]], expected, atol=1e-5)

    # Smooth cube: each corner's normal is its vertex direction from the centre, (+-1,+-1,+-1)/sqrt 3.
    p = geo.positions[by_name["Smooth"]].reshape(-1, 3)
    expected = p / np.linalg.norm(p, axis=1, keepdims=True)
    np.testing.assert_allclose(geo.normals[by_name["Smooth"]].reshape(-1, 3), expected, atol=1e-5)

    # Custom normals: the tilted direction, rotated with the object (Blender stores custom
    # normals in a compressed 16-bit form, hence the tolerance).
    world_tilt = np.array(sb.world_matrix(custom).to_3x3() @ tilt)
    np.testing.assert_allclose(geo.normals[by_name["Custom"]].reshape(-1, 3), np.tile(world_tilt, (6, 1)), atol=2e-4)

    # Mirrored (negative scale): the winding is swapped so geometric and shading normals agree.
    p = geo.positions[by_name["Mirrored"]]
    agree = np.einsum("ti,ti->t", geometric_normals(p), geo.normals[by_name["Mirrored"]][:, 0])
    assert (agree > 0.999).all()


@pytest.mark.parametrize("scale", [(1, 1, 0), (0, 1, 0), (0, 0, 0), (-1, 1, 0), (1e-4, 1e-4, 1e-4),
                                   (1e4, 1e4, 1e-4), (-1e4, 1, 1)])
def test_degenerate_and_extreme_scales_extract_with_unit_normals(scale):
    """An object scaled to zero on an axis (a common way to hide one in an animation) has a singular
    transform with no inverse transpose; it flattens to a sheet whose normal is the sheet's, and
    triangles of zero area get a unit normal too, never NaN."""
    sb.box("Scaled", size=1.0, rotation=(0.3, -0.2, 0.5), scale=scale)
    sheared = sb.box("Sheared", size=1.0, location=(3, 0, 0))
    sheared.matrix_world = Matrix(((1, 0.8, 0, 3), (0, 1, 0.5, 0), (0, 0, 1, 0), (0, 0, 0, 1)))
    desc = extract()
    geo = desc.geometry
    assert np.isfinite(geo.positions).all() and np.isfinite(geo.normals).all()
    np.testing.assert_allclose(np.linalg.norm(geo.normals, axis=-1), 1.0, atol=1e-5)
    for name in ("Scaled", "Sheared"):
        mask = geo.object_index == desc.object_names.index(name)
        p = geo.positions[mask].astype(np.float64)
        area = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        big = area > 1e-6 * max(area.max(), 1e-30)
        if not big.any():
            continue
        # Flat box faces: shading normal = geometric normal wherever the face kept an area.
        agree = np.einsum("ti,ti->t", geometric_normals(p[big]), geo.normals[mask][big][:, 0])
        assert (agree > 0.999).all(), (name, agree.min())


def test_lights_scaled_to_zero_are_skipped_with_one_warning_line_but_a_point_light_stays():
    sb.plane(size=4.0)
    sb.spot_light(name="Flat spot", location=(0, 0, 3), scale=(1, 1, 0))
    sb.area_light(name="Gone area", location=(0, 0, 3), scale=0.0)
    sb.point_light(name="Point", location=(0, 0, 2), scale=0.0)
    sb.camera()
    desc = extract()
    assert [light.name for light in desc.lights] == ["Point"]
    point = desc.lights[0]
    assert np.isfinite(point.matrix_world).all() and np.isfinite(point.direction).all()
    lines = [line for line in desc.warnings if "lights skipped" in line]
    assert len(lines) == 1 and "Flat spot (scaled to zero)" in lines[0] and "Gone area" in lines[0]


def test_light_and_shadow_linking_and_ray_visibility_come_through():
    a, b, c = (sb.plane(name, size=1.0, location=(2.0 * i, 0, 0)) for i, name in enumerate("ABC"))
    b.visible_diffuse = False
    c.visible_glossy = c.visible_shadow = False
    spot = sb.spot_light(name="Linked", location=(0, 0, 3))
    sb.point_light(name="Plain", location=(0, 0, 2))
    receivers = bpy.data.collections.new("Receivers")  # A included, B excluded
    receivers.objects.link(a)
    receivers.objects.link(b)
    receivers.collection_objects[1].light_linking.link_state = "EXCLUDE"
    blockers = bpy.data.collections.new("Blockers")  # only exclusions: everything else blocks
    inner = bpy.data.collections.new("Inner")
    inner.objects.link(c)
    blockers.children.link(inner)
    blockers.collection_children[0].light_linking.link_state = "EXCLUDE"
    spot.light_linking.receiver_collection = receivers
    spot.light_linking.blocker_collection = blockers
    sb.camera()
    desc = extract()
    assert desc.object_names == ("A", "B", "C")
    linked, plain = (next(light for light in desc.lights if light.name == n) for n in ("Linked", "Plain"))
    assert linked.receivers.tolist() == [True, False, False]  # with an inclusion, only included ones
    assert linked.blockers.tolist() == [True, True, False]
    assert plain.receivers is None and plain.blockers is None
    assert desc.visibility().tolist() == [[True, True, True], [False, True, True], [True, False, False]]
    assert desc.receiver_lobe_split and desc.uses_light_links
    links = desc.light_links()
    assert links[0, :, 1].tolist() == [1.0, 1.0, 0.0] and links[1, :, 1].tolist() == [1.0, 1.0, 0.0]


def test_non_finite_normals_fall_back_to_the_face_normal():
    from vsgl_addon import scene_extraction

    normals = np.full((2, 1, 3, 3), np.nan, np.float32)
    positions = np.array([[[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], [[[0, 0, 0], [0, 0, 0], [0, 0, 0]]]], np.float32)
    unit = scene_extraction._unit_normals(normals, positions)
    np.testing.assert_array_equal(unit[0, 0], np.tile([0.0, 0.0, 1.0], (3, 1)))
    np.testing.assert_array_equal(unit[1, 0], np.tile([0.0, 0.0, 1.0], (3, 1)))
    positions[0, 0] = [[0, 0, 0], [0, 1, 0], [1, 0, 0]]
    np.testing.assert_array_equal(scene_extraction._unit_normals(normals, positions)[0, 0],
                                  np.tile([0.0, 0.0, -1.0], (3, 1)))


def test_uvs_come_from_the_active_render_uv_map():
    obj = sb.plane(size=2.0)
    second = obj.data.uv_layers.new(name="Second")
    for loop in obj.data.loops:
        second.uv[loop.index].vector = (7.0, 8.0)
    second.active_render = True
    sb.box("NoUV", size=1.0, uv=False, location=(5, 0, 0))
    desc = extract()
    geo = desc.geometry
    np.testing.assert_array_equal(geo.uvs[geo.object_index == 0], np.broadcast_to([7.0, 8.0], (2, 3, 2)))
    assert (geo.uvs[geo.object_index == 1] == 0).all()


# --- materials ----------------------------------------------------------------------------------


def test_principled_values_come_through():
    mat = sb.principled(
        "Copper", base_color=(0.9, 0.4, 0.2), roughness=0.25, metallic=0.8, specular_ior_level=0.7, ior=1.8
    )
    other = sb.principled("Blue", base_color=(0.1, 0.2, 0.9))
    obj = sb.box("Two", size=1.0, material=mat)
    obj.data.materials.append(other)
    obj.data.polygons[0].material_index = 1
    sb.box("Bare", size=1.0, location=(3, 0, 0))
    desc = extract()
    assert [m.name for m in desc.materials] == ["<default>", "Copper", "Blue"]
    copper = desc.materials[1]
    np.testing.assert_allclose(copper.base_color, [0.9, 0.4, 0.2], rtol=1e-6)
    read = (copper.roughness, copper.metallic, copper.specular_ior_level, copper.ior)
    assert read == pytest.approx((0.25, 0.8, 0.7, 1.8))
    assert copper.base_color_image is None and not copper.approximated
    geo = desc.geometry
    assert sorted(geo.material_index[geo.object_index == 0].tolist()) == [1] * 10 + [2] * 2
    assert (geo.material_index[geo.object_index == 1] == 0).all()
    assert desc.materials[0] is DEFAULT_MATERIAL
    assert desc.warnings == ()


def test_object_linked_and_geometry_nodes_materials():
    red, blue = sb.principled("Red", base_color=(1, 0, 0)), sb.principled("Blue", base_color=(0, 0, 1))
    first = sb.box("First", size=1.0, material=red)
    second = bpy.data.objects.new("Second", first.data)  # the same mesh ...
    bpy.context.scene.collection.objects.link(second)
    second.material_slots[0].link = "OBJECT"  # ... with its own material
    second.material_slots[0].material = blue
    scatter = sb.mesh_object("Scatter", [], [], uv=False)
    _instance_on_points(scatter, count=2, spacing=2.0, cube_size=0.5)
    tree = scatter.modifiers[0].node_group
    set_material = tree.nodes.new("GeometryNodeSetMaterial")
    set_material.inputs["Material"].default_value = blue
    cube, instance = tree.nodes["Cube"], tree.nodes["Instance on Points"]
    tree.links.new(cube.outputs[0], set_material.inputs["Geometry"])
    tree.links.new(set_material.outputs[0], instance.inputs["Instance"])
    desc = extract()
    names = [m.name for m in desc.materials]
    geo = desc.geometry
    per_object = [sorted({names[i] for i in geo.material_index[geo.object_index == k]}) for k in range(4)]
    assert desc.object_names[:2] == ("First", "Second")
    assert per_object == [["Red"], ["Blue"], ["Blue"], ["Blue"]]
    assert first.material_slots[0].material == red  # the shared mesh's own slot is untouched


def test_image_texture_in_base_color_is_read_as_linear():
    # Stored (sRGB-encoded) values of a 4 x 2 byte image: the bottom row red-ish, the top row grey.
    srgb = sb.generated_image("Checker", 4, 2)
    pixels = np.array([[[0.5, 0.0, 1.0, 1.0]] * 4, [[0.25, 0.25, 0.25, 0.5]] * 4], np.float32)
    srgb.pixels.foreach_set(pixels.ravel())
    data = sb.generated_image("Data", 2, 2, (0.5, 0.5, 0.5, 1.0), colorspace="Non-Color")
    hdr = sb.generated_image("HDR", 2, 2, (0.5, 2.0, 0.25, 1.0), float_buffer=True)
    for name, image in (("Tex", srgb), ("DataTex", data), ("HdrTex", hdr)):
        sb.box(name, size=1.0, material=sb.principled(name, image=image))
    desc = extract()
    mats = {m.name: m for m in desc.materials}

    tex = mats["Tex"]
    assert tex.base_color_image.shape == (2, 4, 4) and tex.base_color_image.dtype == np.float32
    assert tex.base_color_image_name == "Checker" and not tex.approximated
    stored = np.round(pixels * 255) / 255  # what a byte image holds
    linear = np.where(stored <= 0.04045, stored / 12.92, ((stored + 0.055) / 1.055) ** 2.4)
    np.testing.assert_allclose(tex.base_color_image[..., :3], linear[..., :3], atol=1e-5)
    np.testing.assert_allclose(tex.base_color_image[..., 3], stored[..., 3], atol=1e-6)
    assert tex.base_color_image[0, 0, 0] == pytest.approx(0.2158605, abs=1e-5)  # sRGB 128/255

    np.testing.assert_allclose(mats["DataTex"].base_color_image[..., :3], 128 / 255, atol=1e-6)
    np.testing.assert_allclose(mats["HdrTex"].base_color_image[0, 0], [0.5, 2.0, 0.25, 1.0], atol=1e-6)
    assert desc.warnings == ()


def test_unreadable_materials_fall_back_with_one_warning_line():
    emission = sb.shader_material("Glow", "ShaderNodeEmission", Color=(1, 0, 0, 1))
    emission.diffuse_color = (0.2, 0.3, 0.4, 1.0)
    emission.roughness = 0.6
    emission.metallic = 0.1
    noisy = sb.principled("Noisy", base_color=(0.3, 0.6, 0.9), roughness=0.35)
    noise = noisy.node_tree.nodes.new("ShaderNodeTexNoise")
    noisy.node_tree.links.new(noise.outputs["Color"], sb.principled_node(noisy).inputs["Base Color"])
    sb.box("A", size=1.0, material=emission)
    sb.box("B", size=1.0, material=noisy, location=(2, 0, 0))
    sb.box("C", size=1.0, material=sb.principled("Plain"), location=(4, 0, 0))
    # A slot no triangle uses is not the scene's concern: not read, not warned about.
    bpy.data.objects["C"].data.materials.append(sb.shader_material("Unused", "ShaderNodeEmission"))
    desc = extract()
    mats = {m.name: m for m in desc.materials}

    glow = mats["Glow"]  # the material's Viewport Display values
    assert glow.approximated and "Emission" in glow.approximation
    np.testing.assert_allclose(glow.base_color, [0.2, 0.3, 0.4], rtol=1e-6)
    assert (glow.roughness, glow.metallic, glow.specular_ior_level, glow.ior) == pytest.approx((0.6, 0.1, 0.5, 1.5))

    noisy_read = mats["Noisy"]  # the Principled's own socket values, the texture dropped
    assert noisy_read.approximated and "Noise Texture" in noisy_read.approximation
    np.testing.assert_allclose(noisy_read.base_color, [0.3, 0.6, 0.9], rtol=1e-6)
    assert noisy_read.roughness == pytest.approx(0.35) and noisy_read.base_color_image is None

    assert not mats["Plain"].approximated and "Unused" not in mats
    assert desc.warnings == ("VSGL: approximated materials (not a plain Principled BSDF): Glow, Noisy",)
    assert desc.approximated_materials == ("Glow", "Noisy")


# --- lights -------------------------------------------------------------------------------------


def test_light_types_and_units():
    sb.point_light(name="Point", power=500, color=(1.0, 0.5, 0.25), radius=0.1, location=(1, 2, 3))
    sb.spot_light(
        name="Spot", power=800, spot_size=math.radians(60), spot_blend=0.3, location=(0, 0, 4), look_at_point=(1, 0, 0)
    )
    sb.sun_light(name="Sun", strength=3.0, rotation=(math.radians(30), 0, 0))
    area = sb.area_light(name="Area", power=200, size=0.5, size_y=0.25, location=(0, 0, 2))
    area.scale = (2, 3, 1)
    sb.point_light(name="Bright", power=100, exposure=2.0)
    sb.area_light(name="Unnormalized", power=10, size=2.0, normalize=False)
    sb.point_light(name="UnnormalizedBulb", power=10, radius=0.5, normalize=False)
    sb.sun_light(name="UnnormalizedSun", strength=2.0, angle=0.2, normalize=False)
    warm = sb.point_light(name="Warm", power=100, use_temperature=True, temperature=3000)
    sb.point_light(name="Off", power=0)
    sb.spot_light(name="Black", power=100, color=(0, 0, 0))
    desc = extract()
    lights = {light.name: light for light in desc.lights}
    assert sorted(lights) == [
        "Area", "Bright", "Point", "Spot", "Sun", "Unnormalized", "UnnormalizedBulb", "UnnormalizedSun", "Warm"
    ]
    skipped = sorted((s.name, s.reason) for s in desc.skipped_lights)
    assert skipped == [("Black", "zero colour"), ("Off", "zero power")]

    point = lights["Point"]
    assert point.type == "POINT" and point.power == pytest.approx(500) and point.radius == pytest.approx(0.1)
    np.testing.assert_allclose(point.color, [1.0, 0.5, 0.25])
    np.testing.assert_allclose(point.position, [1, 2, 3])
    np.testing.assert_allclose(point.radiant_intensity, 500 * np.array([1.0, 0.5, 0.25]) / (4 * math.pi))

    spot = lights["Spot"]
    assert spot.type == "SPOT"
    assert (spot.spot_size, spot.spot_blend) == pytest.approx((math.radians(60), 0.3))
    np.testing.assert_allclose(spot.direction, np.array([1, 0, -4]) / math.sqrt(17), atol=1e-6)
    assert spot.matrix_world.shape == (4, 4)

    sun = lights["Sun"]
    assert sun.type == "SUN" and sun.power == pytest.approx(3.0)
    np.testing.assert_allclose(sun.direction, [0, math.sin(math.radians(30)), -math.cos(math.radians(30))], atol=1e-6)

    area_light = lights["Area"]
    assert area_light.type == "AREA" and area_light.shape == "RECTANGLE"
    np.testing.assert_allclose(area_light.size, [1.0, 0.75])  # object scale applied
    np.testing.assert_allclose(area_light.radiant_intensity, [200 / math.pi] * 3)

    assert lights["Bright"].power == pytest.approx(400)  # 2^exposure
    # Normalize off: x the emitter's area (the factors Cycles 5.0.1 renders with, measured).
    assert lights["Unnormalized"].power == pytest.approx(10 * 4.0)
    assert lights["UnnormalizedBulb"].power == pytest.approx(10 * 4 * math.pi * 0.25)
    assert lights["UnnormalizedSun"].power == pytest.approx(2.0 * math.pi * math.sin(0.1) ** 2)
    np.testing.assert_allclose(lights["Warm"].color, np.array(warm.data.temperature_color), rtol=1e-6)
    assert lights["Warm"].color[0] > lights["Warm"].color[2]  # 3000 K is reddish


def _cycles_floor_brightness(
    tmp_path: Path, kind: str, power: float, color, settings: dict
) -> tuple[np.ndarray, SceneDescription]:
    """Mean RGB Cycles renders of a white diffuse floor lit by one light, and the scene's description."""
    scene = sb.reset()
    scene.world = None
    white = sb.principled("White", base_color=(1, 1, 1), roughness=1.0, specular_ior_level=0.0)
    sb.plane("Floor", size=20.0, material=white)
    sb.light(kind, power=power, color=color, location=(0, 0, 3), **settings)
    sb.camera(location=(0, 0, 10), kind="ORTHO", ortho_scale=2.0, resolution=(8, 8))
    desc = extract()
    scene.render.engine = "CYCLES"
    scene.cycles.device, scene.cycles.samples = "CPU", 16
    scene.view_settings.view_transform = "Standard"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(tmp_path / f"{kind}.exr")
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(scene.render.filepath)
    rgb = np.array(image.pixels[:], np.float64).reshape(-1, 4)[:, :3].mean(axis=0)
    return rgb, desc


@pytest.mark.parametrize(
    "kind, shape_settings, variant",
    [
        ("AREA", {"size": 2.0}, {"normalize": False}),
        ("AREA", {"size": 2.0, "shape": "DISK"}, {"normalize": False}),
        ("AREA", {"size": 1.0, "size_y": 0.5, "shape": "RECTANGLE", "scale": (2.0, 3.0, 1.0)}, {"normalize": False}),
        ("POINT", {"shadow_soft_size": 0.5}, {"normalize": False}),
        ("SPOT", {"shadow_soft_size": 0.5, "spot_size": 2.5}, {"normalize": False}),
        ("SUN", {"angle": 0.2}, {"normalize": False}),
        ("POINT", {}, {"exposure": 1.5}),
        ("POINT", {}, {"use_temperature": True, "temperature": 3000.0}),
    ],
)
def test_light_power_and_colour_match_what_cycles_renders(tmp_path, kind, shape_settings, variant):
    """A light with Normalize off, exposure or temperature renders in Cycles exactly like a plain
    light (Normalize on, no exposure, no temperature) of the extracted power and colour."""
    power = 1.0 if kind == "SUN" else 10.0
    rendered, desc = _cycles_floor_brightness(tmp_path, kind, power, (1.0, 0.9, 0.8), {**shape_settings, **variant})
    (light,) = desc.lights
    plain, plain_desc = _cycles_floor_brightness(tmp_path, kind, light.power, tuple(light.color), shape_settings)
    assert rendered.max() > 1e-3
    np.testing.assert_allclose(plain, rendered, rtol=2e-3)
    assert plain_desc.lights[0].power == pytest.approx(light.power)


def test_instanced_lights_use_the_instance_transform():
    source = bpy.data.collections.new("Lamps")
    sb.point_light(name="Lamp", power=50, location=(0, 0, 1), collection=source)
    empty = bpy.data.objects.new("LampInstancer", None)
    empty.instance_type, empty.instance_collection, empty.location = "COLLECTION", source, (3, 0, 0)
    bpy.context.scene.collection.objects.link(empty)
    desc = extract()
    assert len(desc.lights) == 1
    np.testing.assert_allclose(desc.lights[0].position, [3, 0, 1])


# --- camera -------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kind, fit, resolution, percentage, aspect, shift",
    [
        ("PERSP", "AUTO", (64, 48), 100, (1, 1), (0, 0)),
        ("PERSP", "VERTICAL", (40, 90), 50, (1, 2), (0.1, -0.2)),
        ("PERSP", "HORIZONTAL", (33, 77), 75, (2, 1), (0, 0.3)),
        ("ORTHO", "AUTO", (50, 80), 100, (1, 1), (0.2, 0)),
        ("ORTHO", "VERTICAL", (120, 40), 50, (1.5, 1), (0, 0)),
    ],
)
def test_camera_matrices_equal_blenders(kind, fit, resolution, percentage, aspect, shift):
    scene = bpy.context.scene
    cam = sb.camera(
        kind=kind, lens=35, ortho_scale=7.5, clip_start=0.5, clip_end=40, location=(2, -5, 3), resolution=resolution
    )
    cam.data.sensor_fit, cam.data.sensor_height = fit, 20
    cam.data.shift_x, cam.data.shift_y = shift
    scene.render.resolution_percentage = percentage
    scene.render.pixel_aspect_x, scene.render.pixel_aspect_y = aspect
    graph = sb.depsgraph()
    camera = extract_scene(graph).camera
    rx, ry = resolution[0] * percentage // 100, resolution[1] * percentage // 100
    assert camera.resolution == (rx, ry) and camera.type == kind
    expected = cam.evaluated_get(graph).calc_matrix_camera(graph, x=rx, y=ry, scale_x=aspect[0], scale_y=aspect[1])
    np.testing.assert_allclose(camera.projection_matrix(), np.array(expected), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(camera.view_matrix(), np.array(cam.matrix_world.inverted()), atol=1e-5)


def test_no_camera_and_empty_scene():
    desc = extract()
    assert desc.camera is None and desc.lights == () and desc.geometry.triangle_count == 0
    assert desc.geometry.positions.shape == (0, 3, 3)


# --- the user's data and the context ------------------------------------------------------------


def _fingerprint() -> dict:
    collections = (
        "objects", "meshes", "materials", "images", "lights", "cameras", "node_groups", "collections", "scenes", "textures"
    )
    fp = {name: sorted(item.name for item in getattr(bpy.data, name)) for name in collections}
    fp["mesh sizes"] = {m.name: (len(m.vertices), len(m.loops), len(m.polygons), m.users) for m in bpy.data.meshes}
    fp["images"] = {i.name: (tuple(i.size), i.is_dirty, i.colorspace_settings.name) for i in bpy.data.images}
    fp["modifiers"] = {o.name: [m.name for m in o.modifiers] for o in bpy.data.objects}
    fp["matrices"] = {o.name: tuple(map(tuple, o.matrix_world)) for o in bpy.data.objects}
    return fp


def test_extraction_leaves_the_users_data_unchanged():
    image = sb.generated_image("Img", 4, 4, (0.5, 0.5, 0.5, 1))
    obj = sb.box("Arrayed", size=1.0, material=sb.principled("WithImage", image=image))
    obj.modifiers.new("Array", "ARRAY").count = 3
    sb.plane("Floor", material=sb.shader_material("Glow", "ShaderNodeEmission"))
    scatter = sb.mesh_object("Scatter", [], [], uv=False)
    _instance_on_points(scatter, count=5, spacing=1.0, cube_size=0.2)
    sb.spot_light()
    sb.camera()
    graph = sb.depsgraph()
    before = _fingerprint()
    for _ in range(2):
        desc = extract_scene(graph)
    assert desc.geometry.triangle_count == 36 + 2 + 60
    assert _fingerprint() == before


def test_extraction_reads_the_given_depsgraph_not_the_context():
    sb.box("InContextScene", size=1.0)
    other = bpy.data.scenes.new("Other")
    sb.plane("InOtherScene", scene=other)
    sb.point_light(name="OtherLamp", power=10, scene=other)
    sb.camera(scene=other, make_active=False)
    other.camera = other.objects["Camera"]
    desc = extract_scene(sb.depsgraph(other))
    assert bpy.context.scene.name == "Scene"
    assert desc.object_names == ("InOtherScene",) and desc.geometry.triangle_count == 2
    assert [light.name for light in desc.lights] == ["OtherLamp"]
    assert desc.camera is not None and desc.camera.name == "Camera"
    # And the Blender-facing module never reaches for the context at all.
    for module in ("scene_extraction.py", "scene_description.py", "scene.py"):
        tree = ast.parse((Path(__file__).resolve().parents[1] / "vsgl_addon" / module).read_text())
        assert not [n for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr == "context"], module


def test_description_module_imports_no_bpy():
    import subprocess
    import sys

    code = "import sys, vsgl_addon.scene, vsgl_addon.scene_description; assert 'bpy' not in sys.modules"
    root = Path(__file__).resolve().parents[1]
    subprocess.run([sys.executable, "-c", code], cwd=root, check=True)


# --- speed --------------------------------------------------------------------------------------


def test_100k_triangles_and_2000_instances_extract_whole():
    sb.plane("Dense", size=10.0, subdivisions=224, material=sb.principled("Floor"))  # 100,352 triangles
    scatter = sb.mesh_object("Scatter", [], [], uv=False, location=(0, 0, 1))
    _instance_on_points(scatter, count=2000, spacing=0.01, cube_size=0.005)  # 24,000 more
    graph = sb.depsgraph()
    extract_scene(graph)  # the first call pays for lazy evaluation (loop triangles, normals)
    start = time.perf_counter()
    desc = extract_scene(graph)
    seconds = time.perf_counter() - start
    assert desc.geometry.triangle_count == 100_352 + 24_000
    assert len(desc.object_names) == 2 + 2000 - 1 and np.isfinite(desc.geometry.positions).all()
    print(f"\nextraction of {desc.geometry.triangle_count} triangles (2000 instances): {seconds * 1000:.0f} ms")


def test_light_node_trees_warn_only_when_they_change_the_light():
    scene = sb.reset()
    sb.plane("Floor", size=4.0)
    plain = sb.spot_light(name="Plain", power=100.0, location=(0, 0, 3))
    plain.data.use_nodes = True  # Blender 5.2 gives new lights this tree: Emission (1, white) -> output
    dimmed = sb.point_light(name="Dimmed", power=100.0, location=(1, 0, 3))
    dimmed.data.use_nodes = True
    next(n for n in dimmed.data.node_tree.nodes if n.type == "EMISSION").inputs["Strength"].default_value = 0.5
    description = extract_scene(sb.depsgraph(scene))
    lines = [line for line in description.warnings if "light node trees" in line]
    assert len(lines) == 1 and "Dimmed" in lines[0] and "Plain" not in lines[0], description.warnings
