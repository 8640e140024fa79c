# SPDX-License-Identifier: GPL-3.0-or-later
"""Build the validation suite: small scenes that each stress one kind of light path, so that
accuracy is measured on a suite and not only on the demo (benchmarks/validation_suite.py renders
them against their cached Cycles truth).

Every scene: Principled materials only, one camera, a black world (all light is the scene's lights
and their bounces), render size 240x180, point-like lights (radius 0, sun angle 0) as the RSM treats
them, and the add-on's default settings (``scene.vsgl`` is not touched). The builds are
deterministic: no randomness, every placement written out.

    .venv/bin/python tools/build_validation_scenes.py [OUT_DIR] [--only NAME ...]
        (default: benchmarks/scenes/, every scene)

The demo (demo.blend at the top, tools/build_demo_blend.py) is the suite's last member; it is not
rebuilt here.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import bpy
from mathutils import Matrix, Vector

from build_demo_blend import black_world, look_rotation, principled  # tools/, this script's folder

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
SCENE_DIR = REPO / "benchmarks" / "scenes"
RESOLUTION = (240, 180)


# --- Building blocks -----------------------------------------------------------------------------


def _link(obj, material):
    obj.data.materials.append(material)
    return obj


def _plane(name, size, location, rotation, material):
    """A square plane (size × size, or (sx, sy)), rotated by Euler XYZ radians."""
    sx, sy = (size, size) if isinstance(size, (int, float)) else size
    bpy.ops.mesh.primitive_plane_add(size=1.0, location=location, rotation=rotation)
    plane = bpy.context.object
    plane.name = name
    # Scale baked into the mesh, not the object, so normals and areas need no object scale.
    plane.data.transform(Matrix.Diagonal((sx, sy, 1.0, 1.0)))
    return _link(plane, material)


def _box(name, size, location, material, rotation_z=0.0):
    """An axis-aligned box of `size` (x, y, z) with its base centre at `location`, turned about Z."""
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(location[0], location[1], location[2] + size[2] / 2),
                                    rotation=(0.0, 0.0, rotation_z))
    box = bpy.context.object
    box.name = name
    box.data.transform(Matrix.Diagonal((*size, 1.0)))
    return _link(box, material)


def _sphere(name, radius, location, material, segments=32, rings=16):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=segments, ring_count=rings, radius=radius, location=location)
    sphere = bpy.context.object
    sphere.name = name
    bpy.ops.object.shade_smooth()
    return _link(sphere, material)


def _aim(obj, location, target):
    obj.location = location
    obj.rotation_euler = look_rotation(Vector(target) - Vector(location))


def _light(scene, name, kind, energy, location, target=None, color=(1.0, 1.0, 1.0), **settings):
    data = bpy.data.lights.new(name, type=kind)
    data.energy = energy
    data.color = color
    if kind == "SUN":
        data.angle = 0.0
    elif kind != "AREA":
        data.shadow_soft_size = 0.0
    for key, value in settings.items():
        setattr(data, key, value)
    light = bpy.data.objects.new(name, data)
    scene.collection.objects.link(light)
    if target is not None:
        _aim(light, location, target)
    else:
        light.location = location
    return light


def _camera(scene, location, target, lens=30.0):
    data = bpy.data.cameras.new("Camera")
    data.lens = lens
    camera = bpy.data.objects.new("Camera", data)
    scene.collection.objects.link(camera)
    _aim(camera, location, target)
    scene.camera = camera
    return camera


# --- The scenes ----------------------------------------------------------------------------------


def occluder(scene):
    """A spot lights an orange floor patch; a low wall stands between it and a white receiver wall,
    so most of the receiver's bounce light is blocked (without VSGL visibility: too bright there),
    while the low wall's lit-side face is an unoccluded control."""
    floor = principled("Orange floor", (0.8, 0.45, 0.15), roughness=0.5)
    # The same white twice, under two names, so the benchmark's per-material errors tell the
    # occluded receiver from the unoccluded control.
    occluder_white = principled("White occluder", (0.8, 0.8, 0.8), roughness=0.6)
    receiver_white = principled("White receiver", (0.8, 0.8, 0.8), roughness=0.6)
    _plane("Floor", 10.0, (0, 0, 0), (0, 0, 0), floor)
    _box("Occluder", (0.15, 6.0, 1.2), (0.0, 0.0, 0.0), occluder_white)
    _plane("Receiver", (4.0, 6.0), (3.0, 0.0, 2.0), (0, math.radians(-90), 0), receiver_white)
    # 40° cone from 5 m: the floor's lit disc ends 0.7 m before the occluder, whose top stays dark.
    _light(scene, "Spot", "SPOT", 2000.0, (-2.5, 0.0, 5.0), (-2.5, 0.0, 0.0),
           spot_size=math.radians(40), spot_blend=0.2)
    _camera(scene, (-2.0, -7.5, 4.5), (1.2, 0.5, 1.0), lens=28.0)


def sun_courtyard(scene):
    """A sun from behind a glossy wall over a 40 m ground: the wall's courtyard face is in shadow
    and lit only by the sunlit ground and the sunlit opposite wall (one RSM must cover the ground)."""
    ground = principled("Ground", (0.45, 0.42, 0.38), roughness=0.8)
    plaster = principled("Plaster", (0.75, 0.72, 0.65), roughness=0.7)
    glossy = principled("Glossy tiles", (0.35, 0.5, 0.7), roughness=0.2, specular_ior_level=0.8)
    _plane("Ground", 40.0, (0, 0, 0), (0, 0, 0), ground)
    _box("North wall", (8.4, 0.2, 3.5), (0.0, 4.1, 0.0), glossy)
    _box("South wall", (8.4, 0.2, 3.5), (0.0, -4.1, 0.0), plaster)
    _box("East wall", (0.2, 8.0, 3.5), (4.1, 0.0, 0.0), plaster)
    _box("West wall", (0.2, 8.0, 3.5), (-4.1, 0.0, 0.0), plaster)
    # From the north (behind the glossy wall), 40° above the horizon.
    elevation = math.radians(40)
    _light(scene, "Sun", "SUN", 4.0, (0.0, 10.0, 10.0),
           (0.0, 10.0 - math.cos(elevation), 10.0 - math.sin(elevation)))
    _camera(scene, (1.5, -3.6, 1.6), (-0.6, 4.0, 1.6), lens=20.0)


def sun_ground(scene):
    """A sun over an open 60 m ground, the camera looking down at a white block and a red box on it
    from a few metres: the sun's map covers the whole ground, about 40 times the surface the camera
    sees, and the boxes' shaded sides and the ground beside them take their bounce light from the
    few metres around."""
    ground = principled("Ground", (0.5, 0.48, 0.45), roughness=0.8)
    white = principled("White", (0.8, 0.8, 0.8), roughness=0.6)
    red = principled("Red", (0.7, 0.08, 0.05), roughness=0.5)
    _plane("Ground", 60.0, (0, 0, 0), (0, 0, 0), ground)
    _box("Block", (1.0, 1.0, 2.0), (0.0, 0.0, 0.0), white, rotation_z=math.radians(20))
    _box("Red box", (0.8, 0.8, 0.8), (1.4, -0.9, 0.0), red, rotation_z=math.radians(-15))
    # From the south-west, 35° above the horizon: the block's north-east faces are in its shadow.
    elevation, azimuth = math.radians(35), math.radians(225)
    toward = (math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), math.sin(elevation))
    _light(scene, "Sun", "SUN", 3.0, (0.0, 0.0, 10.0),
           (-toward[0], -toward[1], 10.0 - toward[2]))
    _camera(scene, (2.6, 3.1, 3.4), (0.1, -0.3, 0.4), lens=35.0)


def cornell_box(scene):
    """The Cornell box: red and green side walls bleed onto white walls and two blocks, lit by a small
    area light under the ceiling; the blocks occlude part of the bounce."""
    white = principled("White", (0.73, 0.73, 0.73), roughness=0.9)
    red = principled("Red", (0.63, 0.065, 0.05), roughness=0.9)
    green = principled("Green", (0.14, 0.45, 0.09), roughness=0.9)
    _plane("Floor", 2.0, (0, 0, 0), (0, 0, 0), white)
    _plane("Ceiling", 2.0, (0, 0, 2), (math.pi, 0, 0), white)
    _plane("Back wall", 2.0, (0, 1, 1), (math.radians(90), 0, 0), white)
    _plane("Left wall", 2.0, (-1, 0, 1), (0, math.radians(90), 0), red)
    _plane("Right wall", 2.0, (1, 0, 1), (0, math.radians(-90), 0), green)
    _box("Tall block", (0.6, 0.6, 1.2), (-0.35, 0.3, 0.0), white, rotation_z=math.radians(17))
    _box("Short block", (0.6, 0.6, 0.6), (0.35, -0.35, 0.0), white, rotation_z=math.radians(-17))
    _light(scene, "Area", "AREA", 60.0, (0.0, 0.0, 1.98), (0.0, 0.0, 0.0), size=0.5)
    _camera(scene, (0.0, -4.3, 1.0), (0.0, 0.0, 1.0), lens=40.0)


def closed_room(scene):
    """A closed room with a point light inside: every surface both receives and reflects, nothing
    escapes; a table and a glossy ball occlude and reflect."""
    walls = principled("Warm white", (0.8, 0.75, 0.65), roughness=0.7)
    floor = principled("Wood", (0.45, 0.28, 0.15), roughness=0.4)
    ceiling = principled("Ceiling", (0.85, 0.85, 0.85), roughness=0.8)
    blue = principled("Blue", (0.1, 0.2, 0.6), roughness=0.5)
    yellow = principled("Glossy yellow", (0.85, 0.65, 0.1), roughness=0.25)
    _plane("Floor", (5.0, 4.0), (0, 0, 0), (0, 0, 0), floor)
    _plane("Ceiling", (5.0, 4.0), (0, 0, 3), (math.pi, 0, 0), ceiling)
    _plane("North wall", (5.0, 3.0), (0, 2, 1.5), (math.radians(90), 0, 0), walls)
    _plane("South wall", (5.0, 3.0), (0, -2, 1.5), (math.radians(-90), 0, 0), walls)
    _plane("East wall", (3.0, 4.0), (2.5, 0, 1.5), (0, math.radians(-90), 0), walls)
    _plane("West wall", (3.0, 4.0), (-2.5, 0, 1.5), (0, math.radians(90), 0), walls)
    _box("Table", (1.2, 0.8, 0.75), (0.6, 0.4, 0.0), blue)
    _sphere("Ball", 0.35, (-0.8, -0.3, 0.35), yellow)
    _light(scene, "Point", "POINT", 300.0, (1.2, 1.0, 2.4))
    _camera(scene, (-2.2, -1.7, 1.7), (1.0, 1.0, 0.8), lens=18.0)


def caustic_panel(scene):
    """A narrow spot on a polished steel panel (Principled roughness 0.28, GGX α ≈ 0.08) throws a
    caustic onto a white wall: glossy-to-diffuse light concentrated in a small, bright patch."""
    floor = principled("Dark floor", (0.2, 0.2, 0.2), roughness=0.8)
    white = principled("White wall", (0.8, 0.8, 0.8), roughness=0.8)
    steel = principled("Polished steel", (0.56, 0.57, 0.58), roughness=0.28, metallic=1.0)
    _plane("Floor", 8.0, (0, 0, 0), (0, 0, 0), floor)
    _plane("Wall", (6.0, 4.0), (0, 2.0, 2.0), (math.radians(90), 0, 0), white)
    panel_at, spot_at, target = Vector((0.0, -0.5, 0.8)), Vector((0.0, -3.0, 3.2)), Vector((0.0, 2.0, 2.2))
    # The panel's normal halves the angle between the spot and the patch of wall it should light.
    normal = ((spot_at - panel_at).normalized() + (target - panel_at).normalized()).normalized()
    # Large (1.8 × 1.4 m), so that enough of the wall's bounce rays reach it for Cycles to converge.
    panel = _plane("Steel panel", (1.8, 1.4), tuple(panel_at), (0, 0, 0), steel)
    panel.rotation_euler = normal.to_track_quat("Z", "Y").to_euler()
    _light(scene, "Spot", "SPOT", 1500.0, tuple(spot_at), tuple(panel_at),
           spot_size=math.radians(34), spot_blend=0.1)
    _camera(scene, (2.8, -5.0, 2.4), (0.0, 0.8, 1.4), lens=26.0)


def glossy_floor_object(scene):
    """A glossy blue floor under a glossy copper sphere and a glossy white block, lit by a spot from
    the side: each reflects the others' lit sides (glossy-to-glossy), the white wall behind catches
    their bounces."""
    floor = principled("Glossy blue floor", (0.15, 0.25, 0.55), roughness=0.15)
    # Roughness 0.35, not sharper: the copper's caustics on the floor are what Cycles converges slowest on.
    copper = principled("Glossy copper", (0.95, 0.64, 0.54), roughness=0.35, metallic=1.0)
    block = principled("Glossy white", (0.8, 0.8, 0.8), roughness=0.3)
    white = principled("White wall", (0.8, 0.8, 0.8), roughness=0.7)
    _plane("Floor", 8.0, (0, 0, 0), (0, 0, 0), floor)
    _plane("Back wall", (8.0, 4.0), (0, 2.5, 2.0), (math.radians(90), 0, 0), white)
    _sphere("Copper sphere", 0.7, (0.0, 0.3, 0.7), copper, segments=48, rings=24)
    _box("Glossy block", (0.6, 0.6, 0.6), (1.5, -0.4, 0.0), block, rotation_z=math.radians(30))
    _light(scene, "Spot", "SPOT", 1500.0, (-3.0, -1.5, 3.5), (0.3, 0.2, 0.3),
           spot_size=math.radians(50), spot_blend=0.3)
    _camera(scene, (1.5, -5.5, 1.6), (0.3, 0.5, 0.6), lens=30.0)


def polished_metal_floor(scene):
    """A polished metal floor (Principled roughness 0.15, GGX α ≈ 0.02: a rectangle proxy for
    MRP-ASG) lit by a spot, under a glossy gold sphere and a glossy red dielectric block that reflect
    the lit floor (glossy-to-glossy from a sharp planar reflector), and a white wall behind."""
    metal = principled("Polished metal floor", (0.75, 0.75, 0.78), roughness=0.15, metallic=1.0)
    gold = principled("Glossy gold", (0.9, 0.65, 0.25), roughness=0.3, metallic=1.0)
    red = principled("Glossy red", (0.6, 0.08, 0.06), roughness=0.2)
    white = principled("White wall", (0.8, 0.8, 0.8), roughness=0.7)
    _plane("Floor", 8.0, (0, 0, 0), (0, 0, 0), metal)
    _plane("Back wall", (8.0, 4.0), (0, 3.0, 2.0), (math.radians(90), 0, 0), white)
    _sphere("Gold sphere", 0.6, (-0.7, 0.6, 0.6), gold, segments=48, rings=24)
    _box("Red block", (0.7, 0.7, 0.9), (0.9, -0.1, 0.0), red, rotation_z=math.radians(25))
    _light(scene, "Spot", "SPOT", 1500.0, (0.5, -2.5, 3.5), (0.0, 0.3, 0.0),
           spot_size=math.radians(55), spot_blend=0.3)
    _camera(scene, (1.2, -5.5, 1.4), (0.0, 0.4, 0.5), lens=32.0)


def occluded_reflector(scene):
    """A polished metal floor (Principled roughness 0.15: a rectangle proxy for MRP-ASG) lit by a spot
    reflects onto a glossy metal wall (roughness 0.45, GGX α ≈ 0.2); a matte block stands between the
    floor's specular peaks and the wall's lower left, so the floor's reflection there is blocked
    (proxy-to-receiver visibility), while the wall's right half is an unoccluded control."""
    metal = principled("Polished metal floor", (0.75, 0.75, 0.78), roughness=0.15, metallic=1.0)
    # The same metal twice, under two names, so per-material errors tell the shadowed part of the
    # wall (behind the block) from the open one.
    behind = principled("Glossy wall behind block", (0.85, 0.7, 0.45), roughness=0.45, metallic=1.0)
    open_wall = principled("Glossy wall open", (0.85, 0.7, 0.45), roughness=0.45, metallic=1.0)
    grey = principled("Matte block", (0.3, 0.3, 0.3), roughness=0.9)
    _plane("Floor", 8.0, (0, 0, 0), (0, 0, 0), metal)
    _plane("Wall behind block", (3.0, 3.0), (-1.5, 2.5, 1.5), (math.radians(90), 0, 0), behind)
    _plane("Wall open", (3.0, 3.0), (1.5, 2.5, 1.5), (math.radians(90), 0, 0), open_wall)
    # 1.6 m from the wall's foot: the wall's peaks up to ~1.8 m high lie on the floor before it.
    _box("Block", (1.4, 0.25, 0.9), (-0.7, 1.6, 0.0), grey)
    _light(scene, "Spot", "SPOT", 1500.0, (0.0, -2.0, 3.0), (-0.4, 0.8, 0.0),
           spot_size=math.radians(60), spot_blend=0.3)
    _camera(scene, (1.8, -4.5, 1.5), (-0.2, 1.8, 0.8), lens=30.0)


# 24 small point lights, a 6 × 4 grid at two heights, in six colours (deterministic, no randomness).
_PALETTE = [(1.0, 0.55, 0.25), (0.3, 0.55, 1.0), (1.0, 0.9, 0.7), (0.5, 1.0, 0.45), (1.0, 0.35, 0.6),
            (0.8, 0.8, 1.0)]


def many_lights(scene):
    """A room (open at the camera's side) lit by 24 small coloured point lights: many lights, each
    with its own six-face RSM and its own VSGLs, every one of them lighting every receiver."""
    walls = principled("White", (0.78, 0.78, 0.78), roughness=0.7)
    floor = principled("Grey floor", (0.35, 0.35, 0.38), roughness=0.35)
    red = principled("Red", (0.7, 0.1, 0.08), roughness=0.6)
    _plane("Floor", (8.0, 6.0), (0, 0, 0), (0, 0, 0), floor)
    _plane("Ceiling", (8.0, 6.0), (0, 0, 3), (math.pi, 0, 0), walls)
    _plane("Back wall", (8.0, 3.0), (0, 3, 1.5), (math.radians(90), 0, 0), walls)
    _plane("Left wall", (3.0, 6.0), (-4, 0, 1.5), (0, math.radians(90), 0), red)
    _plane("Right wall", (3.0, 6.0), (4, 0, 1.5), (0, math.radians(-90), 0), walls)
    _box("Block", (1.0, 1.0, 1.0), (-1.0, 0.8, 0.0), walls, rotation_z=math.radians(20))
    _box("Pillar", (0.5, 0.5, 2.0), (1.6, 1.4, 0.0), walls)
    index = 0
    for row in range(4):
        for column in range(6):
            x = -3.25 + 1.3 * column
            y = -2.1 + 1.4 * row
            z = 1.9 if (row + column) % 2 else 2.5
            _light(scene, f"Point {index:02d}", "POINT", 12.0, (x, y, z), color=_PALETTE[index % len(_PALETTE)])
            index += 1
    _camera(scene, (0.0, -6.5, 2.0), (0.0, 0.5, 1.2), lens=24.0)


# name -> builder; the builder's doc says what the scene tests. The suite's order.
SCENES = {
    "occluder": occluder,
    "sun_courtyard": sun_courtyard,
    "sun_ground": sun_ground,
    "cornell_box": cornell_box,
    "closed_room": closed_room,
    "caustic_panel": caustic_panel,
    "glossy_floor_object": glossy_floor_object,
    "many_lights": many_lights,
    "polished_metal_floor": polished_metal_floor,
    "occluded_reflector": occluded_reflector,
}


def scene_path(name: str, folder: Path = SCENE_DIR) -> Path:
    return folder / f"{name}.blend"


def purpose(name: str) -> str:
    """What the scene tests, in one line (its builder's doc)."""
    return " ".join(SCENES[name].__doc__.split())


def build(name: str, out: Path) -> None:
    from vsgl_addon import register, unregister

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.name = name
    SCENES[name](scene)
    black_world(scene)
    scene.render.resolution_x, scene.render.resolution_y = RESOLUTION
    scene.render.resolution_percentage = 100
    out.parent.mkdir(parents=True, exist_ok=True)
    bpy.context.preferences.filepaths.save_version = 0  # no .blend1 backup beside a rebuilt scene
    # As demo.blend: saved with the add-on registered, so scene.vsgl exists in the file (here with
    # its defaults, which the suite measures).
    register()
    try:
        bpy.ops.wm.save_as_mainfile(filepath=str(out), compress=True)
    finally:
        unregister()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", nargs="?", type=Path, default=SCENE_DIR)
    parser.add_argument("--only", nargs="+", choices=list(SCENES), help="build only these scenes")
    args = parser.parse_args(argv)
    for name in args.only or SCENES:
        path = scene_path(name, args.out_dir.resolve())
        build(name, path)
        print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
