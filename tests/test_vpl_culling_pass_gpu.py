# SPDX-License-Identifier: GPL-3.0-or-later
"""The tiled culling + shading compute pass (vsgl_addon/passes/vpl_culling.py) on llvmpipe against
the float64 reference: the image equals shading every accepted VPL without culling for the same xi
(culling exactness), delta -> 0 equals brute force, the tile lists hold every VPL a pixel of the
tile accepts and match the reference's spheroid lists, and empty inputs give black, finite images."""

from __future__ import annotations

import numpy as np
import pytest

from test_reference_vpl_culling import look_at, perspective, small_scene
from vsgl_addon.passes import vpl_culling as pass_
from vsgl_addon.passes.gpu_util import texture_from_array
from vsgl_addon.reference import vpl_culling as vc

pytestmark = pytest.mark.gpu


def wall_gbuffer(width, height, hole=False, diagonal=False):
    eye, target = np.array([-1.0, 0.0, 1.5]), np.array([2.0, 0.0, 1.5])
    v2w = look_at(eye, target)
    proj = perspective(np.radians(60.0), width / height, 0.1, 20.0)
    inv_proj = np.linalg.inv(proj)
    nx, ny = np.meshgrid((np.arange(width) + 0.5) / width * 2 - 1, (np.arange(height) + 0.5) / height * 2 - 1)
    view = np.einsum("ij,...j->...i", inv_proj, np.stack([nx, ny, np.ones_like(nx), np.ones_like(nx)], -1))
    dirs = (view[..., :3] / view[..., 3:]) @ v2w[:3, :3].T
    t = (2.0 - eye[0]) / dirs[..., 0]
    points = eye + t[..., None] * dirs
    coverage = np.ones((height, width))
    if hole:  # background pixels (no geometry) and one fully empty tile
        coverage[:16, :16] = 0.0
        coverage[20:24, 30:40] = 0.0
    if diagonal:  # the wall below a diagonal, sky above: tiles partly covered along it
        x, y = np.meshgrid(np.arange(width), np.arange(height))
        coverage[x / width + y / height > 1.1] = 0.0
    position = np.concatenate([points, coverage[..., None]], -1)
    normal = np.zeros((height, width, 4))
    normal[..., 0] = -1.0
    albedo = np.zeros((height, width, 4))
    albedo[..., :3] = [0.8, 0.6, 0.4]
    return position, normal, albedo, np.linalg.inv(v2w), proj, v2w, inv_proj


def run_pass(position, normal, albedo, vpls, w2v, proj, delta, seed=3, frame=0, interleave=1, offset=0, stride=1):
    textures = [texture_from_array(a) for a in (position, normal, albedo)]
    result = pass_.run(*textures, vpls, w2v, proj, delta, seed, frame, interleave, offset, stride)
    image, counts = result.read(), result.read_counts()
    lists = result.read_lists()
    result.free()
    return image.astype(np.float64), counts, lists


def reference_image(position, normal, albedo, vpls, delta, xi):
    h, w = position.shape[:2]
    points = position[..., :3].reshape(-1, 3)
    out = vc.shade_glossy_vpls(points, normal[..., :3].reshape(-1, 3), albedo[..., :3].reshape(-1, 3),
                               vpls, delta, xi).reshape(h, w, 3)
    return out * (position[..., 3:] > 0.0)


def _vpls(count, flux_scale=1e-3):
    vpls = small_scene(np.random.default_rng(8), count=count, roughness=0.08, flux_scale=flux_scale)
    # float32 what the GPU sees
    return {k: v.astype(np.float32).astype(np.float64) for k, v in vpls.items()}


def tile_reference_lists(position, w2v, inv_proj, v2w, volume, pixel_edges=False):
    """(tiles_y, tiles_x) VPLs the reference lists per tile: the exact test against the frustum over
    the covered pixels' centres (the pass's), or with ``pixel_edges`` through the tile's pixel edges."""
    h, w = position.shape[:2]
    depth = -(position[..., :3] @ w2v[2, :3] + w2v[2, 3])
    counts = np.zeros(((h + 15) // 16, (w + 15) // 16), int)
    for ty in range(counts.shape[0]):
        for tx in range(counts.shape[1]):
            sl = (slice(16 * ty, 16 * ty + 16), slice(16 * tx, 16 * tx + 16))
            ys, xs = np.nonzero(position[sl][..., 3] > 0.0)
            if not len(ys):
                continue
            d = depth[sl][ys, xs]
            if pixel_edges:
                lo = np.array([16 * tx / w, 16 * ty / h]) * 2 - 1
                hi = np.array([min(16 * tx + 16, w) / w, min(16 * ty + 16, h) / h]) * 2 - 1
            else:
                lo, hi = vc.tile_receiver_ndc([16 * tx + xs.min(), 16 * ty + ys.min()],
                                              [16 * tx + xs.max(), 16 * ty + ys.max()], [w, h])
            planes = vc.tile_frustum_planes(inv_proj, v2w, lo, hi, d.min(), d.max())
            corners = vc.tile_frustum_corners(inv_proj, v2w, lo, hi, d.min(), d.max())
            counts[ty, tx] = vc.ellipsoid_frustum_overlap_exact(planes[None], corners[None], *volume).sum()
    return counts


@pytest.mark.parametrize("delta, diagonal", [(1e-3, False), (1e-2, False), (0.0, False), (1e-3, True)])
def test_tiled_pass_equals_untiled_reference(delta, diagonal):
    """Also on a 72 x 40 image (partial tiles on both axes) with sky above a diagonal."""
    size = (72, 40) if diagonal else (64, 48)
    position, normal, albedo, w2v, proj, v2w, inv_proj = wall_gbuffer(*size, hole=True, diagonal=diagonal)
    vpls = _vpls(300)  # more than one chunk of 256
    xi = vc.vpl_xi(np.arange(300), 3, 0)
    image, counts, lists = run_pass(position, normal, albedo, vpls, w2v, proj, delta)
    reference = reference_image(position, normal, albedo, vpls, delta, xi)
    assert np.all(np.isfinite(image))
    assert reference.max() > 0.0
    err = np.abs(image[..., :3] - reference)
    assert np.all(err <= 2e-3 * reference + 1e-6 * reference.max()), f"worst {np.max(err / (reference + 1e-30)):.3g}"
    tiles = ((size[1] + 15) // 16, (size[0] + 15) // 16)
    assert counts.shape == tiles
    assert counts[0, 0] == 0  # the empty tile lists nothing
    # Every VPL a pixel of the tile accepts is listed.
    for ty in range(tiles[0]):
        for tx in range(tiles[1]):
            sl = (slice(16 * ty, 16 * ty + 16), slice(16 * tx, 16 * tx + 16))
            cov = position[sl][..., 3].reshape(-1) > 0.0
            if not cov.any():
                continue
            pts = position[sl][..., :3].reshape(-1, 3)[cov]
            _, intensity, l2 = vc.glossy_vpl_radiance(
                pts[:, None], normal[sl][..., :3].reshape(-1, 3)[cov][:, None], np.ones((len(pts), 1, 3)),
                vpls["position"][None], vpls["normal"][None], vpls["incoming"][None], vpls["roughness"][None],
                vpls["flux"][None], vpls["rs"][None])
            needed = np.flatnonzero(np.any(vc.acceptance_probability(intensity, l2, delta) > xi[None], axis=0)
                                    if delta > 0 else np.ones(300, bool))
            listed = set(lists[ty * tiles[1] + tx, :counts[ty, tx]].tolist())
            assert set(needed.tolist()) <= listed
    if delta == 0.0:
        assert np.all(counts[counts > 0] == 300)


def test_tile_counts_match_reference_lists():
    position, normal, albedo, w2v, proj, v2w, inv_proj = wall_gbuffer(64, 64)
    vpls = _vpls(200)
    delta = 1e-2
    xi = vc.vpl_xi(np.arange(200), 3, 0)
    _, counts, _ = run_pass(position, normal, albedo, vpls, w2v, proj, delta)
    centre, axes, rotation = vc.glossy_bounding_volumes(vpls, delta, xi)
    ref = tile_reference_lists(position, w2v, inv_proj, v2w, (centre, axes, rotation))
    # View depth of the wall's pixels.
    depth = -(position[..., :3] @ w2v[2, :3] + w2v[2, 3])
    plane_only = np.zeros((4, 4), int)
    for ty in range(4):
        for tx in range(4):
            sl = (slice(16 * ty, 16 * ty + 16), slice(16 * tx, 16 * tx + 16))
            lo, hi = vc.tile_receiver_ndc([16 * tx, 16 * ty], [16 * tx + 15, 16 * ty + 15], [64, 64])
            planes = vc.tile_frustum_planes(inv_proj, v2w, lo, hi, depth[sl].min(), depth[sl].max())
            plane_only[ty, tx] = vc.ellipsoid_frustum_overlap(planes[None], centre, axes, rotation).sum()
    assert ref.sum() > 0
    # The exact test lists fewer than the plane test here, so the counts tell the two apart.
    assert ref.sum() < plane_only.sum()
    # Equal up to spheroids that touch a tile within float32 rounding (the GPU's slack keeps them).
    assert np.all(counts >= ref) and np.all(counts - ref <= np.maximum(2, 0.02 * ref))


def test_tile_frustum_spans_only_the_covered_pixel_centres():
    """On a 72 x 40 image (partial tiles) with sky above a diagonal, each tile lists what the
    reference's frustum over its covered pixels' centres lists, clearly fewer than a frustum through
    the tile's pixel edges would (which the receivers, at the pixel centres, never reach)."""
    position, normal, albedo, w2v, proj, v2w, inv_proj = wall_gbuffer(72, 40, diagonal=True)
    vpls = _vpls(300)
    delta = 1e-2
    xi = vc.vpl_xi(np.arange(300), 3, 0)
    _, counts, _ = run_pass(position, normal, albedo, vpls, w2v, proj, delta)
    volume = vc.glossy_bounding_volumes(vpls, delta, xi)
    ref = tile_reference_lists(position, w2v, inv_proj, v2w, volume)
    edges = tile_reference_lists(position, w2v, inv_proj, v2w, volume, pixel_edges=True)
    assert ref.sum() > 0 and np.all(edges >= ref)
    tolerance = np.maximum(2, 0.02 * ref)
    assert np.sum(edges - ref > tolerance) >= 3, (edges - ref)
    assert np.all(counts >= ref) and np.all(counts - ref <= tolerance), (counts - ref)


def test_no_vpls_and_single_vpl():
    position, normal, albedo, w2v, proj, *_ = wall_gbuffer(20, 17)
    empty = {k: v[:0] for k, v in _vpls(1).items()}
    image, counts, _ = run_pass(position, normal, albedo, empty, w2v, proj, 1e-3)
    np.testing.assert_array_equal(image, 0.0)
    np.testing.assert_array_equal(counts, 0)
    one = _vpls(1, flux_scale=1.0)
    image, counts, _ = run_pass(position, normal, albedo, one, w2v, proj, 1e-6)
    assert np.all(np.isfinite(image)) and image.max() > 0.0


@pytest.mark.parametrize("interleave", [2, 4])
def test_interleaved_subsets_average_to_full_estimate(interleave):
    """Each of the N^2 offsets shades a different VPL subset per pixel; their mean is the N = 1 image."""
    position, normal, albedo, w2v, proj, *_ = wall_gbuffer(48, 32)
    vpls = _vpls(120)
    full, _, _ = run_pass(position, normal, albedo, vpls, w2v, proj, 1e-3)
    images = [run_pass(position, normal, albedo, vpls, w2v, proj, 1e-3, interleave=interleave, offset=o)[0]
              for o in range(interleave**2)]
    mean = np.mean(images, axis=0)
    np.testing.assert_allclose(mean, full, rtol=1e-5, atol=1e-7 * full.max())
    # One sub-image differs from the full image (it really shades a subset).
    assert np.max(np.abs(images[0] - full)) > 1e-3 * full.max()
    with pytest.raises(ValueError):
        run_pass(position, normal, albedo, vpls, w2v, proj, 1e-3, interleave=3)


@pytest.mark.parametrize("interleave, offset", [(2, 1), (8, 37)])
def test_each_sub_image_shades_exactly_its_subset_across_chunks(interleave, offset):
    """Over several 256-VPL chunks, each pixel's sub-image ((x % N) + N (y % N) + offset) % N^2 is the
    reference's sum over the VPLs i with i % N^2 equal to it, weighted N^2 (004 section 6): the pass
    partitions each chunk's list by subset, so a pixel loops over its own subset only."""
    position, normal, albedo, w2v, proj, *_ = wall_gbuffer(64, 48)
    count, delta, seed = 700, 1e-3, 3
    vpls = _vpls(count)
    xi = vc.vpl_xi(np.arange(count), seed, 0)
    image, _, _ = run_pass(position, normal, albedo, vpls, w2v, proj, delta, seed, interleave=interleave,
                           offset=offset)
    n2 = interleave * interleave
    h, w = position.shape[:2]
    ys, xs = np.mgrid[0:h, 0:w]
    pixel_subset = (xs % interleave + interleave * (ys % interleave) + offset) % n2
    members_of = np.arange(count) % n2
    reference = np.zeros((h, w, 3))
    for sub in np.unique(pixel_subset):
        members = np.nonzero(members_of == sub)[0]
        part = reference_image(position, normal, albedo, {k: v[members] for k, v in vpls.items()}, delta,
                               xi[members])
        reference[pixel_subset == sub] = (n2 * part)[pixel_subset == sub]
    assert reference.max() > 0.0 and np.all(np.isfinite(image))
    err = np.abs(image[..., :3] - reference)
    assert np.all(err <= 2e-3 * reference + 1e-6 * reference.max()), f"worst {np.max(err / (reference + 1e-30)):.3g}"


def test_progressive_samples_and_denoise():
    """S frames average towards brute force (error falls with S); the filter keeps a flat wall's
    mean and lowers the interleaved image's error."""
    position, normal, albedo, w2v, proj, *_ = wall_gbuffer(64, 48)
    vpls = _vpls(300)
    textures = [texture_from_array(a) for a in (position, normal, albedo)]
    brute = reference_image(position, normal, albedo, vpls, 0.0, None)

    def error(image):
        return np.sqrt(np.mean((image[..., :3] - brute) ** 2)) / brute.mean()

    one = pass_.render_caustics(*textures, vpls, w2v, proj, 3e-2, samples=1, interleave=2)
    many = pass_.render_caustics(*textures, vpls, w2v, proj, 3e-2, samples=16, interleave=2)
    filtered = pass_.render_caustics(*textures, vpls, w2v, proj, 3e-2, samples=1, interleave=2, radius=4)
    assert np.all(np.isfinite(filtered))
    assert error(many) < 0.5 * error(one)
    assert error(filtered) < error(one)


@pytest.mark.parametrize("stride, interleave", [(4, 1), (16, 1), (4, 2)])
def test_strided_preview_shades_one_vpl_of_each_block_weighted_by_the_stride(stride, interleave):
    """The coarse preview's pass: the image is the reference's sum over
    reference.vpl_culling.strided_vpls (one jittered VPL of each block of S) times S, the interleave
    subsets taken over the strided sequence; its jitter is the GLSL strided_vpl_jitter's."""
    from glsl_harness import evaluate_glsl

    position, normal, albedo, w2v, proj, *_ = wall_gbuffer(64, 48, hole=True)
    vpls = _vpls(300)
    delta, seed = 1e-3, 3
    xi = vc.vpl_xi(np.arange(300), seed, 0)
    image, _, _ = run_pass(position, normal, albedo, vpls, w2v, proj, delta, seed, interleave=interleave,
                           stride=stride)
    chosen = vc.strided_vpls(300, stride, seed)
    # One of each block (the last, partial block's member may lie past the count: unbiased all the same).
    assert 300 // stride <= len(chosen) <= -(-300 // stride) and np.all(np.diff(chosen // stride) >= 1)
    if interleave == 1:
        reference = stride * reference_image(position, normal, albedo, {k: v[chosen] for k, v in vpls.items()},
                                             delta, xi[chosen])
    else:
        n2 = interleave * interleave
        h, w = position.shape[:2]
        ys, xs = np.mgrid[0:h, 0:w]
        pixel_subset = (xs % interleave + interleave * (ys % interleave)) % n2
        reference = np.zeros((h, w, 3))
        for sub in range(n2):
            members = chosen[(chosen // stride) % n2 == sub]
            part = reference_image(position, normal, albedo, {k: v[members] for k, v in vpls.items()}, delta,
                                   xi[members])
            reference[pixel_subset == sub] = (stride * n2 * part)[pixel_subset == sub]
    assert reference.max() > 0.0 and np.all(np.isfinite(image))
    err = np.abs(image[..., :3] - reference)
    assert np.all(err <= 2e-3 * reference + 1e-6 * reference.max()), f"worst {np.max(err / (reference + 1e-30)):.3g}"
    k = np.arange(0, 5000, 7).astype(np.float64)
    got = evaluate_glsl(f"float(strided_vpl_jitter(uint(k), {seed}u, {stride}u))", {"k": k},
                        libraries=["lib/vpl_culling.glsl"])
    np.testing.assert_array_equal(got, vc.strided_vpl_jitter(k.astype(np.int64), seed, stride))
