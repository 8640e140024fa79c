# SPDX-License-Identifier: GPL-3.0-or-later
"""Tests of the float64 VSGL generation reference (vsgl_addon/reference/vsgl.py, mipmap.py).

000 = Tokuyoshi, "Modified filtered importance sampling for virtual spherical Gaussian lights"
(CVM 2016); 003 = the Square Enix SG talk (simplified 2-VSGL mode). Expected values are computed
here from the paper's formulas directly (brute-force sums over texels), not from the module.
"""

from __future__ import annotations

import numpy as np
import pytest

from vsgl_addon.reference import mipmap, vsgl
from vsgl_addon.reference.sg import DIFFUSE_HEMISPHERE_SCALE, specular_lobe_warp

LUM = np.array([0.2126, 0.7152, 0.0722])
#: λ_d of the diffuse SG lobe, ≈ 2 in 000 Eq. 6 (sg.py may refine the fit).
LAMBDA_D = float(vsgl.DIFFUSE_SHARPNESS)
assert abs(LAMBDA_D - 2.0) < 0.5


# --------------------------------------------------------------------------------------------
# Test RSMs


def _grid(size):
    """Texel-centre coordinates (v, u) in [0, 1]^2, each (size, size)."""
    v, u = (np.mgrid[0:size, 0:size] + 0.5) / size
    return v, u


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def make_rsm(size, seed=0, flux_diffuse=None, flux_specular=None, sharpness=None):
    """A bumpy lit floor with varied normals, coloured flux and varied specular lobes."""
    rng = np.random.default_rng(seed)
    v, u = _grid(size)
    position = np.stack([4.0 * u - 2.0, 4.0 * v - 2.0, 0.3 * np.sin(5.0 * u) * np.cos(3.0 * v)], -1)
    normal = _unit(np.stack([0.3 * np.cos(5.0 * u), -0.2 * np.sin(3.0 * v), np.ones_like(u)], -1))
    blob = np.exp(-((u - 0.3) ** 2 + (v - 0.6) ** 2) / 0.05)
    if flux_diffuse is None:
        flux_diffuse = np.stack([0.2 + blob, 0.2 + u * blob, 0.1 + v], -1)
    if flux_specular is None:
        flux_specular = 0.3 * np.stack([0.1 + v, 0.3 + blob, 0.2 + 0.0 * u], -1)
    incoming = _unit(np.stack([u - 0.5, v - 0.5, np.full_like(u, 1.5)], -1))
    axis, lam = specular_lobe_warp(incoming, normal, 0.3 + 0.2 * rng.random((size, size)))
    if sharpness is not None:
        lam = np.broadcast_to(sharpness, lam.shape)
    return vsgl.RSM(position, normal, flux_diffuse, flux_specular, axis, lam)


def smooth_pdf(size):
    """A smooth PDF deliberately not proportional to the flux of make_rsm."""
    v, u = _grid(size)
    return 0.3 + u + np.exp(-((u - 0.7) ** 2 + (v - 0.3) ** 2) / 0.02)


def hot_gradient_pdf(size):
    """Gradient + a few hot texels + zero texels (a row and two corners)."""
    v, u = _grid(size)
    pdf = 0.2 + u + v
    pdf[3, 5] += 30.0
    pdf[size - 6, size // 2 + 4] += 50.0
    pdf[size // 2 - 1, :] = 0.0
    pdf[0, 0] = pdf[-1, -1] = 0.0
    return pdf / pdf.sum()


def all_finite(out):
    return all(np.all(np.isfinite(value)) for value in out.values())


def check_shapes(out, count):
    expected = {
        "mean": (count, 3), "variance": (count,), "diffuse_mean": (count, 3),
        "diffuse_variance": (count,), "specular_mean": (count, 3), "specular_variance": (count,),
        "diffuse_amplitude": (count, 3),
        "diffuse_axis": (count, 3), "diffuse_sharpness": (count,), "specular_amplitude": (count, 3),
        "specular_axis": (count, 3), "specular_sharpness": (count,), "power": (count, 3),
        "kernel_center": (count, 2), "kernel_level": (count,), "rsm_total_power": (3,),
    }
    assert {key: value.shape for key, value in out.items()} == expected


def check_sane(out, count, top_level):
    check_shapes(out, count)
    assert all_finite(out)
    assert np.all(out["variance"] > 0.0)
    assert np.all(out["diffuse_variance"] > 0.0) and np.all(out["specular_variance"] > 0.0)
    assert np.all(out["diffuse_sharpness"] >= 0.0) and np.all(out["specular_sharpness"] >= 0.0)
    assert np.all(out["diffuse_sharpness"] <= vsgl.MAX_SHARPNESS * (1 + 1e-12))
    assert np.all(out["specular_sharpness"] <= vsgl.MAX_SHARPNESS * (1 + 1e-12))
    for key in ("diffuse_axis", "specular_axis"):
        np.testing.assert_allclose(np.linalg.norm(out[key], axis=-1), 1.0, rtol=1e-12)
    for key in ("diffuse_amplitude", "specular_amplitude", "power"):
        assert np.all(out[key] >= 0.0)
    assert np.all((out["kernel_center"] >= 0.0) & (out["kernel_center"] <= 1.0))
    assert np.all((out["kernel_level"] >= 0.0) & (out["kernel_level"] <= top_level))
    # Each lobe's SG carries the lobe's power: c_d A(λ_d) + c_s A(λ_s) = power (000 app. B.1), the
    # diffuse lobe's over its hemisphere (sphere: DIFFUSE_HEMISPHERE_SCALE times).
    energy = (out["diffuse_amplitude"] * sg_integral(out["diffuse_sharpness"])[:, None] / DIFFUSE_HEMISPHERE_SCALE
              + out["specular_amplitude"] * sg_integral(out["specular_sharpness"])[:, None])
    np.testing.assert_allclose(energy, out["power"], rtol=1e-12, atol=1e-300)


# --------------------------------------------------------------------------------------------
# Independent formulas (000 app. A-B), per VPL


def sg_integral(lam):
    lam = np.asarray(lam, dtype=np.float64)
    safe = np.where(lam > 0.0, lam, 1.0)
    return np.where(lam > 0.0, 2.0 * np.pi * -np.expm1(-2.0 * safe) / safe, 4.0 * np.pi)


def brute_force_vsgl(weights_rgb, axes, sharpness, position_weights, positions):
    """One VSGL lobe + position from per-VPL arrays (000 app. B.1-B.2), written from the paper."""
    w = weights_rgb @ LUM
    xi_bar = (sharpness / (sharpness + 1.0))[:, None] * axes
    mean_dir = (w[:, None] * xi_bar).sum(0) / w.sum()
    length = np.linalg.norm(mean_dir)
    lam = length / (1.0 - length)
    amplitude = weights_rgb.sum(0) / sg_integral(lam)
    pw = position_weights
    mu = (pw[:, None] * positions).sum(0) / pw.sum()
    var = (pw * (positions**2).sum(-1)).sum() / pw.sum() - mu @ mu
    return amplitude, mean_dir / length, lam, mu, var


# --------------------------------------------------------------------------------------------
# Mip chains and filtering


def test_mip_chain_levels_are_block_means_of_the_app_b3_quantities():
    """Each level-l texel is the mean over its 2^l x 2^l block of ΦRd, ΦRd ξ̄_d, ... (000 app. B.3)."""
    size = 16
    rsm = make_rsm(size)
    maps = vsgl.build_mipmaps(rsm)
    w_d = rsm.flux_diffuse @ LUM
    w_s = rsm.flux_specular @ LUM
    w = w_d + w_s
    lam_s = rsm.specular_sharpness
    quantities = np.concatenate(
        [
            rsm.flux_diffuse,
            w_d[..., None] * (LAMBDA_D / (LAMBDA_D + 1.0)) * rsm.normal,  # 000 Eq. 6, Toksvig
            rsm.flux_specular,
            w_s[..., None] * (lam_s / (lam_s + 1.0))[..., None] * rsm.specular_axis,
            w_d[..., None] * rsm.position,  # per-lobe position moments; their sum is app. B.2's
            (w_d * (rsm.position**2).sum(-1))[..., None],
            w_s[..., None] * rsm.position,
            (w_s * (rsm.position**2).sum(-1))[..., None],
        ],
        axis=-1,
    )
    pdf_density = (w / w.sum()) * size * size
    assert len(maps.moments) == 5 and maps.top_level == 4
    for level in range(5):
        block = 2**level
        n = size // block
        expected = quantities.reshape(n, block, n, block, -1).mean(axis=(1, 3))
        np.testing.assert_allclose(maps.moments[level], expected, rtol=1e-12, atol=1e-13)
        expected_pdf = pdf_density.reshape(n, block, n, block).mean(axis=(1, 3))
        np.testing.assert_allclose(maps.pdf[level], expected_pdf, rtol=1e-12)
        # 4^l times the mean is the cluster total of app. B.3: Σ over the block.
        np.testing.assert_allclose(
            4.0**level * maps.moments[level][..., vsgl.CH_DIFFUSE],
            rsm.flux_diffuse.reshape(n, block, n, block, 3).sum(axis=(1, 3)), rtol=1e-12,
        )
    np.testing.assert_allclose(maps.pdf[-1], [[1.0]], rtol=1e-13)


def test_trilinear_lookup_at_integer_levels_and_texel_centres():
    rng = np.random.default_rng(3)
    chain = mipmap.build_mip_chain(rng.random((8, 8, 2)))
    uv = rng.random((50, 2))
    for level in range(4):
        np.testing.assert_allclose(
            mipmap.trilinear(chain, uv, np.full(50, float(level))),
            mipmap.bilinear(chain[level], uv), rtol=0, atol=1e-15,
        )
        # At the texel centres of a level the bilinear lookup returns the texel.
        n = 8 >> level
        i, j = np.divmod(np.arange(n * n), n)
        centres = np.stack([(j + 0.5) / n, (i + 0.5) / n], -1)
        np.testing.assert_allclose(
            mipmap.trilinear(chain, centres, np.full(n * n, float(level))), chain[level][i, j],
            rtol=1e-14,
        )
    # Linear in l between levels.
    half = mipmap.trilinear(chain, uv, np.full(50, 1.25))
    expected = 0.75 * mipmap.bilinear(chain[1], uv) + 0.25 * mipmap.bilinear(chain[2], uv)
    np.testing.assert_allclose(half, expected, rtol=1e-14)
    # Levels outside [0, top] clamp to the ends.
    np.testing.assert_allclose(mipmap.trilinear(chain, uv, np.full(50, 9.0)),
                               mipmap.bilinear(chain[3], uv))
    np.testing.assert_allclose(mipmap.trilinear(chain, uv, np.full(50, -1.0)),
                               mipmap.bilinear(chain[0], uv))


def test_bilinear_clamp_to_edge_preserves_the_integral_of_each_level():
    """∫ f̄(x, l) dx = image mean for a fixed level: what makes Eqs. 4-5 unbiased at fixed l."""
    rng = np.random.default_rng(4)
    image = rng.random((8, 8)) * 5.0
    chain = mipmap.build_mip_chain(image)
    fine = 64  # a multiple of 2W: the midpoint rule is exact on each bilinear piece
    v, u = _grid(fine)
    uv = np.stack([u.ravel(), v.ravel()], -1)
    for level in range(4):
        np.testing.assert_allclose(mipmap.bilinear(chain[level], uv).mean(), image.mean(),
                                   rtol=1e-13)


def test_rejects_non_power_of_two_and_non_square():
    with pytest.raises(ValueError):
        mipmap.build_mip_chain(np.zeros((6, 6)))
    with pytest.raises(ValueError):
        mipmap.build_mip_chain(np.zeros((4, 8)))
    vectors = np.zeros((2, 4, 3))
    with pytest.raises(ValueError):
        vsgl.generate_vsgls(vsgl.RSM(vectors, vectors, vectors, vectors, vectors,
                                     np.zeros((2, 4))), 4)


# --------------------------------------------------------------------------------------------
# Kernel centres: Fibonacci lattice and hierarchical sample warping


def _box_discrepancy(points, boxes):
    lo, hi = boxes[:, 0, :], boxes[:, 1, :]
    inside = (
        (points[None, :, 0] >= lo[:, None, 0]) & (points[None, :, 0] < hi[:, None, 0])
        & (points[None, :, 1] >= lo[:, None, 1]) & (points[None, :, 1] < hi[:, None, 1])
    ).sum(1)
    return np.abs(inside - len(points) * np.prod(hi - lo, axis=1)).max()


@pytest.mark.parametrize("count", [1, 7, 100, 1000, 4096])
def test_fibonacci_lattice_is_stratified(count):
    """One point per column strip of width 1/N, and low discrepancy in any box (000 §5)."""
    rng = np.random.default_rng(count)
    points = mipmap.fibonacci_lattice(count, rng.random(2))
    assert points.shape == (count, 2)
    assert np.all((points >= 0.0) & (points < 1.0))
    strips = np.floor(points[:, 0] * count).astype(int)
    assert np.array_equal(np.sort(strips), np.arange(count))
    if count >= 100:
        boxes = np.sort(rng.random((2000, 2, 2)), axis=1)
        lattice_error = _box_discrepancy(points, boxes)
        random_error = _box_discrepancy(rng.random((count, 2)), boxes)
        # |#points - N·area| stays O(log N) (measured <= 3.4 up to N = 4096) while iid points
        # deviate by O(sqrt N) (9 at N = 100, 85 at N = 4096).
        assert lattice_error <= 5.0
        assert lattice_error < random_error


def test_hierarchical_warping_density_equals_the_pdf():
    """Histogram of warped iid samples at 4x the PDF resolution matches P_t/16 (chi-square)."""
    size, sub = 16, 4
    probability = hot_gradient_pdf(size)
    chain = mipmap.build_mip_chain(probability * size * size)
    rng = np.random.default_rng(11)
    count = 200_000
    uv, texel = mipmap.warp_hierarchical(chain, rng.random((count, 2)))
    assert np.all((uv >= 0.0) & (uv < 1.0))
    # The reported texel is the one the point lies in.
    assert np.array_equal(np.floor(uv * size).astype(int)[:, ::-1], texel)
    fine = size * sub
    counts = np.zeros((fine, fine))
    np.add.at(counts, (np.floor(uv[:, 1] * fine).astype(int), np.floor(uv[:, 0] * fine).astype(int)), 1)
    expected = np.repeat(np.repeat(probability, sub, 0), sub, 1) / sub**2 * count
    assert counts[expected == 0.0].sum() == 0  # zero-PDF texels are never chosen
    mask = expected > 0.0
    chi2 = ((counts[mask] - expected[mask]) ** 2 / expected[mask]).sum()
    dof = mask.sum() - 1
    assert chi2 < dof + 5.0 * np.sqrt(2.0 * dof), (chi2, dof)


def test_hierarchical_warping_keeps_the_lattice_stratified():
    """Warped Fibonacci points: every texel gets N·P_t points up to a few (iid: ~sqrt(N P_t))."""
    size = 16
    probability = hot_gradient_pdf(size)
    chain = mipmap.build_mip_chain(probability * size * size)
    count = 65536
    _, texel = mipmap.warp_hierarchical(chain, mipmap.fibonacci_lattice(count, (0.3, 0.7)))
    counts = np.zeros((size, size))
    np.add.at(counts, (texel[:, 0], texel[:, 1]), 1)
    assert np.abs(counts - count * probability).max() < 4.0  # measured 2.5


# --------------------------------------------------------------------------------------------
# Kernel level (000 Eq. 1, Eq. 3, Algorithm 1)


def _centres(size, count, probability, rotation=(0.1, 0.2)):
    chain = mipmap.build_mip_chain(probability * size * size)
    uv, texel = mipmap.warp_hierarchical(chain, mipmap.fibonacci_lattice(count, rotation))
    return chain, uv, texel


def test_bisection_solves_eq3():
    size, count, k = 32, 64, 1.0
    probability = hot_gradient_pdf(size)
    chain, uv, _ = _centres(size, count, probability)
    top = len(chain) - 1
    level = vsgl.kernel_level_modified(chain, uv, k, count, size * size)
    mass = vsgl.kernel_pdf_mass(chain, uv, level, size * size)
    tolerance = top * 2.0**-12  # final bracket width: the result is within half of it
    interior = (level > tolerance) & (level < top - tolerance)
    assert interior.sum() > count // 2
    np.testing.assert_allclose(mass[interior], k / count, rtol=0.01)
    # Kernels that end at level ~0 sit on texels whose own mass already exceeds K/N.
    low = level <= tolerance
    assert np.all(vsgl.kernel_pdf_mass(chain, uv[low], np.zeros(low.sum()), size * size)
                  >= k / count * 0.99)
    # The bisection of Algorithm 1 with 12 iterations: l = (l_min + l_max)/2 on a grid of top/2^13.
    grid = level / top * 2.0**13
    np.testing.assert_allclose(grid, np.round(grid), atol=1e-9)


def test_bisection_is_monotone_in_k_and_n():
    size = 32
    probability = hot_gradient_pdf(size)
    chain, uv, _ = _centres(size, 128, probability)
    levels_k = [vsgl.kernel_level_modified(chain, uv, k, 128, size * size)
                for k in (0.25, 0.5, 1.0, 2.0, 4.0, 16.0)]
    assert all(np.all(a <= b) for a, b in zip(levels_k, levels_k[1:]))
    assert np.mean(levels_k[-1] - levels_k[0]) > 2.0
    levels_n = [vsgl.kernel_level_modified(chain, uv, 1.0, n, size * size)
                for n in (1, 16, 128, 1024, 65536)]
    assert all(np.all(a >= b) for a, b in zip(levels_n, levels_n[1:]))


def test_bisection_reaches_the_ends_gracefully():
    size = 8
    top = 3
    end = top * 2.0**-13  # Algorithm 1 returns the midpoint of the last bracket
    probability = np.full((size, size), 1.0 / size**2)
    chain, uv, _ = _centres(size, 16, probability)
    # K/N >= 1: the whole RSM is one kernel.
    for k, n in ((1.0, 1), (16.0, 4), (1e6, 16)):
        level = vsgl.kernel_level_modified(chain, uv[:n], k, n, size**2)
        np.testing.assert_allclose(level, top - end, rtol=0, atol=1e-12)
    # K/N below one texel's mass: single texels.
    level = vsgl.kernel_level_modified(chain, uv, 0.25, 4096, size**2)
    np.testing.assert_allclose(level, end, rtol=0, atol=1e-12)
    # 1x1 RSM: top level 0.
    chain1 = mipmap.build_mip_chain(np.ones((1, 1)))
    np.testing.assert_array_equal(
        vsgl.kernel_level_modified(chain1, np.array([[0.3, 0.8]]), 1.0, 10, 1), [0.0])


def test_original_kernel_level_eq1():
    """4^l / M = min(K / (N p(x_i)), 1), clamped to [0, top] (000 Eq. 1)."""
    m, top = 1024, 5
    p = np.array([1e-9, 0.01, 0.5, 1.0, 2.0, 7.0, 1e9])
    for k, n in ((1.0, 64), (4.0, 64), (1.0, 1)):
        level = vsgl.kernel_level_original(p, k, n, m, top)
        expected_area = np.minimum(k / (n * p), 1.0)
        inside = (expected_area >= 1.0 / m)
        np.testing.assert_allclose(4.0 ** level[inside] / m, expected_area[inside], rtol=1e-12)
        np.testing.assert_array_equal(level[~inside], 0.0)


# --------------------------------------------------------------------------------------------
# VSGL parameters (000 app. B) and the 2-VSGL mode (003)


def test_vsgl_parameters_of_the_whole_rsm_match_appendix_b():
    size = 8
    rsm = make_rsm(size, seed=5)
    totals = vsgl.texel_moments(rsm).reshape(-1, vsgl.MOMENT_CHANNELS).sum(0)
    out = vsgl.vsgl_parameters(totals[None])
    fd = rsm.flux_diffuse.reshape(-1, 3)
    fs = rsm.flux_specular.reshape(-1, 3)
    y = rsm.position.reshape(-1, 3)
    w = (fd + fs) @ LUM
    amp, axis, lam, mu, var = brute_force_vsgl(fd, rsm.normal.reshape(-1, 3),
                                               np.full(size * size, LAMBDA_D), w, y)
    # The texels' diffuse lobes are 000 Eq. 6's SG normalized over the hemisphere.
    np.testing.assert_allclose(out["diffuse_amplitude"][0], amp * DIFFUSE_HEMISPHERE_SCALE, rtol=1e-10)
    np.testing.assert_allclose(out["diffuse_axis"][0], axis, rtol=1e-12)
    np.testing.assert_allclose(out["diffuse_sharpness"][0], lam, rtol=1e-10)
    np.testing.assert_allclose(out["mean"][0], mu, rtol=1e-12)
    np.testing.assert_allclose(out["variance"][0], var, rtol=1e-10)
    amp, axis, lam, _, _ = brute_force_vsgl(fs, rsm.specular_axis.reshape(-1, 3),
                                            rsm.specular_sharpness.reshape(-1), w, y)
    np.testing.assert_allclose(out["specular_amplitude"][0], amp, rtol=1e-10)
    np.testing.assert_allclose(out["specular_axis"][0], axis, rtol=1e-12)
    np.testing.assert_allclose(out["specular_sharpness"][0], lam, rtol=1e-10)
    np.testing.assert_allclose(out["power"][0], (fd + fs).sum(0), rtol=1e-13)
    # c_v A(λ_v) = Σ ΦR (000 app. B.1), the diffuse lobe's over the hemisphere: (1 + e^(-λd)) Σ ΦRd
    # over the sphere.
    np.testing.assert_allclose(out["diffuse_amplitude"][0] * sg_integral(out["diffuse_sharpness"][0]),
                               fd.sum(0) * DIFFUSE_HEMISPHERE_SCALE, rtol=1e-12)


def test_flat_cluster_diffuse_vsgl_emits_its_power_above_the_surface():
    """A flat reflector's VSGL diffuse lobe (λv = λd) puts Σ ΦRd into the reflector's hemisphere
    (quadrature), as a Lambertian surface does; 000 Eq. 6 as printed (sphere-normalized) put 88 %."""
    from vsgl_addon.reference.quadrature import sphere_quadrature

    size = 4
    rsm = make_rsm(size, seed=2)
    normal = np.broadcast_to(np.array([0.0, 0.6, 0.8]), rsm.normal.shape).copy()
    rsm = vsgl.RSM(rsm.position, normal, rsm.flux_diffuse, rsm.flux_specular, rsm.specular_axis,
                   rsm.specular_sharpness)
    out = vsgl.vsgl_parameters(vsgl.texel_moments(rsm).reshape(-1, vsgl.MOMENT_CHANNELS).sum(0)[None])
    np.testing.assert_allclose(out["diffuse_sharpness"][0], LAMBDA_D, rtol=1e-9)
    axis, lam = out["diffuse_axis"][0], out["diffuse_sharpness"][0]
    n = normal[0, 0]
    above = sphere_quadrature(lambda w: np.exp(lam * (w @ axis - 1.0)) * (w @ n > 0.0), n, equator=True)
    np.testing.assert_allclose(above * out["diffuse_amplitude"][0], rsm.flux_diffuse.reshape(-1, 3).sum(0),
                               rtol=1e-6)


def test_per_lobe_positions_are_each_lobes_power_centroid():
    """'per-lobe': µ, σ² of each lobe weighted by its own power (lum Φ Rd, resp. lum Φ Rs), the
    formulas of 000 app. B.2 with the lobe's weight; 'shared' and ``mean``/``variance``: the paper's
    weight lum Φ (Rd + Rs) for both lobes."""
    size = 8
    rsm = make_rsm(size, seed=7)
    totals = vsgl.texel_moments(rsm).reshape(-1, vsgl.MOMENT_CHANNELS).sum(0)
    fd = rsm.flux_diffuse.reshape(-1, 3)
    fs = rsm.flux_specular.reshape(-1, 3)
    y = rsm.position.reshape(-1, 3)
    per_lobe = vsgl.vsgl_parameters(totals[None], positional_distribution="per-lobe")
    shared = vsgl.vsgl_parameters(totals[None], positional_distribution="shared")
    for lobe, flux in (("diffuse", fd), ("specular", fs)):
        weight = flux @ LUM
        mu = (weight[:, None] * y).sum(0) / weight.sum()
        var = (weight * ((y - mu) ** 2).sum(-1)).sum() / weight.sum()
        np.testing.assert_allclose(per_lobe[f"{lobe}_mean"][0], mu, rtol=1e-12)
        np.testing.assert_allclose(per_lobe[f"{lobe}_variance"][0], var, rtol=1e-10)
        np.testing.assert_array_equal(shared[f"{lobe}_mean"], shared["mean"])
        np.testing.assert_array_equal(shared[f"{lobe}_variance"], shared["variance"])
    for key in ("mean", "variance", "diffuse_amplitude", "specular_axis", "power"):
        np.testing.assert_array_equal(per_lobe[key], shared[key])
    with pytest.raises(ValueError, match="positional_distribution"):
        vsgl.vsgl_parameters(totals[None], positional_distribution="split")
    with pytest.raises(ValueError, match="positional_distribution"):
        vsgl.generate_vsgls(rsm, 4, positional_distribution="")


def test_per_lobe_positions_keep_two_materials_apart():
    """A cluster spanning a diffuse-only floor and a specular-only (metal) block above it: the
    shared mean floats between the two surfaces, the per-lobe means stay on each; a lobe without
    power takes the combined position (finite). Where every texel has the same Rd : Rs the two
    distributions coincide."""
    size = 8
    v, u = _grid(size)
    metal = u > 0.5
    position = np.stack([u, v, np.where(metal, 1.0, 0.0)], -1)
    normal = np.broadcast_to([0.0, 0.0, 1.0], (size, size, 3)).copy()
    flux_d = np.where(metal[..., None], 0.0, 1.0) * np.ones((size, size, 3))
    flux_s = np.where(metal[..., None], 3.0, 0.0) * np.ones((size, size, 3))
    rsm = vsgl.RSM(position, normal, flux_d, flux_s, normal, np.full((size, size), 100.0))
    uniform = np.ones((size, size))  # N = 1, K = 1, p = 1: Eq. 1 gives the whole RSM
    per_lobe = vsgl.generate_vsgls(rsm, 1, kernel="original", seed=None, pdf=uniform,
                                   positional_distribution="per-lobe")
    shared = vsgl.generate_vsgls(rsm, 1, kernel="original", seed=None, pdf=uniform,
                                 positional_distribution="shared")
    assert per_lobe["kernel_level"][0] == 3.0  # one cluster: the whole RSM
    np.testing.assert_allclose(per_lobe["diffuse_mean"][0, 2], 0.0, atol=1e-14)
    np.testing.assert_allclose(per_lobe["specular_mean"][0, 2], 1.0, rtol=1e-14)
    np.testing.assert_allclose(shared["diffuse_mean"][0, 2], 0.75, rtol=1e-12)  # 3 : 1 power
    np.testing.assert_allclose(per_lobe["diffuse_mean"][0, :2], [0.25, 0.5], rtol=1e-12)
    # A cluster of the floor alone has no specular power: its specular lobe sits at the combined mean.
    floor_only = vsgl.RSM(position, normal, flux_d, 0.0 * flux_s, normal, np.full((size, size), 100.0))
    out = vsgl.generate_vsgls(floor_only, 4, positional_distribution="per-lobe")
    np.testing.assert_array_equal(out["specular_mean"], out["mean"])
    np.testing.assert_array_equal(out["specular_variance"], out["variance"])
    assert all_finite(out)
    # Same Rd : Rs everywhere: both distributions give the same positions (to rounding).
    rsm = make_rsm(16, seed=3, flux_specular=0.25 * make_rsm(16, seed=3).flux_diffuse)
    a = vsgl.generate_vsgls(rsm, 64, positional_distribution="per-lobe")
    b = vsgl.generate_vsgls(rsm, 64, positional_distribution="shared")
    for key in ("diffuse_mean", "specular_mean"):
        np.testing.assert_allclose(a[key], b[key], rtol=1e-10, atol=1e-12)
    for key in ("diffuse_variance", "specular_variance"):
        np.testing.assert_allclose(a[key], b[key], rtol=1e-8)


def test_toksvig_round_trip_for_identical_lobes():
    """All VPLs with the same lobe: λ_v recovers the VPLs' λ (000 app. B.1)."""
    size = 4
    n = np.broadcast_to(_unit(np.array([0.2, -0.1, 1.0])), (size, size, 3))
    flux = np.ones((size, size, 3))
    rsm = vsgl.RSM(np.zeros((size, size, 3)), n, flux, flux, n, np.full((size, size), 50.0))
    out = vsgl.generate_vsgls(rsm, 16, seed=1)
    np.testing.assert_allclose(out["diffuse_sharpness"], LAMBDA_D, rtol=1e-12)
    np.testing.assert_allclose(out["specular_sharpness"], 50.0, rtol=1e-10)
    np.testing.assert_allclose(out["diffuse_axis"], np.broadcast_to(n[0, 0], (16, 3)), rtol=1e-13)


def test_two_vsgl_mode_matches_whole_rsm_totals_and_is_exact():
    size = 16
    rsm = make_rsm(size, seed=2)
    out = vsgl.generate_vsgls(rsm, 999, kernel="two-vsgl")
    check_sane(out, 2, 4)
    fd = rsm.flux_diffuse.reshape(-1, 3)
    fs = rsm.flux_specular.reshape(-1, 3)
    y = rsm.position.reshape(-1, 3)
    total = (fd + fs).sum(0)
    np.testing.assert_allclose(out["rsm_total_power"], total, rtol=1e-14)
    np.testing.assert_allclose(out["power"].sum(0), total, rtol=1e-14)
    np.testing.assert_allclose(out["power"], [fd.sum(0), fs.sum(0)], rtol=1e-14)
    amp, axis, lam, mu, var = brute_force_vsgl(fd, rsm.normal.reshape(-1, 3),
                                               np.full(size * size, LAMBDA_D), fd @ LUM, y)
    np.testing.assert_allclose(out["diffuse_amplitude"][0], amp * DIFFUSE_HEMISPHERE_SCALE, rtol=1e-10)
    np.testing.assert_allclose(out["diffuse_axis"][0], axis, rtol=1e-12)
    np.testing.assert_allclose(out["diffuse_sharpness"][0], lam, rtol=1e-10)
    np.testing.assert_allclose(out["mean"][0], mu, rtol=1e-12)
    np.testing.assert_allclose(out["variance"][0], var, rtol=1e-10)
    amp, axis, lam, mu, var = brute_force_vsgl(fs, rsm.specular_axis.reshape(-1, 3),
                                               rsm.specular_sharpness.reshape(-1), fs @ LUM, y)
    np.testing.assert_allclose(out["specular_amplitude"][1], amp, rtol=1e-10)
    np.testing.assert_allclose(out["specular_axis"][1], axis, rtol=1e-12)
    np.testing.assert_allclose(out["specular_sharpness"][1], lam, rtol=1e-10)
    np.testing.assert_allclose(out["mean"][1], mu, rtol=1e-12)
    np.testing.assert_allclose(out["variance"][1], var, rtol=1e-10)
    # One lobe per VSGL.
    np.testing.assert_array_equal(out["specular_amplitude"][0], 0.0)
    np.testing.assert_array_equal(out["diffuse_amplitude"][1], 0.0)


# --------------------------------------------------------------------------------------------
# Unbiasedness of the summed power (000 Eqs. 4-5)


@pytest.mark.parametrize("kernel", ["modified", "original"])
@pytest.mark.parametrize("pdf_kind", ["default", "smooth"])
def test_summed_power_is_unbiased_over_lattice_rotations(kernel, pdf_kind):
    """Mean over 100 random rotations of Σ_i power_i = RSM total within 1 % (measured <= 0.5 %).

    Filtered importance sampling is biased where the PDF varies at the kernel's scale (the level
    varies with x_i, and Eq. 5's p̄ is not the sampling density); for this smooth RSM with
    N = 256 kernels of ~4 texels the bias is below 0.5 %, a normalization error (M, 4^l, K) would
    be a factor.
    """
    size, count = 32, 256
    rsm = make_rsm(size)
    pdf = None if pdf_kind == "default" else smooth_pdf(size)
    sums = np.array([
        vsgl.generate_vsgls(rsm, count, kernel=kernel, seed=seed, pdf=pdf)["power"].sum(0)
        for seed in range(100)
    ])
    total = (rsm.flux_diffuse + rsm.flux_specular).reshape(-1, 3).sum(0)
    np.testing.assert_allclose(sums.mean(0), total, rtol=0.01)


@pytest.mark.parametrize("k", [0.25, 1.0, 4.0, 16.0])
def test_modified_estimate_is_exact_when_the_pdf_is_proportional_to_the_flux(k):
    """Eq. 5 divides f̄ by the same filter of p: for p ∝ f every lattice gives the exact total."""
    size = 32
    rng = np.random.default_rng(8)
    grey = rng.exponential(size=(size, size))
    grey[rng.random((size, size)) < 0.3] = 0.0
    flux = grey[..., None] * np.array([0.5, 0.5, 0.5])
    rsm = make_rsm(size, flux_diffuse=flux, flux_specular=0.5 * flux)
    for seed in range(3):
        out = vsgl.generate_vsgls(rsm, 100, k=k, seed=seed)
        np.testing.assert_allclose(out["power"].sum(0), out["rsm_total_power"], rtol=1e-11)
        # f̄/p̄ is the same for every kernel, whatever its level: each carries total/N.
        np.testing.assert_allclose(out["power"], np.broadcast_to(out["rsm_total_power"] / 100,
                                                                 (100, 3)), rtol=1e-11)


def test_original_eq4_clamp_returns_the_rsm_total_for_whole_rsm_kernels():
    """N p(x_i) <= 1 with K = 1: the kernel is the whole RSM and carries its total (000 Eq. 4)."""
    size = 8
    rsm = make_rsm(size)
    probability = np.full((size, size), 0.5 / 32)
    probability[:4] = 1.5 / 32  # densities 0.5 (bottom half) and 1.5 (top half)
    total = (rsm.flux_diffuse + rsm.flux_specular).reshape(-1, 3).sum(0)
    seen_low = False
    for seed in range(8):
        out = vsgl.generate_vsgls(rsm, 1, kernel="original", seed=seed, pdf=probability)
        if out["kernel_center"][0, 1] >= 0.5:  # density 0.5: N p = 0.5 < 1
            seen_low = True
            np.testing.assert_allclose(out["kernel_level"], 3.0)
            np.testing.assert_allclose(out["power"][0], total, rtol=1e-12)
        else:  # density 1.5: area 1/1.5, estimate = M F̄ / 1.5
            np.testing.assert_allclose(4.0 ** out["kernel_level"] / 64, 1 / 1.5, rtol=1e-12)
    assert seen_low


# --------------------------------------------------------------------------------------------
# The paper's Fig. 1 claim: equal PDF mass per kernel


def _box_pdf_mass(probability, centres, level):
    """∫ p g for the box kernel of side 2^l texels centred at x_i (exact, partial texels)."""
    size = probability.shape[0]
    sat = np.zeros((size + 1, size + 1))
    sat[1:, 1:] = probability.cumsum(0).cumsum(1)

    def integral(u, v):  # ∫ over [0,u]x[0,v]: bilinear inside each texel of the SAT grid
        s = np.clip(u, 0.0, 1.0) * size
        t = np.clip(v, 0.0, 1.0) * size
        j = np.minimum(np.floor(s).astype(int), size - 1)
        i = np.minimum(np.floor(t).astype(int), size - 1)
        fx, fy = s - j, t - i
        return ((1 - fy) * ((1 - fx) * sat[i, j] + fx * sat[i, j + 1])
                + fy * ((1 - fx) * sat[i + 1, j] + fx * sat[i + 1, j + 1]))

    half = 0.5 * 2.0**level / size
    u, v = centres[:, 0], centres[:, 1]
    return (integral(u + half, v + half) - integral(u - half, v + half)
            - integral(u + half, v - half) + integral(u - half, v - half))


@pytest.mark.parametrize("pattern", ["checker", "noise"])
def test_modified_kernels_have_equal_pdf_mass(pattern):
    """CV over kernels of the PDF mass inside each kernel: modified at least 3x below original.

    Measured on a 128² RSM, N = 256, K = 1: fine checker 0.10 vs 2.06 (~20x), exponential noise
    0.13 vs 1.48 (~12x). The mass is integrated over a centred box of area 4^l/M, independent of
    the trilinear lookup the bisection solves with (whose mass is K/N by construction).
    """
    size, count = 128, 256
    rng = np.random.default_rng(21)
    if pattern == "checker":
        i, j = np.mgrid[0:size, 0:size]
        texture = np.where((i + j) % 2 == 0, 1.0, 0.05)
    else:
        texture = rng.exponential(size=(size, size))
    v, u = _grid(size)
    flux = (texture * (0.5 + u))[..., None] * np.ones(3)
    rsm = make_rsm(size, flux_diffuse=flux, flux_specular=0.2 * flux)
    probability = vsgl.default_pdf(rsm)
    cv = {}
    for kernel in ("modified", "original"):
        values = []
        for seed in range(2):
            out = vsgl.generate_vsgls(rsm, count, kernel=kernel, seed=seed)
            mass = _box_pdf_mass(probability, out["kernel_center"], out["kernel_level"])
            values.append(mass.std() / mass.mean())
        cv[kernel] = np.mean(values)
    assert cv["original"] >= 3.0 * cv["modified"], cv


# --------------------------------------------------------------------------------------------
# Extremes: no NaN or Inf anywhere


@pytest.mark.parametrize("kernel", vsgl.KERNEL_MODES)
def test_empty_rsm_gives_zero_power_vsgls(kernel):
    size = 8
    rsm = make_rsm(size, flux_diffuse=np.zeros((size, size, 3)),
                   flux_specular=np.zeros((size, size, 3)))
    # Background texels may hold garbage: it must not leak.
    rsm = vsgl.RSM(np.full((size, size, 3), np.nan), np.zeros((size, size, 3)),
                   rsm.flux_diffuse, rsm.flux_specular, np.zeros((size, size, 3)),
                   np.full((size, size), np.inf))
    out = vsgl.generate_vsgls(rsm, 32, kernel=kernel)
    count = 2 if kernel == "two-vsgl" else 32
    check_sane(out, count, 3)
    for key in ("power", "diffuse_amplitude", "specular_amplitude", "rsm_total_power"):
        np.testing.assert_array_equal(out[key], 0.0)
    np.testing.assert_array_equal(out["variance"], vsgl.VARIANCE_FLOOR_ABSOLUTE)


@pytest.mark.parametrize("kernel", vsgl.KERNEL_MODES)
def test_single_lit_texel(kernel):
    size = 16
    flux = np.zeros((size, size, 3))
    flux[5, 9] = [2.0, 1.0, 0.5]
    rsm = make_rsm(size, flux_diffuse=flux, flux_specular=0.5 * flux)
    count = 64
    out = vsgl.generate_vsgls(rsm, count, kernel=kernel)
    n_out = 2 if kernel == "two-vsgl" else count
    check_sane(out, n_out, 4)
    np.testing.assert_allclose(out["mean"], np.broadcast_to(rsm.position[5, 9], (n_out, 3)),
                               rtol=1e-12)
    y2 = rsm.position[5, 9] @ rsm.position[5, 9]
    np.testing.assert_allclose(out["variance"], max(vsgl.VARIANCE_FLOOR_RELATIVE * y2, 1e-12),
                               rtol=1e-6)
    diffuse = out["diffuse_amplitude"].sum(-1) > 0
    np.testing.assert_allclose(out["diffuse_sharpness"][diffuse], LAMBDA_D, rtol=1e-10)
    np.testing.assert_allclose(out["diffuse_axis"][diffuse],
                               np.broadcast_to(rsm.normal[5, 9], (diffuse.sum(), 3)), rtol=1e-12)
    if kernel != "original":  # Eq. 4 is not exact here: its f̄ is filtered, its p is not
        np.testing.assert_allclose(out["power"].sum(0), 1.5 * flux[5, 9], rtol=1e-12)
    if kernel == "modified":  # every kernel lands on the texel
        assert np.all(np.floor(out["kernel_center"] * size).astype(int) == [9, 5])


@pytest.mark.parametrize("kernel", vsgl.KERNEL_MODES)
def test_one_by_one_rsm(kernel):
    rsm = make_rsm(1)
    out = vsgl.generate_vsgls(rsm, 5, kernel=kernel)
    n_out = 2 if kernel == "two-vsgl" else 5
    check_sane(out, n_out, 0)
    np.testing.assert_allclose(out["power"].sum(0), out["rsm_total_power"], rtol=1e-13)
    np.testing.assert_array_equal(out["kernel_level"], 0.0)


@pytest.mark.parametrize("kernel", vsgl.KERNEL_MODES)
def test_identical_vpls(kernel):
    """Same position, normal, flux, lobe: |ξ̄_v| -> the VPLs' and σ_v² -> 0, clamped."""
    size = 16
    position = np.broadcast_to([1.0, 2.0, 3.0], (size, size, 3))
    normal = np.broadcast_to([0.0, 0.0, 1.0], (size, size, 3))
    flux = np.ones((size, size, 3))
    rsm = vsgl.RSM(position, normal, flux, flux, normal, np.full((size, size), 1e12))
    out = vsgl.generate_vsgls(rsm, 64, kernel=kernel)
    n_out = 2 if kernel == "two-vsgl" else 64
    check_sane(out, n_out, 4)
    np.testing.assert_allclose(out["variance"], 14.0 * vsgl.VARIANCE_FLOOR_RELATIVE, rtol=1e-6)
    specular = out["specular_amplitude"].sum(-1) > 0
    np.testing.assert_allclose(out["specular_sharpness"][specular], vsgl.MAX_SHARPNESS, rtol=1e-9)
    np.testing.assert_allclose(out["power"].sum(0), out["rsm_total_power"], rtol=1e-12)


@pytest.mark.parametrize("kernel", ["modified", "original"])
@pytest.mark.parametrize("count,size,k", [(1, 16, 1.0), (4096, 64, 1.0), (256, 32, 0.25),
                                          (256, 32, 16.0)])
def test_counts_sizes_and_k(kernel, count, size, k):
    rsm = make_rsm(size, seed=count)
    out = vsgl.generate_vsgls(rsm, count, k=k, kernel=kernel, seed=count)
    check_sane(out, count, int(np.log2(size)))
    np.testing.assert_allclose(out["power"].sum(0), out["rsm_total_power"], rtol=0.1)


@pytest.mark.parametrize("roughness", [1e-3, 1.0])
@pytest.mark.parametrize("kernel", vsgl.KERNEL_MODES)
def test_specular_sharpness_from_roughness(roughness, kernel):
    size = 16
    rsm = make_rsm(size)
    v, u = _grid(size)
    # Incidence from normal to near grazing: λ_s = 2/α² / (4 |w'.n|) ~ 5e5 ... 3.7e7 at α = 1e-3.
    incoming = _unit(np.stack([u * 8.0, v - 0.5, np.full_like(u, 0.2)], -1))
    axis, lam = specular_lobe_warp(incoming, rsm.normal, roughness)
    rsm = vsgl.RSM(rsm.position, rsm.normal, rsm.flux_diffuse, rsm.flux_specular, axis, lam)
    out = vsgl.generate_vsgls(rsm, 128, kernel=kernel)
    check_sane(out, 2 if kernel == "two-vsgl" else 128, 4)
    if roughness == 1e-3:
        assert lam.max() > 1e7  # the input reaches near-grazing sharpness (3.7e7)
    # The sharpness clamp keeps each lobe's energy (check_sane: Σ c_v A(λ_v) = power).


@pytest.mark.parametrize("kernel", vsgl.KERNEL_MODES)
def test_mirror_lobes_at_normal_incidence_keep_their_sharpness(kernel):
    """Flat mirror lit head-on, α = 1e-3: every VPL has λ_s = 2/α² / 4 = 5e5 < MAX_SHARPNESS."""
    size = 16
    rsm = make_rsm(size)
    normal = np.broadcast_to([0.0, 0.0, 1.0], (size, size, 3))
    axis, lam = specular_lobe_warp(normal, normal, 1e-3)
    rsm = vsgl.RSM(rsm.position, normal, rsm.flux_diffuse, rsm.flux_specular, axis, lam)
    out = vsgl.generate_vsgls(rsm, 64, kernel=kernel)
    check_sane(out, 2 if kernel == "two-vsgl" else 64, 4)
    specular = out["specular_amplitude"].sum(-1) > 0
    np.testing.assert_allclose(out["specular_sharpness"][specular], 5e5, rtol=1e-8)


def test_mapping_input_and_argument_checks():
    rsm = make_rsm(4)
    as_dict = {name: getattr(rsm, name) for name in vsgl.RSM.__dataclass_fields__}
    a = vsgl.generate_vsgls(as_dict, 8, seed=3)
    b = vsgl.generate_vsgls(rsm, 8, seed=3)
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])
    c = vsgl.generate_vsgls(rsm, 8, seed=None, rotation=(1.25, -0.5))
    d = vsgl.generate_vsgls(rsm, 8, seed=7, rotation=(0.25, 0.5))
    np.testing.assert_array_equal(c["kernel_center"], d["kernel_center"])
    with pytest.raises(ValueError):
        vsgl.generate_vsgls(rsm, 8, kernel="kmeans")
    with pytest.raises(ValueError):
        vsgl.generate_vsgls(rsm, 0)
    with pytest.raises(ValueError):
        vsgl.generate_vsgls(rsm, 8, k=0.0)
    with pytest.raises(ValueError):
        vsgl.generate_vsgls({**as_dict, "flux_diffuse": -as_dict["flux_diffuse"]}, 8)
    with pytest.raises(ValueError):
        vsgl.generate_vsgls(rsm, 8, pdf=np.ones((8, 8)))


# --------------------------------------------------------------------------------------------
# Kernels across depth discontinuities (texel_areas, straddles, kernel_level_unstraddled)


def _plane_rsm(size, heights, tilt=0.0, texel=0.25, flux=1.0):
    """A sun's orthographic RSM looking down −z at planes: texel (column c, row r) at x = (c + ½) w,
    y = (r + ½) w, z = heights[r, c] + tan(tilt) x, so each texel covers w² / cos(tilt); uniform
    diffuse flux, normals of the tilted plane."""
    v, u = _grid(size)
    x, y = u * size * texel, v * size * texel
    z = np.asarray(heights, np.float64) + np.tan(tilt) * x
    position = np.stack([x, y, z], -1)
    normal = np.broadcast_to(_unit(np.array([-np.sin(tilt), 0.0, np.cos(tilt)])), position.shape).copy()
    flux_d = np.full((size, size, 3), flux)
    zero = np.zeros((size, size, 3))
    return vsgl.RSM(position, normal, flux_d, zero, normal.copy(), np.zeros((size, size)))


@pytest.mark.parametrize("tilt", [0.0, 0.6, 1.2])
def test_texel_areas_of_a_plane_are_its_texels_surface_area(tilt):
    """On one plane every texel's one-sided differences span exactly its footprint w² / cos θ."""
    rsm = _plane_rsm(16, np.zeros((16, 16)), tilt=tilt)
    np.testing.assert_allclose(vsgl.texel_areas(rsm), 0.25**2 / np.cos(tilt), rtol=1e-12)


def test_texel_areas_take_the_side_of_a_depth_jump_that_is_the_texel_own_surface():
    """Beside a 3 m step each texel's area is still its plane's (the other side spans the jump);
    an unlit texel has none and a texel with no lit neighbour on one axis takes the other's."""
    heights = np.zeros((16, 16))
    heights[:, 8:] = 3.0
    rsm = _plane_rsm(16, heights)
    np.testing.assert_allclose(vsgl.texel_areas(rsm), 0.25**2, rtol=1e-12)
    flux = rsm.flux_diffuse.copy()
    flux[:, 5] = 0.0
    flux[:, 7] = 0.0
    cut = vsgl.RSM(rsm.position, rsm.normal, flux, rsm.flux_specular, rsm.specular_axis, rsm.specular_sharpness)
    areas = vsgl.texel_areas(cut)
    assert np.all(areas[:, 5] == 0.0)
    np.testing.assert_allclose(areas[:, 6], 0.25**2, rtol=1e-12)  # rows still give |Δv|²


@pytest.mark.parametrize("tilt", [0.0, 1.3])
def test_no_jump_on_one_plane_even_at_grazing_light(tilt):
    """A plane at 75° from the light (texels 3.9x longer than wide) has no jump texel, so no kernel
    on one surface descends."""
    size = 32
    rsm = _plane_rsm(size, np.zeros((size, size)), tilt=tilt)
    assert not vsgl.texel_jumps(rsm).any()
    maps = vsgl.build_mipmaps(rsm)
    center = np.random.default_rng(3).uniform(0.0, 1.0, (100, 2))
    level = np.random.default_rng(4).uniform(0.0, 5.0, 100)
    texel = np.floor(center[:, ::-1] * size).astype(np.int64)
    new_level, new_center = vsgl.kernel_level_unstraddled(maps, center, texel, level, split=True)
    np.testing.assert_array_equal(new_level, level)
    np.testing.assert_array_equal(new_center, center)


def test_jump_texels_are_the_two_sides_of_a_depth_step():
    """A 3 m step (12 texel sizes) flags the columns on both sides of it and nothing else; a 0.5 m
    step (2 texel sizes, a continuous slope at the RSM's resolution) flags nothing."""
    heights = np.zeros((16, 16))
    heights[:, 8:] = 3.0
    jumps = vsgl.texel_jumps(_plane_rsm(16, heights))
    expected = np.zeros((16, 16), bool)
    expected[:, 7:9] = True
    np.testing.assert_array_equal(jumps, expected)
    heights[:, 8:] = 0.5
    assert not vsgl.texel_jumps(_plane_rsm(16, heights)).any()


def _facing(rsm, column, normal=(0.0, 1.0, 0.0)):
    """The RSM with the texels from ``column`` on facing ``normal`` (a wall's face beside the ground)."""
    normals = rsm.normal.copy()
    normals[:, column:] = _unit(np.array(normal))
    return vsgl.RSM(rsm.position, normals, rsm.flux_diffuse, rsm.flux_specular, rsm.specular_axis,
                    rsm.specular_sharpness)


def test_layers_facing_one_way_keep_their_kernels():
    """A roof over the ground, both facing up: the kernels over the jump hold one normal
    (NORMAL_AGREEMENT), so none descends; the same step with the roof facing sideways descends."""
    size = 64
    heights = np.zeros((size, size))
    heights[:, 29:] = 3.0
    rsm = _plane_rsm(size, heights)
    same = vsgl.generate_vsgls(rsm, 64, seed=2, split_at_jumps=True)
    whole = vsgl.generate_vsgls(rsm, 64, seed=2, split_at_jumps=False)
    np.testing.assert_array_equal(same["kernel_level"], whole["kernel_level"])
    turned = vsgl.generate_vsgls(_facing(rsm, 29), 64, seed=2, split_at_jumps=True)
    assert np.sum(turned["kernel_level"] < whole["kernel_level"] - 0.5) >= 3


def test_no_vsgl_straddles_a_depth_step_after_the_descent():
    """A ground at z = 0 beside a raised face at z = 3 turned towards +y (sun from above, 64² texels
    of 0.25 m): without the
    descent some of N = 64 VSGLs have their mean in the air between the two (a cluster of both
    sides); with it no VSGL's mean lies farther than 10 % of the step from both planes (a kernel
    keeps up to 5 % of the other side, NORMAL_AGREEMENT at 90°), and the
    summed power over 32 lattice rotations stays the RSM total within 2 % (the descended kernels
    no longer tile the RSM near the step)."""
    size, count = 64, 64
    heights = np.zeros((size, size))
    heights[:, 29:] = 3.0
    rsm = _facing(_plane_rsm(size, heights), 29)
    total = rsm.flux_diffuse.reshape(-1, 3).sum(0)
    floating_before, floating_after, sums = 0, 0, []
    for seed in range(32):
        before = vsgl.generate_vsgls(rsm, count, seed=seed, split_at_jumps=False)
        after = vsgl.generate_vsgls(rsm, count, seed=seed, split_at_jumps=True)
        gap = lambda z: np.minimum(np.abs(z), np.abs(z - 3.0))  # noqa: E731
        floating_before += int((gap(before["mean"][:, 2]) > 0.3).sum())
        floating_after += int((gap(after["mean"][:, 2]) > 0.3).sum())
        assert np.all(after["kernel_level"] <= before["kernel_level"] + 1e-12)
        sums.append(after["power"].sum(0))
    assert floating_before > 32
    assert floating_after == 0
    np.testing.assert_allclose(np.mean(sums, axis=0), total, rtol=0.02)


# --------------------------------------------------------------------------------------------
# Plane-split clusters (vsgl.PLANE_SPLIT)


def corner_rsm(size=32, fold=16, texel=0.1, seed=0):
    """A room's corner seen by a point light's cube face: columns before ``fold`` a floor (z = 0,
    normal +z), the rest a wall rising from its edge (x = fold · texel, normal −x), with a
    varied diffuse flux and a glossy lobe."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:size, 0:size]
    floor = u < fold
    x = np.where(floor, (u + 0.5) * texel, fold * texel)
    z = np.where(floor, 0.0, (u - fold + 0.5) * texel)
    position = np.stack([x, (v + 0.5) * texel, z], -1).astype(np.float64)
    normal = np.where(floor[..., None], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0])
    flux_d = np.stack([0.5 + 0.2 * rng.random((size, size)), 0.6 + 0.01 * v, np.full((size, size), 0.4)], -1)
    incoming = _unit(np.stack([np.ones((size, size)), 0.2 * np.ones((size, size)), np.ones((size, size))], -1))
    axis, lam = specular_lobe_warp(incoming, normal, np.full((size, size), 0.3))
    return vsgl.RSM(position, normal, flux_d, 0.1 * flux_d, axis, lam)


@pytest.mark.parametrize("count", [1, 4, 16, 64])
def test_plane_split_keeps_each_kernel_power_and_gives_each_plane_a_flat_vsgl(count):
    """Over a floor-wall corner, splitting moves no power (each kernel's VSGLs sum to 000's
    cluster, the specular lobe stays in the kernel's VSGL) and every extra VSGL is one plane's:
    a flat lobe along its normal (λ = 2) with its mean on that plane."""
    rsm = corner_rsm()
    whole = vsgl.generate_vsgls(rsm, count, seed=3, plane_split=False)
    split = vsgl.generate_vsgls(rsm, count, seed=3, plane_split=True)
    extra = len(split["power"]) - count
    assert extra >= 1
    np.testing.assert_allclose(split["power"].sum(0), whole["power"].sum(0), rtol=1e-12)
    np.testing.assert_allclose(split["specular_amplitude"][:count], whole["specular_amplitude"], rtol=1e-12)
    assert np.all(split["specular_amplitude"][count:] == 0.0)
    for key in ("kernel_center", "kernel_level"):
        np.testing.assert_array_equal(split[key][:count], whole[key])
    # Each extra VSGL belongs to one kernel's centre: its kernel's power is the sum of its parts.
    for i in range(count):
        parts = np.all(split["kernel_center"][count:] == whole["kernel_center"][i], axis=1)
        np.testing.assert_allclose(split["power"][i] + split["power"][count:][parts].sum(0), whole["power"][i],
                                   rtol=1e-10)
    axis, lam = split["diffuse_axis"][count:], split["diffuse_sharpness"][count:]
    on_floor = np.isclose(axis, [0.0, 0.0, 1.0], atol=1e-9).all(axis=1)
    on_wall = np.isclose(axis, [-1.0, 0.0, 0.0], atol=1e-9).all(axis=1)
    assert np.all(on_floor | on_wall)
    np.testing.assert_allclose(lam, 2.0, rtol=1e-9)
    mean = split["diffuse_mean"][count:]
    np.testing.assert_allclose(mean[on_floor, 2], 0.0, atol=1e-12)
    np.testing.assert_allclose(mean[on_wall, 0], 1.6, atol=1e-12)


def test_plane_split_leaves_flat_clusters_as_they_are():
    """On a bumpy floor (normals within a few degrees, NORMAL_AGREEMENT) nothing splits: the table
    is 000's, row for row."""
    rsm = _plane_rsm(32, np.zeros((32, 32)), tilt=0.3)
    whole = vsgl.generate_vsgls(rsm, 64, seed=1, plane_split=False)
    split = vsgl.generate_vsgls(rsm, 64, seed=1, plane_split=True)
    for key in vsgl.OUTPUT_KEYS:
        np.testing.assert_array_equal(split[key], whole[key], err_msg=key)


@pytest.mark.parametrize("level", [0.0, 1.3, 2.0, 3.7, 5.0])
def test_plane_classes_sum_to_the_kernel_filter(level):
    """The classes of plane_class_moments regroup the trilinear filter: their sum is
    mipmap.trilinear's diffuse channels at every level, edges included."""
    maps = vsgl.build_mipmaps(corner_rsm())
    center = np.array([[0.47, 0.52], [0.01, 0.99], [0.8, 0.3]])
    classes = vsgl.plane_class_moments(maps, center, np.full(3, level))
    filtered = mipmap.trilinear(maps.moments, center, np.full(3, level))
    diffuse = np.r_[0:6, 12:16]
    np.testing.assert_allclose(classes.sum(axis=1)[:, diffuse], filtered[:, diffuse], rtol=1e-12, atol=1e-15)
    assert np.all(classes[:, :, 6:12] == 0.0) and np.all(classes[:, :, 16:] == 0.0)


def test_plane_split_brings_a_corner_light_closer_to_its_texels():
    """Receivers on the floor's plane beyond the corner and on the wall facing it (no visibility,
    separable diffuse): the VSGLs of 4 kernels over the corner light them closer to the texels'
    own Lambertian light (brute force over every texel) with the split than without, in the mean
    and per receiver."""
    from vsgl_addon.reference.vsgl_shading import shade

    rsm = corner_rsm(32)
    grid = np.linspace(0.3, 2.9, 6)
    floor = np.stack(np.meshgrid(-0.5 - grid / 2, grid, [0.0]), -1).reshape(-1, 3)
    wall = np.stack(np.meshgrid([-1.5], grid, grid / 2), -1).reshape(-1, 3)
    position = np.concatenate([floor, wall])
    normal = np.concatenate([np.tile([0.0, 0.0, 1.0], (len(floor), 1)), np.tile([1.0, 0.0, 0.0], (len(wall), 1))])
    y = rsm.position.reshape(-1, 3)
    n = rsm.normal.reshape(-1, 3)
    phi = rsm.flux_diffuse.reshape(-1, 3)
    d = y[None] - position[:, None]
    dist2 = np.sum(d * d, -1)
    w = d / np.sqrt(dist2)[..., None]
    emit = np.maximum(-np.einsum("pmk,mk->pm", w, n), 0.0) / np.pi
    cos_r = np.maximum(np.einsum("pmk,pk->pm", w, normal), 0.0)
    rd = np.full((len(position), 3), 0.8)
    texels = np.einsum("pm,mc->pc", emit * cos_r / dist2, phi) * rd / np.pi
    view = normal.copy()
    f0 = np.zeros((len(position), 3))
    alpha = np.full(len(position), 1.0)
    errors, means = {}, {}
    for split in (False, True):
        table = vsgl.generate_vsgls(rsm, 4, seed=0, plane_split=split)
        table["specular_amplitude"] = np.zeros_like(table["specular_amplitude"])
        diffuse, _ = shade(table, position, normal, view, rd, f0, alpha, diffuse_mode="separable")
        errors[split] = np.sqrt(np.mean((vsgl.luminance(diffuse) - vsgl.luminance(texels)) ** 2)) / np.mean(
            vsgl.luminance(texels))
        means[split] = np.mean(vsgl.luminance(diffuse)) / np.mean(vsgl.luminance(texels))
    # Measured: mean 0.922 -> 0.960, relative RMSE 0.137 -> 0.127.
    assert abs(1.0 - means[True]) < 0.6 * abs(1.0 - means[False]), means
    assert errors[True] < 0.95 * errors[False], errors


@pytest.mark.parametrize("size, count", [(1, 1), (2, 1), (8, 4096), (8, 5000)])
def test_plane_split_extremes(size, count):
    """A one-texel and a two-texel RSM, N = 4096 (the most that splits: N (1 + PLANE_SPLIT_EXTRA)
    table columns) and N = 5000 (000's clusters, N rows), an unlit corner: finite, no split
    without power, the power kept."""
    rsm = corner_rsm(size, fold=max(size // 2, 1)) if size > 1 else corner_rsm(2, 1)
    if size == 1:
        rsm = vsgl.RSM(*(np.asarray(getattr(rsm, name))[:1, :1] for name in
                         ("position", "normal", "flux_diffuse", "flux_specular", "specular_axis", "specular_sharpness")))
    split = vsgl.generate_vsgls(rsm, count, seed=0, plane_split=True)
    whole = vsgl.generate_vsgls(rsm, count, seed=0, plane_split=False)
    for key in vsgl.OUTPUT_KEYS:
        assert np.all(np.isfinite(split[key])), key
    np.testing.assert_allclose(split["power"].sum(0), whole["power"].sum(0), rtol=1e-10)
    assert len(split["power"]) <= count * (1 + vsgl.PLANE_SPLIT_EXTRA)
    if count > 4096:
        assert len(split["power"]) == count
    dark = vsgl.RSM(rsm.position, rsm.normal, 0.0 * rsm.flux_diffuse, 0.0 * rsm.flux_specular, rsm.specular_axis,
                    rsm.specular_sharpness)
    empty = vsgl.generate_vsgls(dark, min(count, 64), seed=0, plane_split=True)
    assert len(empty["power"]) == min(count, 64)
    for key in vsgl.OUTPUT_KEYS:
        assert np.all(np.isfinite(empty[key])), key
