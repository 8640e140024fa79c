# SPDX-License-Identifier: GPL-3.0-or-later
"""False positives of tiled VPL culling per bounding volume (004 Fig. 9) on caustic_panel (not a test).

    .venv/bin/python benchmarks/vpl_bounds.py [--delta 1e-3]

The scene's glossy VPLs (benchmarks/vpl_caustics.py collect_vpls) and camera G-buffer (240x180),
16x16 tiles with their depth ranges; per tile the VPLs listed by the ellipsoid-frustum test
(reference.vpl_culling, float64) with three volumes: the GGX spheroid (Eqs. 13-15), the sphere
centred on the VPL that bounds the same range (radius |c - q| + r_u), and the spheroid's enclosing
sphere (centre c, radius r_u). A false positive is a VPL listed for a pixel's tile that the pixel
does not accept (p <= xi). Prints false positives per pixel for each and the spheroid's reduction.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from vpl_caustics import HEIGHT, WIDTH, collect_vpls  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--delta", type=float, default=1e-3)
    args = parser.parse_args(argv)
    import bpy

    from build_validation_scenes import scene_path
    from tradeoff.bench import Bench
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.reference import vpl_culling as vc
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    register()
    ensure_gpu_context()
    bpy.ops.wm.open_mainfile(filepath=str(scene_path("caustic_panel")), load_ui=False)
    settings = VSGLSettings.from_properties(bpy.context.scene.vsgl)
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    bench = Bench(description, WIDTH, HEIGHT)
    try:
        vpls = collect_vpls(bench, description, settings)
        arrays = bench.gbuffer.to_numpy()
    finally:
        bench.free()
    position = arrays["position"].astype(np.float64)
    normal = arrays["normal"][..., :3].astype(np.float64)
    count = len(vpls["roughness"])
    xi = vc.vpl_xi(np.arange(count), 0, 0)
    w2v = np.asarray(description.camera.view_matrix(), np.float64)
    proj = np.asarray(description.camera.projection_matrix(), np.float64)
    inv_proj, v2w = np.linalg.inv(proj), np.linalg.inv(w2v)
    centre, axes, rotation = vc.glossy_bounding_volumes(vpls, args.delta, xi)
    offset = np.linalg.norm(centre - vpls["position"], axis=-1)
    identity = np.broadcast_to(np.eye(3), (count, 3, 3))
    volumes = {"spheroid": (centre, axes, rotation),
               "vpl_sphere": (vpls["position"], np.repeat((axes[:, 0] + offset)[:, None], 3, 1), identity),
               "enclosing_sphere": (centre, np.repeat(axes[:, :1], 3, 1), identity)}
    false_pos = dict.fromkeys(volumes, 0)
    accepted_total = 0
    pixels = 0
    depth = -(position[..., :3] @ w2v[2, :3] + w2v[2, 3])
    for ty in range(0, HEIGHT, 16):
        for tx in range(0, WIDTH, 16):
            sl = (slice(ty, min(ty + 16, HEIGHT)), slice(tx, min(tx + 16, WIDTH)))
            cov = position[sl][..., 3].reshape(-1) > 0.0
            if not cov.any():
                continue
            lo = np.array([tx / WIDTH, ty / HEIGHT]) * 2 - 1
            hi = np.array([min(tx + 16, WIDTH) / WIDTH, min(ty + 16, HEIGHT) / HEIGHT]) * 2 - 1
            d = depth[sl].reshape(-1)[cov]
            planes = vc.tile_frustum_planes(inv_proj, v2w, lo, hi, d.min(), d.max())
            pts = position[sl][..., :3].reshape(-1, 3)[cov]
            nrm = normal[sl].reshape(-1, 3)[cov]
            _, intensity, l2 = vc.glossy_vpl_radiance(
                pts[:, None], nrm[:, None], np.ones((len(pts), 1, 3)), vpls["position"][None], vpls["normal"][None],
                vpls["incoming"][None], vpls["roughness"][None], vpls["flux"][None], vpls["rs"][None])
            accepted = vc.acceptance_probability(intensity, l2, args.delta) > xi[None]
            accepted_total += int(accepted.sum())
            pixels += len(pts)
            for name, volume in volumes.items():
                listed = vc.ellipsoid_frustum_overlap(planes[None], *volume)
                if np.any(accepted & ~listed[None]):
                    raise AssertionError(f"{name} culled an accepted VPL")
                false_pos[name] += int(np.sum(listed[None] & ~accepted))
    print(f"caustic_panel 240x180, {count} VPLs, delta {args.delta:g}: accepted per pixel "
          f"{accepted_total / pixels:.2f}")
    for name, value in false_pos.items():
        print(f"  {name}: false positives per pixel {value / pixels:.2f}")
    reduction = 1.0 - false_pos["spheroid"] / max(false_pos["vpl_sphere"], 1)
    print(f"  spheroid vs VPL-centred sphere: {100 * reduction:.1f} % fewer false positives "
          f"(target >= 90 %: {'met' if reduction >= 0.9 else 'missed'}); vs enclosing sphere "
          f"{100 * (1 - false_pos['spheroid'] / max(false_pos['enclosing_sphere'], 1)):.1f} % fewer")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
