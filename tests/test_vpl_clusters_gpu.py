# SPDX-License-Identifier: GPL-3.0-or-later
"""The glossy VPLs' shadow-map clusters made on the GPU (passes/vpl_culling.py cluster_view,
cluster_sets, extract_vpls with ``shadows``; glsl/vpl_culling/vpl_clusters.comp.glsl,
vpl_cluster_sets.comp.glsl, glsl/lib/vpl_clusters.glsl) against the float64 twin
(reference/vpl_clusters.py vpl_cluster_origins, vpl_cluster_map): the splat's table of every block of
every view (origin, point set, minimum distance, half-space) at the extremes (blocks with no VPL, a
block of sharp texels with zero flux, a block with a single VPL, a one-texel RSM, a view side that is
no multiple of a block), each extracted VPL's map, and the maps and the shadowed culling made from
the VPLs with nothing read back against the CPU's (upload_visible_vpls of scene_vpls)."""

from __future__ import annotations

import numpy as np
import pytest

from glsl_harness import as_gpu_floats
from test_vpl_render import SETTINGS, _scene
from vsgl_addon.passes import vpl_culling as pass_
from vsgl_addon.passes.gpu_util import RoundTrips, read_texture, texture_from_array
from vsgl_addon.passes.scene_gpu import SceneGPU
from vsgl_addon.pipeline import OWN_REFLECTOR_SIGMAS, POINT_SETS
from vsgl_addon.reference import vpl_clusters as rc
from vsgl_addon.reference import vpl_culling as vc

pytestmark = pytest.mark.gpu
ALPHA_C = 0.1
POINT_LIGHT = np.array([0.3, -2.0, 2.5, 1.0])
# Kinds of block: a tilted patch of sharp and rough texels, one VPL among rough texels, sharp texels
# that reflect nothing (no VPL), rough texels only (no VPL).
PATCH, SINGLE, ZERO_FLUX, ROUGH = range(4)


def _rsm(rng, size, view):
    """(position, normal, flux_specular) RSM slots (size, size, 4), float32-exact, block (bx, by)
    of kind (bx + 2 by + view) mod 4; a one-texel RSM is a patch."""
    y, x = np.mgrid[0:size, 0:size]
    blocks = rc.cluster_blocks(size)
    kind = (x // rc.CLUSTER_TEXELS + 2 * (y // rc.CLUSTER_TEXELS) + view) % 4 if size > 1 else np.zeros((1, 1), int)
    shape = (size, size)
    surface = np.stack([0.02 * x, 0.02 * y, 0.3 + 0.01 * x - 0.004 * y], -1) + rng.normal(0, 2e-3, shape + (3,))
    normal = np.array([-0.01, 0.004, 1.0]) + rng.normal(0, 0.1, shape + (3,))
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    sharp = np.where(kind == PATCH, rng.uniform(size=shape) < 0.7, kind == ZERO_FLUX)
    block_index = (y // rc.CLUSTER_TEXELS) * blocks + x // rc.CLUSTER_TEXELS
    first = np.zeros(shape, bool)
    for index in np.unique(block_index[kind == SINGLE]):
        where = np.argwhere((block_index == index) & (kind == SINGLE))
        first[tuple(where[rng.integers(len(where))])] = True
    sharp |= first | (size == 1)
    roughness = np.where(sharp, rng.uniform(0.0, 0.31, shape), rng.uniform(0.33, 1.0, shape))
    flux = 10.0 ** rng.uniform(-3, 1, shape + (3,))
    flux[(kind == PATCH) & (rng.uniform(size=shape) < 0.1) & (size > 1)] = 0.0
    flux[kind == ZERO_FLUX] = 0.0
    slots = (np.concatenate([surface, np.ones(shape + (1,))], -1), np.concatenate([normal, roughness[..., None]], -1),
             np.concatenate([flux, np.full(shape + (1,), 1e-4)], -1))
    return tuple(as_gpu_floats(slot) for slot in slots), kind


def _reference_vpls(views):
    parts = []
    for index, slots in enumerate(views):
        records, texels = vc.extract_glossy_vpls(*slots, POINT_LIGHT, ALPHA_C)
        parts.append(dict(pass_._records_to_vpls(records), texel=texels, view=np.full(len(texels), index)))
    return {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}


def _gpu_table(views, first_map):
    """(3, maps, 4) float64: the GPU's splat table of the views' clusters (nothing read back before)."""
    import gpu

    from vsgl_addon.passes.ism import MapOrigins

    size = views[0][0].shape[0]
    maps = len(views) * rc.cluster_blocks(size) ** 2
    origins = MapOrigins(gpu.types.GPUTexture((maps, 3), format="RGBA32F"), maps)
    reads = RoundTrips.read_backs
    for index, slots in enumerate(views):
        textures = {name: texture_from_array(slot) for name, slot in zip(pass_.EXTRACTION_SLOTS, slots)}
        pass_.cluster_view(origins, textures, size, POINT_LIGHT, ALPHA_C, index, OWN_REFLECTOR_SIGMAS)
    pass_.cluster_sets(origins, first_map, POINT_SETS)
    assert RoundTrips.read_backs == reads
    return read_texture(origins.texture, maps, 3).astype(np.float64)


@pytest.mark.parametrize("size, views", [(1, 1), (16, 1), (40, 2), (64, 3)])
def test_cluster_table_equals_the_reference(size, views):
    rng = np.random.default_rng(size)
    built = [_rsm(rng, size, view) for view in range(views)]
    slots = [slot for slot, _ in built]
    first_map = 70  # past POINT_SETS: the sets wrap
    table = _gpu_table(slots, first_map)
    vpls = _reference_vpls(slots)
    origins, sets, distance, planes, occupied = rc.vpl_cluster_origins(
        vpls, size, views, first_map, POINT_SETS, OWN_REFLECTOR_SIGMAS)
    assert np.isfinite(table).all()
    np.testing.assert_array_equal(table[1, :, 1] > 0.5, occupied)
    np.testing.assert_array_equal(table[0, :, 3], sets)
    # Every kind of block is there (a one-texel RSM: one VPL), and only patches and single VPLs hold one.
    kinds = np.concatenate([[kind[by * rc.CLUSTER_TEXELS, bx * rc.CLUSTER_TEXELS]
                             for by in range(rc.cluster_blocks(size)) for bx in range(rc.cluster_blocks(size))]
                            for _, kind in built])
    if len(kinds) >= 4:
        assert set(kinds) == {PATCH, SINGLE, ZERO_FLUX, ROUGH}
    assert occupied[np.isin(kinds, (PATCH, SINGLE))].all() and not occupied[np.isin(kinds, (ZERO_FLUX, ROUGH))].any()
    np.testing.assert_allclose(table[0, :, :3], origins, rtol=0, atol=2e-6)
    np.testing.assert_allclose(table[1, :, 0], distance, rtol=1e-4, atol=1e-7)
    np.testing.assert_allclose(table[2], planes, rtol=0, atol=2e-6)
    # A single VPL: σ 0 (within float32 rounding of Φ p / Φ), the origin on it, its own plane's
    # slack above it.
    single = occupied & (kinds == SINGLE)
    if single.any():
        assert (table[1, single, 0] < 1e-7).all()
        np.testing.assert_allclose(table[2, single, 3], rc.CLUSTER_PLANE_SLACK, atol=1e-7)
    # Empty blocks keep no point: a minimum distance beyond every point, no half-space.
    assert (table[1, ~occupied, 0] == np.float32(rc.EMPTY_CLUSTER_DISTANCE)).all()
    assert (~occupied).any() == (len(kinds) >= 4)
    assert (table[2, ~occupied] == 0.0).all()


def test_extracted_vpls_carry_their_cluster_s_map():
    """extract_view with a view index writes each VPL's map (vpl_cluster_map) into record 3's w, in
    the reference's order; without one, 0."""
    rng = np.random.default_rng(5)
    size = 40
    views = [_rsm(rng, size, view)[0] for view in range(2)]
    expected = _reference_vpls(views)
    for indexed in (True, False):
        vpl_set = pass_.empty_vpl_set(2 * size * size)
        for index, slots in enumerate(views):
            textures = {name: texture_from_array(slot) for name, slot in zip(pass_.EXTRACTION_SLOTS, slots)}
            pass_.extract_view(vpl_set, textures, size, POINT_LIGHT, ALPHA_C, index if indexed else -1)
        count, rows = vpl_set.count, vpl_set.table.height
        table = read_texture(vpl_set.table, pass_.TABLE_WIDTH, rows).astype(np.float64)
        records = table.reshape(rows // 4, 4, pass_.TABLE_WIDTH, 4).transpose(0, 2, 1, 3).reshape(-1, 4, 4)[:count]
        vpl_set.free()
        assert count == len(expected["texel"]) > 0
        maps = rc.vpl_cluster_map(expected["texel"], expected["view"], size) if indexed else np.zeros(count)
        np.testing.assert_array_equal(records[:, 3, 3], maps)


def test_gpu_clusters_shadow_as_the_cpu_ones_with_nothing_read_back():
    """The occluded caustic scene (a 64² RSM: the panel fills several blocks): extract_vpls with
    shadows reads nothing back, its occupied maps are the CPU's (upload_visible_vpls of scene_vpls)
    in order, and the shadowed culling of every VPL (δ = 0) gives the same image within float32
    rounding of the maps' origins."""
    from vsgl_addon.passes.gbuffer import render_gbuffer
    from vsgl_addon.passes.shading_inputs import shading_gbuffer

    description = _scene(occluder=True)
    settings = SETTINGS.overridden(rsm_size=64, ism_size=32, ism_points=4096)
    width, height = 48, 36
    scene_gpu = SceneGPU(description)
    camera = description.camera
    gbuffer = render_gbuffer(scene_gpu, camera.view_matrix(), camera.projection_matrix(), (width, height))
    inputs = shading_gbuffer(gbuffer)
    images, atlases = [], []
    try:
        cpu = pass_.upload_visible_vpls(pass_.scene_vpls(scene_gpu, settings.rsm_size, settings.caustic_roughness),
                                        scene_gpu, settings, settings.rsm_size)
        reads, read_bytes = RoundTrips.read_backs, RoundTrips.read_back_bytes
        gpu_set = pass_.extract_vpls(scene_gpu, settings.rsm_size, settings.caustic_roughness, settings)
        assert (RoundTrips.read_backs, RoundTrips.read_back_bytes) == (reads, read_bytes)
        table = read_texture(gpu_set.map_origins, gpu_set.isms.count, 3)
        occupied = table[1, :, 1] > 0.5
        assert cpu.isms.count == occupied.sum() > 4 and gpu_set.isms.count > cpu.isms.count
        assert gpu_set.count == cpu.count
        for vpl_set in (cpu, gpu_set):
            result = pass_.run(inputs.position, inputs.normal, inputs.diffuse_reflectance, vpl_set,
                               camera.view_matrix(), camera.projection_matrix(), 0.0)
            images.append(result.read()[..., :3].astype(np.float64))
            result.free()
            atlases.append(vpl_set.isms.read())
        cpu.free()
        gpu_set.free()
    finally:
        gbuffer.free()
        scene_gpu.free()
    cpu_maps, gpu_maps = atlases[0], atlases[1][occupied]
    assert np.isinf(atlases[1][~occupied]).all()  # empty blocks: nothing splatted
    known = np.isfinite(cpu_maps)
    np.testing.assert_array_equal(np.isfinite(gpu_maps), known)
    np.testing.assert_allclose(gpu_maps[known], cpu_maps[known], rtol=1e-5, atol=1e-6)
    assert images[0].max() > 0.0
    np.testing.assert_allclose(images[1], images[0], rtol=1e-4, atol=1e-5 * images[0].max())
