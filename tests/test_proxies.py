# SPDX-License-Identifier: GPL-3.0-or-later
"""Rectangle proxies from a SceneDescription (vsgl_addon/proxies.py): planar regions of sharp
glossy triangles, their oriented rectangles, the per-object override, the light/receiver filter and
the geometry-only cache."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vsgl_addon import proxies as P
from vsgl_addon.scene_description import DEFAULT_MATERIAL, Geometry, Light, Material, SceneDescription


def grid(nu, nv, size_u, size_v, origin=(0, 0, 0), u=(1, 0, 0), v=(0, 1, 0)):
    """A planar grid of 2 nu nv triangles (counter-clockwise about u × v)."""
    u, v, origin = (np.asarray(a, np.float64) for a in (u, v, origin))
    tris = []
    for i in range(nu):
        for j in range(nv):
            p = [origin + (i + a) / nu * size_u * u + (j + b) / nv * size_v * v
                 for a, b in ((0, 0), (1, 0), (1, 1), (0, 1))]
            tris += [(p[0], p[1], p[2]), (p[0], p[2], p[3])]
    return np.array(tris)


def material(name, roughness, metallic=1.0, color=(0.9, 0.6, 0.2)):
    return Material(name, np.array(color, np.float32), roughness, metallic, 0.5, 1.5)


def point_light(position=(0.0, 0.0, 3.0), power=1000.0, kind="POINT", direction=(0, 0, -1.0), **extra):
    m = np.eye(4)
    m[:3, 3] = position
    fields = dict(name="L", type=kind, matrix_world=m, position=np.array(position, float),
                  direction=np.array(direction, float) / np.linalg.norm(direction), color=np.ones(3),
                  power=power, energy=power, exposure=0.0, normalize=True, radius=0.0, spot_size=0.0,
                  spot_blend=0.0, sun_angle=0.0, shape="", size=np.zeros(2), diffuse_factor=1.0,
                  specular_factor=1.0)
    fields.update(extra)
    return Light(**fields)


def scene_of(sets, mats, lights, names=None):
    """sets: list of (triangles, material number (1-based into mats), object index)."""
    positions = np.concatenate([s[0] for s in sets]).astype(np.float32)
    material_index = np.concatenate([np.full(len(s[0]), s[1]) for s in sets]).astype(np.int32)
    object_index = np.concatenate([np.full(len(s[0]), s[2]) for s in sets]).astype(np.int32)
    count = len(positions)
    face = np.cross(positions[:, 1] - positions[:, 0], positions[:, 2] - positions[:, 0])
    face /= np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-30)
    geometry = Geometry(positions, np.repeat(face[:, None], 3, axis=1).astype(np.float32),
                        np.zeros((count, 3, 2), np.float32), material_index, object_index)
    objects = max(s[2] for s in sets) + 1
    names = names or tuple(f"object{i}" for i in range(objects))
    return SceneDescription(geometry, (DEFAULT_MATERIAL, *mats), tuple(lights), None, names)


def floor_scene(roughness=0.1, lights=None, rotate=0.0):
    c, s = math.cos(rotate), math.sin(rotate)
    floor = grid(8, 6, 4.0, 3.0, origin=(-2 * c + 1.5 * s, -2 * s - 1.5 * c, 0), u=(c, s, 0), v=(-s, c, 0))
    box = grid(2, 2, 0.5, 0.5, origin=(0, 0, 1.0))  # something above the floor (a receiver)
    return scene_of([(floor, 1, 0), (box, 2, 1)], (material("Floor", roughness), material("Box", 0.6)),
                    lights if lights is not None else [point_light()])


def test_floor_becomes_one_rectangle():
    scene = floor_scene(0.2, rotate=0.4)  # α = 0.04 < α_c
    proxies = P.build_proxies(scene)
    assert len(proxies) == 1  # the rough box (α = 0.36) is not a candidate
    (proxy, _), = P.lit_proxies(proxies, scene)  # the side the light and the box are on
    assert proxy.triangle_count == 96 and proxy.area == pytest.approx(12.0, rel=1e-5)
    assert sorted((proxy.half_u, proxy.half_v)) == pytest.approx([1.5, 2.0], rel=1e-5)
    np.testing.assert_allclose(proxy.center, [0, 0, 0], atol=1e-5)
    np.testing.assert_allclose(proxy.normal, [0, 0, 1], atol=1e-6)  # the side the box is on
    axis = proxy.axis_u if proxy.half_u > proxy.half_v else proxy.axis_v
    assert abs(abs(axis @ [math.cos(0.4), math.sin(0.4), 0]) - 1.0) < 1e-5
    assert proxy.alpha == pytest.approx(0.04)
    np.testing.assert_allclose(proxy.f0, [0.9, 0.6, 0.2], rtol=1e-6)  # metallic: the base colour
    np.testing.assert_allclose(np.cross(proxy.axis_u, proxy.axis_v), proxy.normal, atol=1e-9)


def test_rough_floor_and_overrides():
    scene = floor_scene(0.5)  # α = 0.25 ≥ α_c
    assert P.build_proxies(scene) == []
    assert len(P.build_proxies(scene, overrides={"object0": "always"})) == 1
    assert P.build_proxies(floor_scene(0.1), overrides={"object0": "never"}) == []
    assert len(P.build_proxies(scene, caustic_roughness=0.3)) == 1


def test_regions_split_by_plane_material_and_connection():
    a = grid(2, 2, 1.0, 1.0, origin=(0, 0, 0))
    b = grid(2, 2, 1.0, 1.0, origin=(3, 0, 0))  # same plane, not connected
    c = grid(2, 2, 1.0, 1.0, origin=(0, 3, 0.5))  # parallel plane
    d = grid(2, 2, 1.0, 1.0, origin=(1, 0, 0))  # connected to a, other material
    wall = grid(2, 2, 1.0, 1.0, origin=(0, 0, 0), u=(1, 0, 0), v=(0, 0, 1))  # connected to a, other plane
    m = material("M", 0.1)
    scene = scene_of([(a, 1, 0), (b, 1, 0), (c, 1, 0), (d, 2, 0), (wall, 1, 0)], (m, material("N", 0.1)),
                     [point_light()])
    proxies = P.build_proxies(scene)
    assert len(proxies) == 5 and all(p.triangle_count == 8 for p in proxies)


def test_l_shape_and_degenerate_input():
    l_shape = np.concatenate([grid(4, 1, 2.0, 0.5), grid(1, 3, 0.5, 1.5, origin=(0, 0.5, 0))])
    scene = scene_of([(l_shape, 1, 0)], (material("M", 0.1),), [point_light()])
    (proxy,) = P.build_proxies(scene)
    assert proxy.half_u * proxy.half_v * 4.0 == pytest.approx(4.0, rel=1e-6)  # 2 × 2 box
    empty = SceneDescription(Geometry.empty(), (DEFAULT_MATERIAL,), (), None, ())
    assert P.build_proxies(empty) == []
    zero = scene_of([(np.zeros((4, 3, 3)), 1, 0)], (material("M", 0.1),), [point_light()])
    assert P.build_proxies(zero) == []


def test_lit_filter():
    scene = floor_scene(0.1)
    proxies = P.ProxyCache().get(scene)
    assert len(P.lit_proxies(proxies, scene)) == 1
    # A light below the floor, with nothing below it to receive; then something below too.
    below = floor_scene(0.1, lights=[point_light((0, 0, -2.0))])
    assert P.lit_proxies(proxies, below) == []
    both = scene_of([(grid(8, 6, 4.0, 3.0, origin=(-2, -1.5, 0)), 1, 0), (grid(2, 2, 0.5, 0.5, origin=(0, 0, 1.0)), 2, 1),
                     (grid(2, 2, 0.5, 0.5, origin=(0, 0, -1.0)), 2, 1)],
                    (material("Floor", 0.1), material("Box", 0.6)), [point_light((0, 0, 3.0)), point_light((0, 0, -2.0))])
    sides = P.lit_proxies(P.build_proxies(both), both)
    assert len(sides) == 2
    assert {tuple(np.round(p.normal, 6)) for p, _ in sides} == {(0.0, 0.0, 1.0), (0.0, 0.0, -1.0)}
    assert [m.tolist() for p, m in sorted(sides, key=lambda s: -s[0].normal[2])] == [[True, False], [False, True]]
    # A spot aimed away from the floor, a sun from below, no receiver in front.
    spot = point_light((0, 0, 3.0), kind="SPOT", direction=(0, 0, 1.0), spot_size=math.radians(30), spot_blend=0.1)
    m = np.eye(4)
    m[:3, :3] = np.diag([1.0, -1.0, -1.0])  # local -Z = world +Z
    m[:3, 3] = (0, 0, 3.0)
    spot = Light(**{**spot.__dict__, "matrix_world": m})
    assert P.lit_proxies(proxies, floor_scene(0.1, lights=[spot])) == []
    sun = point_light(kind="SUN", direction=(0, 0, 1.0))
    assert P.lit_proxies(proxies, floor_scene(0.1, lights=[sun])) == []
    alone = scene_of([(grid(2, 2, 1.0, 1.0), 1, 0)], (material("M", 0.1),), [point_light()])
    assert P.lit_proxies(P.ProxyCache().get(alone), alone) == []


def test_cache_rebuilds_only_on_geometry_change():
    cache = P.ProxyCache()
    scene = floor_scene(0.1)
    cache.get(scene)
    moved_light = floor_scene(0.1, lights=[point_light((1.0, 0.5, 2.0))])
    cache.get(moved_light)
    assert cache.builds == 1
    cache.get(floor_scene(0.1, rotate=0.2))
    assert cache.builds == 2
    cache.get(floor_scene(0.12, rotate=0.2))  # a material change
    assert cache.builds == 3


def test_smooth_shaded_facets_are_not_proxies():
    floor = grid(2, 2, 2.0, 2.0)
    scene = scene_of([(floor, 1, 0)], (material("M", 0.1),), [point_light()])
    bent = np.array(scene.geometry.normals)
    bent[:, 0] = [0.3, 0.0, 0.954]  # one corner normal tilted, as smooth shading of a curved surface does
    smooth = SceneDescription(Geometry(scene.geometry.positions, bent.astype(np.float32), scene.geometry.uvs,
                                       scene.geometry.material_index, scene.geometry.object_index),
                              scene.materials, scene.lights, None, scene.object_names)
    assert len(P.build_proxies(scene)) == 1 and P.build_proxies(smooth) == []


def test_statistics_rows_and_debug_outlines():
    scene = floor_scene(0.2)
    scene = SceneDescription(scene.geometry, scene.materials, scene.lights, None, ("Floor", "Box"))
    proxies = P.build_proxies(scene, overrides={"Box": "always"})  # the rough box top too: unlit
    assert len(proxies) == 2
    lit = P.lit_proxies(proxies, scene)
    (row,) = P.describe_proxies(lit, scene)
    assert row["object"] == "Floor" and row["material"] == "Floor" and row["lit_by"] == ["L"]
    assert sorted(row["size"]) == pytest.approx([3.0, 4.0]) and row["area"] == pytest.approx(12.0, rel=1e-5)
    assert row["roughness"] == pytest.approx(0.2) and row["alpha"] == pytest.approx(0.04)
    assert row["normal"] == pytest.approx([0.0, 0.0, 1.0])
    assert P.describe_row(row).startswith("Floor: ") and row["lit_by"][0] in P.describe_row(row)
    positions, colours = P.outline_lines(proxies, lit)
    # Four edges per rectangle, one normal tick for the lit side.
    assert positions.shape == (2 * (4 * 2 + 1), 3) and colours.shape == (len(positions), 4)
    floor = next(p for p in proxies if p.object_index == 0)
    edges = positions[:16].reshape(2, 4, 2, 3)
    lit_rect = 0 if proxies[0] is floor else 1
    np.testing.assert_allclose(edges[lit_rect, :, 0], floor.corners(), atol=1e-6)
    np.testing.assert_allclose(edges[lit_rect, :, 1], np.roll(floor.corners(), -1, axis=0), atol=1e-6)
    np.testing.assert_array_equal(colours[8 * lit_rect:8 * lit_rect + 8], np.tile(np.float32(P.OUTLINE_LIT), (8, 1)))
    np.testing.assert_array_equal(colours[8 * (1 - lit_rect):8 * (1 - lit_rect) + 8],
                                  np.tile(np.float32(P.OUTLINE_UNLIT), (8, 1)))
    tick = positions[16:]
    np.testing.assert_allclose(tick[0], floor.center, atol=1e-6)
    assert tick[1][2] == pytest.approx(0.5 * min(floor.half_u, floor.half_v))  # along +z, the lit side
    empty = P.outline_lines([], [])
    assert empty[0].shape == (0, 3) and empty[1].shape == (0, 4)
