# SPDX-License-Identifier: GPL-3.0-or-later
"""False positives of tiled VPL culling per bounding volume (004 Fig. 9) on caustic_panel (not a test).

    .venv/bin/python benchmarks/vpl_bounds.py [--delta 1e-3 ...] [--size W H] [--vpl-stride K]

The scene's glossy VPLs (benchmarks/vpl_caustics.py collect_vpls) and camera G-buffer (240x180, or
--size; --vpl-stride K keeps every K-th VPL, an unbiased subsample of the counts for large sizes),
16x16 tiles with their depth ranges and frusta over their covered pixels' centres (the pass's,
reference.vpl_culling.tile_receiver_ndc); per tile the VPLs listed (float64) by two
ellipsoid-frustum tests, the exact one the pass uses (ellipsoid_frustum_overlap_exact) and 004
Eq. 16's plane-by-plane one (ellipsoid_frustum_overlap), with three volumes: the GGX spheroid (Eqs.
13-15), the sphere centred on the VPL that bounds the same range (radius |c - q| + r_u), and the
spheroid's enclosing sphere (centre c, radius r_u). A false positive is a VPL listed for a pixel's
tile that the pixel does not accept (p <= xi). Prints false positives per pixel for each and the
exact-test spheroid's reduction against the VPL-centred sphere under either test, per δ (one ξ per
VPL, shared by every δ, as the pass draws it).

The reduction depends on how far the light ranges reach compared with the tiles' extent in the
scene: δ is in Blender's radiometric units (p = I/(δ l²), Eq. 2), so the same δ gives longer ranges
in a brighter scene, and a tile covers more of the scene at a lower resolution. Both spheres and
the spheroid then list the same far tiles, and the ratio falls; hence the sweep.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from vpl_caustics import HEIGHT, WIDTH, collect_vpls  # noqa: E402

TILE = 16
VOLUMES = ("spheroid", "vpl_sphere", "enclosing_sphere")
TESTS = ("exact", "plane")


def culling_inputs(args):
    """caustic_panel's G-buffer and VPLs at args.size, every args.vpl_stride-th VPL with its ξ, the
    camera's matrices and, per args.delta, the three bounding volumes (shared with vpl_bounds_diag.py)."""
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
    width, height = args.size
    bench = Bench(description, width, height)
    try:
        vpls = collect_vpls(bench, description, settings)
        arrays = bench.gbuffer.to_numpy()
    finally:
        bench.free()
    position = arrays["position"].astype(np.float64)
    normal = arrays["normal"][..., :3].astype(np.float64)
    generated = len(vpls["roughness"])
    # ξ of every generated VPL (Eq. 3's one draw per light), then the subsample.
    keep = np.arange(0, generated, max(args.vpl_stride, 1))
    xi = vc.vpl_xi(np.arange(generated), 0, 0)[keep]
    vpls = {key: np.asarray(value)[keep] for key, value in vpls.items()}
    count = len(keep)
    w2v = np.asarray(description.camera.view_matrix(), np.float64)
    proj = np.asarray(description.camera.projection_matrix(), np.float64)
    inv_proj, v2w = np.linalg.inv(proj), np.linalg.inv(w2v)
    identity = np.broadcast_to(np.eye(3), (count, 3, 3))
    volumes = {}
    for delta in args.delta:
        centre, axes, rotation = vc.glossy_bounding_volumes(vpls, delta, xi)
        offset = np.linalg.norm(centre - vpls["position"], axis=-1)
        # 004 §7: the VPL-centred sphere of radius r_α (the NDF's maximum in Eq. 9), which is the
        # spheroid's farthest point from q, |c − q| + r_u = r/α; the enclosing sphere (c, r_u).
        volumes[delta] = {"spheroid": (centre, axes, rotation),
                          "vpl_sphere": (vpls["position"], np.repeat((axes[:, 0] + offset)[:, None], 3, 1), identity),
                          "enclosing_sphere": (centre, np.repeat(axes[:, :1], 3, 1), identity)}
    return position, normal, vpls, xi, generated, count, inv_proj, v2w, w2v, volumes, vc


def parse_arguments(argv, description: str, deltas: str | int = "+") -> argparse.Namespace:
    """--delta, --size and --vpl-stride, what culling_inputs reads (shared with vpl_bounds_diag.py and
    vpl_bounds_frusta.py)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--delta", type=float, nargs=deltas, default=[1e-3])
    parser.add_argument("--size", type=int, nargs=2, default=[WIDTH, HEIGHT], metavar=("W", "H"))
    parser.add_argument("--vpl-stride", type=int, default=1)
    return parser.parse_args(argv)


def view_depth(position, w2v):
    """Each pixel's view-space depth (distance along the camera's forward axis)."""
    return -(position[..., :3] @ w2v[2, :3] + w2v[2, 3])


class Tile(NamedTuple):
    """One TILE x TILE tile with covered pixels: its first pixel (tx, ty), its covered mask, their
    rows and columns in it, view depths, positions and normals, the pass's receiver NDC rectangle
    over them (tile_receiver_ndc: through the covered pixels' outermost centres), and every VPL's
    glossy intensity and squared distance at them (reference.vpl_culling.glossy_vpl_radiance)."""
    tx: int
    ty: int
    covered: np.ndarray
    ys: np.ndarray
    xs: np.ndarray
    depth: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    ndc: tuple
    intensity: np.ndarray
    l2: np.ndarray


def covered_tiles(position, normal, vpls, depth, width: int, height: int, vc):
    """The image's tiles with covered pixels, row by row (shared with vpl_bounds_diag.py and
    vpl_bounds_frusta.py)."""
    for ty in range(0, height, TILE):
        for tx in range(0, width, TILE):
            sl = (slice(ty, min(ty + TILE, height)), slice(tx, min(tx + TILE, width)))
            covered = position[sl][..., 3] > 0.0
            if not covered.any():
                continue
            ys, xs = np.nonzero(covered)
            pts = position[sl][..., :3][ys, xs]
            nrm = normal[sl][ys, xs]
            ndc = vc.tile_receiver_ndc([tx + xs.min(), ty + ys.min()], [tx + xs.max(), ty + ys.max()], [width, height])
            _, intensity, l2 = vc.glossy_vpl_radiance(
                pts[:, None], nrm[:, None], np.ones((len(pts), 1, 3)), vpls["position"][None], vpls["normal"][None],
                vpls["incoming"][None], vpls["roughness"][None], vpls["flux"][None], vpls["rs"][None])
            yield Tile(tx, ty, covered, ys, xs, depth[sl][ys, xs], pts, nrm, ndc, intensity, l2)


def main(argv=None) -> int:
    args = parse_arguments(argv, __doc__.splitlines()[0])
    width, height = args.size
    position, normal, vpls, xi, generated, count, inv_proj, v2w, w2v, volumes, vc = culling_inputs(args)
    false_pos = {delta: {(name, test): 0 for name in VOLUMES for test in TESTS} for delta in args.delta}
    accepted_total = dict.fromkeys(args.delta, 0)
    pixels = 0
    for tile in covered_tiles(position, normal, vpls, view_depth(position, w2v), width, height, vc):
        d, intensity, l2 = tile.depth, tile.intensity, tile.l2
        planes = vc.tile_frustum_planes(inv_proj, v2w, *tile.ndc, d.min(), d.max())
        corners = vc.tile_frustum_corners(inv_proj, v2w, *tile.ndc, d.min(), d.max())
        pixels += len(tile.points)
        for delta in args.delta:
            accepted = vc.acceptance_probability(intensity, l2, delta) > xi[None]
            accepted_total[delta] += int(accepted.sum())
            for name, volume in volumes[delta].items():
                for test in TESTS:
                    listed = (vc.ellipsoid_frustum_overlap_exact(planes[None], corners[None], *volume)
                              if test == "exact" else vc.ellipsoid_frustum_overlap(planes[None], *volume))
                    if np.any(accepted & ~listed[None]):
                        raise AssertionError(f"{name} ({test} test) culled an accepted VPL at delta {delta:g}")
                    false_pos[delta][name, test] += int(np.sum(listed[None] & ~accepted))
    scale = max(args.vpl_stride, 1)
    print(f"caustic_panel {width}x{height}, {generated} VPLs ({count} counted, every {scale}th; counts "
          f"below are scaled to all), tiles {TILE}x{TILE}")
    print("False positives per pixel, exact test / plane test (004 Eq. 16); the spheroid's reduction is its "
          "exact-test figure against the VPL-centred sphere's under the same test and under the plane test")
    print("| delta | accepted / px | spheroid FP / px | VPL sphere FP / px | enclosing sphere FP / px "
          "| spheroid fewer than VPL sphere, both exact | spheroid (exact) fewer than VPL sphere (plane) "
          "| plane test alone: spheroid fewer than VPL sphere |")
    print("|---|---|---|---|---|---|---|---|")

    def verdict(reduction):
        return f"{100 * reduction:.1f} % ({'met' if reduction >= 0.9 else 'missed'}: target >= 90 %)"

    for delta in args.delta:
        fp = {key: scale * value / pixels for key, value in false_pos[delta].items()}
        like = 1.0 - fp["spheroid", "exact"] / max(fp["vpl_sphere", "exact"], 1e-30)
        against_plane = 1.0 - fp["spheroid", "exact"] / max(fp["vpl_sphere", "plane"], 1e-30)
        plane_only = 1.0 - fp["spheroid", "plane"] / max(fp["vpl_sphere", "plane"], 1e-30)
        pair = {name: f"{fp[name, 'exact']:.1f} / {fp[name, 'plane']:.1f}" for name in VOLUMES}
        print(f"| {delta:g} | {scale * accepted_total[delta] / pixels:.2f} | {pair['spheroid']} | "
              f"{pair['vpl_sphere']} | {pair['enclosing_sphere']} | {verdict(like)} | {verdict(against_plane)} | "
              f"{100 * plane_only:.1f} % |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
