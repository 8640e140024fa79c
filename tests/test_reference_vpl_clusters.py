# SPDX-License-Identifier: GPL-3.0-or-later
"""The float64 twin of the VPL shadows' clusters (reference/vpl_clusters.py) against brute force: each
block's origin, σ and half-space from an explicit loop over its VPLs, the empty blocks' rows, the
point sets in map order, and passes/vpl_culling.py vpl_clusters (the occupied clusters, compacted)
equal to the table's occupied rows."""

from __future__ import annotations

import numpy as np

from vsgl_addon.passes import vpl_culling
from vsgl_addon.reference import ism
from vsgl_addon.reference import vpl_clusters as rc


def _vpls(rng, size, views, count):
    texel = rng.choice(size * size * views, count, replace=False)
    normal = np.array([0.1, -0.2, 1.0]) + rng.normal(0, 0.2, (count, 3))
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    flux = 10.0 ** rng.uniform(-3, 1, (count, 3))
    flux[:3] = 0.0  # zero flux: the weight floor alone
    return {"position": rng.normal(0, 0.3, (count, 3)), "normal": normal, "flux": flux,
            "rs": rng.uniform(0.2, 1.0, (count, 3)), "roughness": np.full(count, 0.01),
            "texel": texel % (size * size), "view": texel // (size * size)}


def test_cluster_table_equals_brute_force():
    rng = np.random.default_rng(2)
    size, views = 40, 2  # 3 blocks a side, the last partial
    vpls = _vpls(rng, size, views, 300)
    # Empty blocks: the first map, and the middle block of the second view.
    rows, columns = vpls["texel"] // size, vpls["texel"] % size
    kept = ~(((vpls["view"] == 0) & (rows < 16) & (columns < 16))
             | ((vpls["view"] == 1) & (rows // 16 == 1) & (columns // 16 == 1)))
    vpls = {key: value[kept] for key, value in vpls.items()}
    origins, sets, distance, planes, occupied = rc.vpl_cluster_origins(vpls, size, views, 60, 64, 1.0)
    blocks = 3
    assert len(origins) == views * blocks * blocks
    rank = 0
    for map_index in range(len(origins)):
        view, block = divmod(map_index, blocks * blocks)
        rows, columns = vpls["texel"] // size, vpls["texel"] % size
        mine = ((vpls["view"] == view) & (rows // 16 == block // blocks) & (columns // 16 == block % blocks))
        assert sets[map_index] == (60 + rank) % 64
        assert occupied[map_index] == mine.any()
        if not mine.any():
            assert distance[map_index] == rc.EMPTY_CLUSTER_DISTANCE and not planes[map_index].any()
            assert not origins[map_index].any()
            continue
        rank += 1
        p, n = vpls["position"][mine], vpls["normal"][mine]
        w = np.array([max(f * r) for f, r in zip(vpls["flux"][mine], vpls["rs"][mine])]) + rc.CLUSTER_WEIGHT_FLOOR
        mean = (w[:, None] * p).sum(0) / w.sum()
        variance = sum(wk * np.dot(pk - mean, pk - mean) for wk, pk in zip(w, p)) / w.sum() / 3.0
        axis = (w[:, None] * n).sum(0)
        axis /= np.linalg.norm(axis)
        origin = mean + ism.SHADOW_ORIGIN_SIGMAS * np.sqrt(variance) * axis
        np.testing.assert_allclose(origins[map_index], origin, atol=1e-12)
        np.testing.assert_allclose(distance[map_index], np.sqrt(variance), rtol=1e-12)
        top = max(np.dot(pk - origin, axis) for pk in p)
        np.testing.assert_allclose(planes[map_index], [*axis, top + rc.CLUSTER_PLANE_SLACK], atol=1e-12)
        # The map keeps none of its own VPLs (they lie on or below the highest one's plane).
        assert not ism.keeps_point(p - origin, planes[map_index]).any()
    assert rank == len(origins) - 2 and not occupied[0] and not occupied[9 + 4]


def test_compacted_clusters_are_the_table_s_occupied_rows():
    rng = np.random.default_rng(4)
    vpls = _vpls(rng, 64, 3, 120)
    cluster, origins, sigma, planes = vpl_culling.vpl_clusters(vpls, 64)
    table_origins, _, distance, table_planes, occupied = rc.vpl_cluster_origins(vpls, 64, 3, 0, 64, 1.0)
    np.testing.assert_allclose(origins, table_origins[occupied], atol=1e-12)
    np.testing.assert_allclose(sigma, distance[occupied], atol=1e-12)
    np.testing.assert_allclose(planes, table_planes[occupied], atol=1e-12)
    maps = rc.vpl_cluster_map(vpls["texel"], vpls["view"], 64)
    np.testing.assert_array_equal(np.flatnonzero(occupied)[cluster], maps)


def test_a_one_texel_view_is_one_block():
    vpls = _vpls(np.random.default_rng(0), 1, 1, 1)
    vpls["flux"][:] = 0.0
    origins, sets, distance, planes, occupied = rc.vpl_cluster_origins(vpls, 1, 1, 5, 64, 1.0)
    assert occupied.tolist() == [True] and sets.tolist() == [5] and distance[0] < 1e-15
    np.testing.assert_allclose(origins[0], vpls["position"][0], atol=1e-15)
    np.testing.assert_allclose(planes[0, 3], rc.CLUSTER_PLANE_SLACK, atol=1e-15)
