# SPDX-License-Identifier: GPL-3.0-or-later
"""Where tiled spheroid culling's false positives come from, by tile frustum (not a test; diagnoses
vpl_bounds.py).

    .venv/bin/python benchmarks/vpl_bounds_frusta.py [--delta 1e-3] [--size W H] [--vpl-stride K]

Same VPLs, xi, G-buffer, 16x16 tiles and exact ellipsoid-frustum test as vpl_bounds.py, at one δ.
Tiles are grouped as full (16x16 pixels inside the image, all covered), sky (16x16, some pixels
without a receiver), edge (a partial tile at the image's border, all covered) and edge + sky. Per
group and in all, false positives per pixel of the three volumes with the tile frustum built:
through the tile's pixel edges (the pass before), the same without clipping a partial tile to the
image (16 rows and columns whatever the image holds), through the tile's outermost pixel centres,
and through the covered pixels' outermost centres (reference tile_receiver_ndc, the pass's); last,
for the spheroid, listing a VPL only if one of the tile's receivers lies inside it (the best any
per-tile list can do). Also the largest distance of a receiver from its pixel's centre ray, in
pixels (the frustum through the centres relies on it being small against PIXEL_MARGIN).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from vpl_bounds import TILE, VOLUMES, covered_tiles, culling_inputs, parse_arguments, view_depth  # noqa: E402

FRUSTA = ("pixel edges", "unclipped", "tile centres", "covered centres")


def main(argv=None) -> int:
    args = parse_arguments(argv, __doc__.splitlines()[0], 1)
    width, height = args.size
    size = np.array([width, height])
    position, normal, vpls, xi, generated, count, inv_proj, v2w, w2v, volumes, vc = culling_inputs(args)
    delta = args.delta[0]
    projection = np.linalg.inv(inv_proj)
    groups: dict[str, dict] = {}
    off_centre = 0.0
    for tile in covered_tiles(position, normal, vpls, view_depth(position, w2v), width, height, vc):
        tx, ty, covered, ys, xs, d, pts = tile.tx, tile.ty, tile.covered, tile.ys, tile.xs, tile.depth, tile.points
        whole = covered.shape == (TILE, TILE)
        group = {(True, True): "full", (True, False): "sky", (False, True): "edge",
                 (False, False): "edge + sky"}[whole, bool(covered.all())]
        clip = (np.c_[pts, np.ones(len(pts))] @ w2v.T) @ projection.T
        pixel = (clip[:, :2] / clip[:, 3:] + 1.0) / 2.0 * size - np.c_[tx + xs, ty + ys] - 0.5
        off_centre = max(off_centre, float(np.abs(pixel).max()))
        accepted = vc.acceptance_probability(tile.intensity, tile.l2, delta) > xi[None]
        tally = groups.setdefault(group, {"tiles": 0, "pixels": 0})
        tally["tiles"] += 1
        tally["pixels"] += len(pts)
        rects = {"pixel edges": (np.array([tx, ty]) / size * 2 - 1,
                                 np.minimum([tx + TILE, ty + TILE], size) / size * 2 - 1),
                 "unclipped": (np.array([tx, ty]) / size * 2 - 1, np.array([tx + TILE, ty + TILE]) / size * 2 - 1),
                 "tile centres": vc.tile_receiver_ndc([tx, ty], np.minimum([tx + TILE, ty + TILE], size) - 1, size),
                 "covered centres": tile.ndc}
        for frustum, (lo, hi) in rects.items():
            planes = vc.tile_frustum_planes(inv_proj, v2w, lo, hi, d.min(), d.max())
            corners = vc.tile_frustum_corners(inv_proj, v2w, lo, hi, d.min(), d.max())
            for name in VOLUMES:
                listed = vc.ellipsoid_frustum_overlap_exact(planes[None], corners[None], *volumes[delta][name])
                if np.any(accepted & ~listed[None]):
                    raise AssertionError(f"{name} ({frustum}) culled an accepted VPL")
                key = (name, frustum)
                tally[key] = tally.get(key, 0) + int(np.sum(listed[None] & ~accepted))
        c, a, rotation = volumes[delta]["spheroid"]
        local = np.einsum("vij,pvj->pvi", rotation, pts[:, None, :] - c[None]) / a[None]
        inside = (np.sum(local ** 2, axis=-1) <= 1.0).any(axis=0)
        tally["any receiver inside"] = tally.get("any receiver inside", 0) + int(np.sum(inside[None] & ~accepted))
    scale = max(args.vpl_stride, 1)
    total = {"tiles": 0, "pixels": 0}
    for tally in groups.values():
        for key, value in tally.items():
            total[key] = total.get(key, 0) + value
    pixels = total["pixels"]
    print(f"caustic_panel {width}x{height}, delta {delta:g}, {generated} VPLs ({count} counted, every {scale}th), "
          f"tiles {TILE}x{TILE}; receivers lie within {off_centre:.2g} px of their pixel's centre ray")
    print("False positives per pixel (the group's share of all covered pixels' mean), exact test, by tile frustum")
    print("| tiles | count | pixels | volume | " + " | ".join(FRUSTA) + " | any receiver inside |")
    print("|---|---|---|---|" + "---|" * (len(FRUSTA) + 1))
    for group, tally in list(sorted(groups.items())) + [("all", total)]:
        for name in VOLUMES:
            cells = " | ".join(f"{scale * tally[name, f] / pixels:.1f}" for f in FRUSTA)
            inside = f"{scale * tally['any receiver inside'] / pixels:.1f}" if name == "spheroid" else ""
            print(f"| {group} | {tally['tiles']} | {tally['pixels']} | {name} | {cells} | {inside} |")
    for frustum in FRUSTA:
        reduction = 1.0 - total["spheroid", frustum] / max(total["vpl_sphere", frustum], 1)
        print(f"{frustum}: spheroid {100 * reduction:.2f} % fewer than the VPL-centred sphere (same frustum)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
