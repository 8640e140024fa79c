# SPDX-License-Identifier: GPL-3.0-or-later
"""benchmarks/vsgl_aggregation.py's cluster weights c_ij against the reference generator's clusters."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))

from vsgl_addon.reference import vsgl as ref  # noqa: E402


def _random_rsm(size, rng):
    normal = rng.normal(size=(size, size, 3))
    return ref.RSM(position=rng.normal(size=(size, size, 3)), normal=normal,
                   flux_diffuse=rng.random((size, size, 3)) * (rng.random((size, size, 1)) > 0.3),
                   flux_specular=0.2 * rng.random((size, size, 3)),
                   specular_axis=rng.normal(size=(size, size, 3)), specular_sharpness=10.0 * rng.random((size, size)))


def test_cluster_weights_rebuild_the_generators_vsgls():
    from vsgl_aggregation import cluster_weights

    rng = np.random.default_rng(5)
    rsm = _random_rsm(16, rng)
    count = 24
    out = ref.generate_vsgls(rsm, count, seed=3)
    maps = ref.build_mipmaps(rsm)
    c = cluster_weights(maps.pdf, out["kernel_center"], out["kernel_level"], count, rsm.size)
    totals = c @ ref.texel_moments(rsm).reshape(-1, ref.MOMENT_CHANNELS)
    rebuilt = ref.vsgl_parameters(totals, *ref._rsm_fallback(maps.moments[-1]))
    for key in ("power", "diffuse_axis", "diffuse_sharpness", "diffuse_mean", "diffuse_variance", "specular_axis"):
        np.testing.assert_allclose(rebuilt[key], out[key], rtol=1e-9, atol=1e-12, err_msg=key)
