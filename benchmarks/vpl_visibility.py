# SPDX-License-Identifier: GPL-3.0-or-later
"""VPL visibility (passes/vpl_culling.py: one imperfect shadow map per cluster of VPLs) against exact,
ray-cast visibility, on a caustic scene with an occluder (not a test).

    .venv/bin/python benchmarks/vpl_visibility.py [--size 80x60] [--rsm-size 64]
    .venv/bin/python benchmarks/vpl_visibility.py --scene polished_metal_floor --vpls 400

The scene: a spot on a polished metal panel (GGX α 0.04) throws its caustic onto a white wall; a box
between panel and wall shadows part of it. The glossy VPLs of the RSM (every texel of the panel) are
shaded onto the camera G-buffer's diffuse receivers by brute force (δ = 0: every VPL, no interleave,
no filter) three ways: the GPU pass with the clusters' shadow maps, the float64 reference
(reference.vpl_culling.glossy_vpl_radiance) with each VPL-receiver segment ray-cast against every
triangle (exact), and the reference unshadowed. Figures over the covered pixels: relative RMSE and
mean of the ISM image against the exact one, next to the unshadowed image's (what visibility must
remove), and the share of the exact image's light inside the shadow. Writes
benchmarks/results/vpl_visibility.{md,json}. With --scene, a validation-suite scene (its saved
settings; --vpls draws a random subset, so that ray casting every segment stays minutes) into
vpl_visibility_<scene>.{md,json}.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

RESULTS = REPO / "benchmarks" / "results"


def build_scene():
    import scene_builders as sb

    scene = sb.reset()
    sb.plane("Floor", size=6.0, material=sb.principled("Floor", base_color=(0.3, 0.3, 0.3), roughness=0.8),
             location=(0.0, 0.0, -0.5))
    sb.plane("Wall", size=6.0, material=sb.principled("Wall", base_color=(0.8, 0.8, 0.8), roughness=0.8),
             location=(0.0, 2.0, 1.0), rotation=(np.radians(90.0), 0.0, 0.0))
    sb.plane("Panel", size=1.0, material=sb.principled("Steel", base_color=(0.6, 0.6, 0.6), roughness=0.2,
                                                       metallic=1.0), rotation=(np.radians(-30.0), 0.0, 0.0))
    # In the panel's mirror path (the caustic lands on the floor in front of the wall), covering part of it.
    sb.box("Occluder", size=(0.35, 0.1, 0.3), location=(0.2, 1.0, -0.2),
           material=sb.principled("Occluder", base_color=(0.5, 0.5, 0.5), roughness=0.8))
    sb.spot_light(power=1500.0, location=(0.0, -2.0, 2.0), look_at_point=(0.0, 0.0, 0.0), spot_size=0.5)
    sb.camera(location=(2.5, -3.5, 1.5), look_at_point=(0.0, 1.0, 0.5))
    return scene


def segment_blocked(origins, targets, triangles, epsilon=1e-4) -> np.ndarray:
    """(N,) bool: the open segment origin -> target crosses a triangle (Möller-Trumbore, float64)."""
    d = targets - origins
    blocked = np.zeros(len(origins), bool)
    for p0, p1, p2 in triangles:
        e1, e2 = p1 - p0, p2 - p0
        h = np.cross(d, e2)
        a = h @ e1
        ok = np.abs(a) > 1e-12
        f = np.where(ok, 1.0 / np.where(ok, a, 1.0), 0.0)
        s = origins - p0
        u = f * np.einsum("ij,ij->i", s, h)
        q = np.cross(s, e1)
        v = f * np.einsum("ij,ij->i", d, q)
        t = f * (q @ e2)
        blocked |= ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > epsilon) & (t < 1.0 - epsilon)
    return blocked


def bvh_blocked(triangles):
    """A ray caster for scenes of thousands of triangles (mathutils' BVH, float32 inside):
    (origin (3,), targets (N, 3)) -> (N,) bool, the open segment crosses a triangle."""
    from mathutils import Vector
    from mathutils.bvhtree import BVHTree

    flat = np.asarray(triangles, np.float64).reshape(-1, 3)
    tree = BVHTree.FromPolygons(flat.tolist(), [(3 * i, 3 * i + 1, 3 * i + 2) for i in range(len(flat) // 3)],
                                epsilon=0.0)

    def blocked(origin, targets, epsilon=1e-4):
        out = np.zeros(len(targets), bool)
        start = Vector(origin)
        for i, target in enumerate(targets):
            offset = Vector(target - origin)
            length = offset.length
            hit = tree.ray_cast(start, offset / length, length) if length > 2 * epsilon else (None,)
            out[i] = hit[0] is not None and epsilon < hit[3] < length - epsilon
        return out

    return blocked


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="80x60")
    parser.add_argument("--rsm-size", type=int, default=64)
    parser.add_argument("--ism-size", type=int, default=64)
    parser.add_argument("--ism-points", type=int, default=4096)
    parser.add_argument("--scene", help="a validation-suite scene instead (its saved RSM and ISM settings, "
                                        "BVH ray casting); results go to vpl_visibility_<scene>.{md,json}")
    parser.add_argument("--vpls", type=int, default=0,
                        help="shade this many VPLs drawn at random (flux scaled by all / drawn), 0: all")
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))

    import scene_builders as sb
    from gpu_timing import finish
    from tradeoff.bench import Bench
    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.passes import vpl_culling
    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.reference import vpl_culling as reference
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    ensure_gpu_context()
    if args.scene:
        import bpy
        from build_validation_scenes import scene_path
        from vsgl_addon import register

        register()
        bpy.ops.wm.open_mainfile(filepath=str(scene_path(args.scene)), load_ui=False)
        settings = VSGLSettings.from_properties(bpy.context.scene.vsgl)
        description = extract_scene(bpy.context.evaluated_depsgraph_get())
    else:
        description = extract_scene(sb.depsgraph(build_scene()))
        settings = VSGLSettings(rsm_size=args.rsm_size, ism_size=args.ism_size, ism_points=args.ism_points)
    bench = Bench(description, width, height)
    try:
        vpls = vpl_culling.scene_vpls(bench.scene_gpu, settings.rsm_size, settings.caustic_roughness)
        found = len(vpls["roughness"])
        if 0 < args.vpls < found:
            drawn = np.sort(np.random.default_rng(0).choice(found, args.vpls, replace=False))
            vpls = {key: np.asarray(value)[drawn] for key, value in vpls.items()}
            vpls["flux"] = vpls["flux"] * (found / args.vpls)
        visible = vpl_culling.upload_visible_vpls(vpls, bench.scene_gpu, settings, settings.rsm_size)
        camera = description.camera
        result = vpl_culling.run(bench.inputs.position, bench.inputs.normal, bench.inputs.diffuse_reflectance,
                                 visible, camera.view_matrix(), camera.projection_matrix(), 0.0)
        finish(result.radiance)
        ism_image = result.read()[..., :3].astype(np.float64)
        maps = visible.isms.count
        result.free()
        visible.free()
        position = read_texture(bench.inputs.position, width, height)
        normal = read_texture(bench.inputs.normal, width, height)[..., :3].astype(np.float64)
        albedo = read_texture(bench.inputs.diffuse_reflectance, width, height)[..., :3].astype(np.float64)
    finally:
        bench.free()
    covered = position[..., 3] > 0.0
    receivers = position[..., :3].astype(np.float64)[covered]
    normals, albedos = normal[covered], albedo[covered]
    triangles = description.geometry.positions.astype(np.float64)
    blocked_from = bvh_blocked(triangles) if args.scene else (
        lambda origin, targets: segment_blocked(np.broadcast_to(origin, targets.shape), targets, triangles))
    exact = np.zeros((len(receivers), 3))
    unshadowed = np.zeros_like(exact)
    for k in range(len(vpls["roughness"])):
        radiance, _, _ = reference.glossy_vpl_radiance(
            receivers, normals, albedos, vpls["position"][k], vpls["normal"][k], vpls["incoming"][k],
            vpls["roughness"][k], vpls["flux"][k], vpls["rs"][k])
        lit = radiance.max(axis=-1) > 0.0
        unshadowed += radiance
        if lit.any():
            blocked = blocked_from(vpls["position"][k], receivers[lit])
            shown = radiance[lit]
            shown[blocked] = 0.0
            exact[lit] += shown
    ours = ism_image[covered]
    mean = float(exact.mean())

    def rel(image):
        return float(np.sqrt(np.mean((image - exact) ** 2)) / mean)

    shadow_share = 1.0 - float(exact.sum() / unshadowed.sum())
    rows = {"scene": args.scene or "panel_occluder", "size": [width, height], "rsm_size": settings.rsm_size,
            "vpls": int(len(vpls["roughness"])), "vpls_found": found,
            "maps": int(maps), "ism_size": settings.ism_size, "ism_points": settings.ism_points,
            "shadowed_share_of_unshadowed_light": shadow_share,
            "ism": {"rel": rel(ours), "mean_ratio": float(ours.mean() / mean)},
            "unshadowed": {"rel": rel(unshadowed), "mean_ratio": float(unshadowed.mean() / mean)}}
    RESULTS.mkdir(parents=True, exist_ok=True)
    stem = f"vpl_visibility_{args.scene}" if args.scene else "vpl_visibility"
    (RESULTS / f"{stem}.json").write_text(json.dumps(rows, indent=2))
    command = (f"--scene {args.scene} --size {width}x{height}" if args.scene else
               f"--size {width}x{height} --rsm-size {settings.rsm_size} --ism-size {settings.ism_size} "
               f"--ism-points {settings.ism_points}") + (f" --vpls {args.vpls}" if args.vpls else "")
    text = "\n".join([
        f"# VPL visibility ({rows['scene']}): the clusters' imperfect shadow maps against ray-cast visibility", "",
        f"`.venv/bin/python benchmarks/vpl_visibility.py {command}`: "
        f"{rows['vpls']} of {found} glossy VPLs (brute force, δ = 0, no filter), {maps} maps of {settings.ism_size}², "
        f"{settings.ism_points} points each; the occluder takes {100 * shadow_share:.1f} % of the unshadowed light.", "",
        "| image | rel RMSE vs exact | mean / exact |", "|---|---|---|",
        f"| ISM per VPL cluster (the pass) | {rows['ism']['rel']:.3f} | {rows['ism']['mean_ratio']:.3f} |",
        f"| unshadowed | {rows['unshadowed']['rel']:.3f} | {rows['unshadowed']['mean_ratio']:.3f} |", ""])
    (RESULTS / f"{stem}.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
