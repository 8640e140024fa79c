# SPDX-License-Identifier: GPL-3.0-or-later
"""Why tiled spheroid culling keeps false positives on caustic_panel (not a test; diagnoses vpl_bounds.py).

    .venv/bin/python benchmarks/vpl_bounds_diag.py [--delta 1e-3 1e-2] [--size W H] [--vpl-stride K]

Same VPLs, xi, G-buffer and 16x16 tiles as vpl_bounds.py. Prints the tiles' view-depth spans and,
for the spheroid only, false positives per pixel with: the tile frustum (vpl_bounds.py's figure);
the tile split into 8 equal depth sub-ranges, empty ones skipped, each pixel tested against its
sub-range's frustum (2.5D culling); listing a VPL for a tile only when one of the tile's pixels lies
inside the spheroid (the best any per-tile list can do); and per pixel, the pixel inside the
spheroid or inside the VPL-centred sphere (the volumes' own tightness, no tiles).
Last, the tile frustum sampled (each covered pixel's view ray at 16 depths over the tile's range), a
lower bound on what an exact ellipsoid-frustum test would list.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from vpl_bounds import covered_tiles, culling_inputs, parse_arguments, view_depth  # noqa: E402


def main(argv=None) -> int:
    args = parse_arguments(argv, __doc__.splitlines()[0])
    width, height = args.size
    position, normal, vpls, xi, generated, count, inv_proj, v2w, w2v, volumes, vc = culling_inputs(args)
    BINS = 8  # depth sub-ranges per tile for the 2.5D variant
    fp = {d: 0 for d in args.delta}; fp25 = {d: 0 for d in args.delta}; fppt = {d: 0 for d in args.delta}; fpany = {d: 0 for d in args.delta}; fpsph = {d: 0 for d in args.delta}; fpvol = {d: 0 for d in args.delta}; acc = {d: 0 for d in args.delta}
    spans = []; tile_px = []
    pixels = 0
    depth = view_depth(position, w2v)
    for tile in covered_tiles(position, normal, vpls, depth, width, height, vc):
        d, pts, intensity, l2 = tile.depth, tile.points, tile.intensity, tile.l2
        spans.append(d.max() - d.min()); tile_px.append(len(d))
        planes = vc.tile_frustum_planes(inv_proj, v2w, *tile.ndc, d.min(), d.max())
        edges = np.linspace(d.min(), d.max(), BINS + 1)
        b = np.clip(np.searchsorted(edges, d, side="right") - 1, 0, BINS - 1)
        sub = {}
        for k in np.unique(b):
            dk = d[b == k]
            sub[k] = vc.tile_frustum_planes(inv_proj, v2w, *tile.ndc, dk.min(), dk.max())
        pixels += len(pts)
        for delta in args.delta:
            accepted = vc.acceptance_probability(intensity, l2, delta) > xi[None]
            acc[delta] += int(accepted.sum())
            vol = volumes[delta]["spheroid"]
            listed = vc.ellipsoid_frustum_overlap(planes[None], *vol)
            fp[delta] += int(np.sum(listed[None] & ~accepted))
            c, a, R = vol
            u = np.einsum("vij,pvj->pvi", R, pts[:, None, :] - c[None])
            inside = np.sum((u / a[None]) ** 2, axis=-1) <= 1.0
            fppt[delta] += int(np.sum(inside & ~accepted))
            fpany[delta] += int(np.sum(inside.any(axis=0)[None] & ~accepted))
            cam = v2w[:3, 3]
            ts = np.linspace(d.min(), d.max(), 16)
            samp = (cam + (pts - cam)[:, None, :] * (ts[None, :, None] / d[:, None, None])).reshape(-1, 3)
            hit = np.zeros(len(c), bool)
            for s0 in range(0, len(samp), 512):
                uu = np.einsum("vij,pvj->pvi", R, samp[s0:s0+512, None, :] - c[None])
                hit |= (np.sum((uu / a[None]) ** 2, axis=-1) <= 1.0).any(axis=0)
            fpvol[delta] += int(np.sum(hit[None] & ~accepted))
            cs, as_, _ = volumes[delta]["vpl_sphere"]
            insph = np.sum((pts[:, None, :] - cs[None]) ** 2, axis=-1) <= as_[None, :, 0] ** 2
            fpsph[delta] += int(np.sum(insph & ~accepted))
            for k, pl in sub.items():
                lk = vc.ellipsoid_frustum_overlap(pl[None], *vol)
                m = b == k
                assert not np.any(accepted[m] & ~lk[None])
                fp25[delta] += int(np.sum(lk[None] & ~accepted[m]))
    scale = max(args.vpl_stride, 1)
    spans = np.array(spans); tile_px = np.array(tile_px)
    print(f"{width}x{height} stride {scale}: {len(spans)} covered tiles; depth span median {np.median(spans):.3f} m, "
          f"p90 {np.percentile(spans, 90):.3f} m, max {spans.max():.3f} m; depth of scene {depth[position[...,3]>0].min():.3f}-{depth[position[...,3]>0].max():.3f} m")
    for x in (0.1, 0.25, 0.5, 1.0, 2.0):
        print(f"  tiles with span > {x} m: {100*np.mean(spans > x):.1f} % of tiles, {100*tile_px[spans > x].sum()/tile_px.sum():.1f} % of pixels")
    for delta in args.delta:
        print(f"delta {delta:g}: accepted/px {scale*acc[delta]/pixels:.2f}, spheroid FP/px 2D {scale*fp[delta]/pixels:.1f}, "
              f"2.5D ({BINS} depth bins) {scale*fp25[delta]/pixels:.1f}, exact tile (any pixel inside) {scale*fpany[delta]/pixels:.1f}, per-pixel point in spheroid {scale*fppt[delta]/pixels:.1f}, per-pixel point in VPL sphere {scale*fpsph[delta]/pixels:.1f}, sampled frustum volume {scale*fpvol[delta]/pixels:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
