# SPDX-License-Identifier: GPL-3.0-or-later
"""Build demo.blend: what the add-on is for, in one small scene.

A spot light lights a glossy red floor; the floor throws red glossy (and diffuse) bounce light
onto two white walls and onto a glossy gold sphere, which also catches the floor's reflection.
The lights are points (radius 0) because the RSM treats them as such; the world is black, so all
light in the image is the spot's direct light and its bounces. Saved with the add-on's settings.

    .venv/bin/python tools/build_demo_blend.py [OUT.blend]     (default: demo.blend at the top)
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import bpy

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def principled(name, base_color, roughness, metallic=0.0, specular_ior_level=0.5):
    material = bpy.data.materials.new(name)
    if material.node_tree is None:
        material.use_nodes = True
    bsdf = next(node for node in material.node_tree.nodes if node.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Base Color"].default_value = (*base_color, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Specular IOR Level"].default_value = specular_ior_level
    material.diffuse_color = (*base_color, 1.0)
    return material


def black_world(scene):
    """A black world (no light from the background): the indirect light is the lights' alone."""
    world = bpy.data.worlds.new("Black")
    world.color = (0.0, 0.0, 0.0)
    if world.node_tree is None:
        world.use_nodes = True
    background = next((n for n in world.node_tree.nodes if n.type == "BACKGROUND"), None)
    if background is not None:
        background.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    scene.world = world


def _plane(name, size, location, rotation, material):
    bpy.ops.mesh.primitive_plane_add(size=size, location=location, rotation=rotation)
    plane = bpy.context.object
    plane.name = name
    plane.data.materials.append(material)
    return plane


def build(out: Path) -> None:
    from vsgl_addon import register, unregister

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.name = "VSGL demo"

    floor = principled("Glossy red floor", (0.8, 0.08, 0.03), roughness=0.25)
    white = principled("White wall", (0.8, 0.8, 0.8), roughness=0.6)
    gold = principled("Glossy gold", (0.9, 0.65, 0.25), roughness=0.3, metallic=1.0)

    _plane("Floor", 6.0, (0, 0, 0), (0, 0, 0), floor)
    _plane("Back wall", 6.0, (0, 3, 3), (math.radians(90), 0, 0), white)
    _plane("Left wall", 6.0, (-3, 0, 3), (0, math.radians(90), 0), white)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=0.8, location=(0.6, 0.2, 0.8))
    sphere = bpy.context.object
    sphere.name = "Gold sphere"
    bpy.ops.object.shade_smooth()
    sphere.data.materials.append(gold)

    spot_data = bpy.data.lights.new("Spot", type="SPOT")
    spot_data.energy = 1500.0
    spot_data.spot_size = math.radians(45)
    spot_data.spot_blend = 0.25
    spot_data.shadow_soft_size = 0.0
    spot = bpy.data.objects.new("Spot", spot_data)
    scene.collection.objects.link(spot)
    spot.location = (0.8, -1.2, 4.5)
    spot.rotation_euler = look_rotation((-1.2, 1.7, -4.5))

    camera_data = bpy.data.cameras.new("Camera")
    camera_data.lens = 30.0
    camera = bpy.data.objects.new("Camera", camera_data)
    scene.collection.objects.link(camera)
    camera.location = (3.4, -4.4, 2.4)
    camera.rotation_euler = look_rotation((-4.0, 5.0, -1.4))
    scene.camera = camera

    black_world(scene)

    scene.render.resolution_x, scene.render.resolution_y = 480, 360
    scene.render.resolution_percentage = 100

    register()
    try:
        scene.vsgl.vsgl_count = 256
        scene.vsgl.k = 1.0
        scene.vsgl.kernel = "MODIFIED"
        scene.vsgl.rsm_size = 128
        scene.vsgl.seed = 0
        scene.vsgl.positional_distribution = "PER_LOBE"
        bpy.ops.wm.save_as_mainfile(filepath=str(out), compress=True)
    finally:
        unregister()


def look_rotation(direction):
    from mathutils import Vector

    return Vector(direction).to_track_quat("-Z", "Y").to_euler()


if __name__ == "__main__":
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else REPO / "demo.blend"
    build(target.resolve())
    print(f"wrote {target}")
