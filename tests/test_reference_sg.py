# SPDX-License-Identifier: GPL-3.0-or-later
"""vsgl_addon.reference.sg against sphere quadrature (formulas.md section 1), and the quadrature
itself against known integrals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vsgl_addon.reference import measurements, numerics, quadrature, sg, solvers

RTOL = measurements.EXACT_BOUND  # exact identities: 1e-9 relative
X = np.array([1.0, 0.0, 0.0])
Y = np.array([0.0, 1.0, 0.0])
Z = np.array([0.0, 0.0, 1.0])
SHARPNESS = np.logspace(-6.0, 6.0, 13)
ANGLES = np.array([0.0, 1e-6, 1e-3, 0.1, 1.0, 0.5 * np.pi, 3.0, np.pi])


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def rotated(theta, beta=0.0):
    return solvers.direction(theta, beta)


# --------------------------------------------------------------------------------------------------
# The quadrature on analytic integrals.


@pytest.mark.parametrize("axis", [Z, -Z, unit([1.0, 2.0, -3.0])])
def test_quadrature_total_solid_angle(axis):
    assert quadrature.sphere_quadrature(lambda w: np.ones(w.shape[:-1]), axis, n_phi=3) == pytest.approx(
        4.0 * np.pi, rel=1e-14
    )
    # A mild azimuthal stretch still integrates a constant (a strong one is meant for integrands
    # concentrated like the hinted lobe: tests/test_reference_asg.py).
    stretched = quadrature.sphere_quadrature(
        lambda w: np.ones(w.shape[:-1]), axis, tangent=X + Y, bandwidths=(3.0, 1.0), n_phi=128
    )
    assert stretched == pytest.approx(4.0 * np.pi, rel=1e-12)


def test_quadrature_polynomials():
    # Integral of (w.a)^2 over the sphere is 4 pi / 3; of (w.a)(w.b) with a ⟂ b it is 0.
    a = unit([0.3, -0.4, 0.5])
    value = quadrature.sphere_quadrature(
        lambda w: np.sum(w * a, axis=-1) ** 2, unit([1.0, 1.0, 1.0]), n_phi=8
    )
    assert value == pytest.approx(4.0 * np.pi / 3.0, rel=1e-13)
    b = unit(np.cross(a, Z))
    value = quadrature.sphere_quadrature(lambda w: np.sum(w * a, -1) * np.sum(w * b, -1), Z, n_phi=8)
    assert abs(value) < 1e-13


def test_quadrature_sg_integral_closed_form_independent_of_sg_module():
    # exp(lam (w.xi - 1)) written out here, about the lobe axis and about its antipode.
    lam = np.logspace(-6.0, 7.0, 27)
    expected = 2.0 * np.pi * -np.expm1(-2.0 * lam) / lam
    for pole in (Z, -Z):
        got = quadrature.sphere_quadrature(
            lambda w: np.exp(-0.5 * lam[:, None, None] * np.sum((w - Z) ** 2, axis=-1)),
            np.broadcast_to(pole, lam.shape + (3,)),
            n_phi=2,
        )
        np.testing.assert_allclose(got, expected, rtol=1e-12)


# --------------------------------------------------------------------------------------------------
# SG evaluation and integral.


def test_sg_evaluate_matches_both_written_forms():
    theta = np.array([0.0, 1e-4, 0.3, 1.0, 2.0, np.pi])
    lam = np.array([[1e-6], [1.0], [30.0], [1e6]])
    omega = rotated(theta, 0.7)
    got = sg.sg_evaluate(omega, Z, lam)
    # exp(lam (cos - 1)) = exp(-2 lam sin^2(theta/2)), the latter exact for small angles.
    np.testing.assert_allclose(got, np.exp(-2.0 * lam * np.sin(0.5 * theta) ** 2), rtol=1e-12, atol=0.0)
    moderate = lam < 100.0
    np.testing.assert_allclose(
        got[moderate[:, 0]], np.exp(lam * (np.cos(theta) - 1.0))[moderate[:, 0]], rtol=1e-12, atol=1e-300
    )
    assert sg.sg_evaluate(Z, Z, 1e7) == 1.0
    assert sg.sg_evaluate(-Z, Z, 0.0) == 1.0


def test_sg_integral_vs_quadrature():
    lam = np.concatenate(([0.0], np.logspace(-6.0, 7.0, 27)))
    quad = quadrature.sphere_quadrature(
        lambda w: sg.sg_evaluate(w, Z, lam[:, None, None]), np.broadcast_to(Z, lam.shape + (3,)), n_phi=2
    )
    np.testing.assert_allclose(sg.sg_integral(lam), quad, rtol=RTOL)


def test_sg_integral_limits():
    assert sg.sg_integral(0.0) == 4.0 * np.pi
    lam = 1e-6
    # 2 pi (1 - e^-2lam) / lam = 4 pi (1 - lam + 2 lam^2 / 3 - ...)
    assert sg.sg_integral(lam) == pytest.approx(4.0 * np.pi * (1.0 - lam + 2.0 * lam**2 / 3.0), rel=1e-15)
    assert sg.sg_integral(1e-300) == pytest.approx(4.0 * np.pi, rel=1e-15)
    assert sg.sg_integral(1e6) == pytest.approx(2.0 * np.pi / 1e6, rel=1e-15)
    assert np.isfinite(sg.sg_integral(1e300)) and sg.sg_integral(1e300) > 0.0


# --------------------------------------------------------------------------------------------------
# SG product.


def _pair_grid():
    l1, l2, ang = np.meshgrid(SHARPNESS, SHARPNESS, ANGLES, indexing="ij")
    l1, l2, ang = l1.ravel(), l2.ravel(), ang.ravel()
    a1 = np.broadcast_to(Z, l1.shape + (3,))
    a2 = rotated(ang, 1.1)
    return a1, l1, a2, l2, ang


def test_sg_product_pointwise():
    a1, l1, a2, l2, _ = _pair_grid()
    axis, sharpness, scale = sg.sg_product(a1, l1, a2, l2)
    np.testing.assert_allclose(np.linalg.norm(axis, axis=-1), 1.0, rtol=1e-15)
    # Directions spread over the product lobe (offsets in units of its width) and far from it.
    width = 1.0 / np.sqrt(np.maximum(sharpness, 1e-12))
    t1 = unit(np.cross(axis, X + 0.3 * Y))
    t2 = np.cross(axis, t1)
    for offset in (0.0, 0.3, 1.0, 2.5):
        for beta in (0.0, 1.0, 2.5):
            angle = np.minimum(offset * width, np.pi)[:, None]
            omega = np.cos(angle) * axis + np.sin(angle) * (math.cos(beta) * t1 + math.sin(beta) * t2)
            product = sg.sg_evaluate(omega, a1, l1) * sg.sg_evaluate(omega, a2, l2)
            single = scale * sg.sg_evaluate(omega, axis, sharpness)
            np.testing.assert_allclose(single, product, rtol=RTOL, atol=1e-290)
    for omega in (X, -Z, unit([1.0, -2.0, 0.5])):
        product = sg.sg_evaluate(omega, a1, l1) * sg.sg_evaluate(omega, a2, l2)
        np.testing.assert_allclose(
            scale * sg.sg_evaluate(omega, axis, sharpness), product, rtol=RTOL, atol=1e-290
        )


def test_sg_product_parameters_independently():
    a1, l1, a2, l2, _ = _pair_grid()
    axis, sharpness, scale = sg.sg_product(a1, l1, a2, l2)
    xi_m = l1[:, None] * a1 + l2[:, None] * a2
    np.testing.assert_allclose(sharpness, np.linalg.norm(xi_m, axis=-1), rtol=1e-13)
    # exp(|xi_m| - lam1 - lam2) where the direct difference has no cancellation to speak of.
    direct = sharpness - l1 - l2
    ok = np.abs(direct) > 1e-3 * (l1 + l2)
    np.testing.assert_allclose(scale[ok], np.exp(direct[ok]), rtol=1e-9, atol=1e-300)
    assert np.all(scale <= 1.0) and np.all(scale >= 0.0)


def test_sg_product_stable_exponent_close_sharp_lobes():
    # lam1 = lam2 = 1e6 at 1e-6 rad: |xi_m| - lam1 - lam2 = -lam1 lam2 |d|^2 / (...) ~ -0.5 exactly,
    # where 2e6 - 2e6 cancellation would leave ~1e-10 absolute error at best.
    lam = 1e6
    theta = 1e-6
    _, _, scale = sg.sg_product(Z, lam, rotated(theta), lam)
    chord2 = 4.0 * math.sin(0.5 * theta) ** 2
    expected = math.exp(-lam * lam * chord2 / (2.0 * lam * math.cos(0.5 * theta) + 2.0 * lam))
    assert scale == pytest.approx(expected, rel=1e-13)


def test_sg_product_degenerate_opposite_axes():
    for lam in (0.0, 1e-6, 1.0, 1e6):
        axis, sharpness, scale = sg.sg_product(Z, lam, -Z, lam)
        np.testing.assert_array_equal(axis, Z)
        assert sharpness == 0.0
        assert scale == pytest.approx(math.exp(-2.0 * lam), rel=1e-15)
        integral = sg.sg_product_integral(Z, lam, -Z, lam)
        assert integral == pytest.approx(4.0 * np.pi * math.exp(-2.0 * lam), rel=1e-15)
    axis, sharpness, scale = sg.sg_product(Z, 0.0, X, 0.0)
    assert np.all(np.isfinite(axis)) and sharpness == 0.0 and scale == 1.0
    assert sg.sg_product_integral(Z, 0.0, X, 0.0) == 4.0 * np.pi


def test_sg_product_integral_vs_quadrature():
    a1, l1, a2, l2, _ = _pair_grid()
    # Pole at the product's axis, computed here independently of sg_product.
    xi_m = l1[:, None] * a1 + l2[:, None] * a2
    length = np.linalg.norm(xi_m, axis=-1, keepdims=True)
    pole = np.where(length > 0.0, xi_m / np.where(length > 0.0, length, 1.0), Z)

    def product(w):
        return sg.sg_evaluate(w, a1[:, None, None], l1[:, None, None]) * sg.sg_evaluate(
            w, a2[:, None, None], l2[:, None, None]
        )

    quad = quadrature.sphere_quadrature(product, pole, n_phi=8)
    exact = sg.sg_product_integral(a1, l1, a2, l2)
    big = exact > 1e-250
    assert big.sum() > 0.7 * big.size
    np.testing.assert_allclose(exact[big], quad[big], rtol=RTOL)
    assert np.all(quad[~big] < 1e-240)

    # Scaled by e^-d (d the stable exponent) nothing underflows: every grid point, to 1e-9.
    _, m, d = sg._product_parts(a1, l1, a2, l2)

    def scaled(w):
        log = -0.5 * l1[:, None, None] * np.sum((w - a1[:, None, None]) ** 2, -1) - 0.5 * l2[
            :, None, None
        ] * np.sum((w - a2[:, None, None]) ** 2, -1)
        return np.exp(log - d[:, None, None])

    quad = quadrature.sphere_quadrature(scaled, pole, n_phi=8)
    np.testing.assert_allclose(4.0 * np.pi * numerics.one_minus_exp_ratio(2.0 * m), quad, rtol=RTOL)


def test_sg_product_integral_pole_on_one_lobe():
    # Same identity with the pole on lobe 1 (not on the product axis): the azimuthal rule has to
    # resolve lobe 2 off the pole, so moderate sharpness and more azimuth points.
    lam = np.array([0.1, 1.0, 10.0, 60.0])
    l1, l2, ang = (v.ravel() for v in np.meshgrid(lam, lam, [0.2, 1.0, 2.0, np.pi], indexing="ij"))
    a2 = rotated(ang, 0.4)

    def product(w):
        return sg.sg_evaluate(w, Z, l1[:, None, None]) * sg.sg_evaluate(
            w, a2[:, None, None], l2[:, None, None]
        )

    quad = quadrature.sphere_quadrature(product, np.broadcast_to(Z, a2.shape), n_phi=256)
    np.testing.assert_allclose(sg.sg_product_integral(Z, l1, a2, l2), quad, rtol=RTOL)


# --------------------------------------------------------------------------------------------------
# Lobes.


def test_sg_lobe_normalized_integrates_to_one():
    lam = np.array([0.0, 1e-6, 1e-2, 1.0, 2.0, 100.0, 1e4, 1e6, 1e7])
    quad = quadrature.sphere_quadrature(
        lambda w: sg.sg_lobe_normalized(w, Z, lam[:, None, None]),
        np.broadcast_to(Z, lam.shape + (3,)),
        n_phi=2,
    )
    np.testing.assert_allclose(quad, 1.0, rtol=RTOL)
    assert sg.sg_lobe_normalized(Z, Z, 0.0) == pytest.approx(1.0 / (4.0 * np.pi), rel=1e-15)
    peak = sg.sg_lobe_normalized(Z, Z, np.array([1e6, 1e300]))
    np.testing.assert_allclose(peak, np.array([1e6, 1e300]) / (2.0 * np.pi), rtol=1e-15)


def test_diffuse_lobe_is_eq6_with_lambda_d_2():
    assert sg.DIFFUSE_SHARPNESS == 2.0
    omega = unit(np.random.default_rng(1).normal(size=(50, 3)))
    normal = unit([0.2, -0.3, 0.9])
    expected = np.exp(2.0 * (omega @ normal - 1.0)) * 2.0 / (2.0 * np.pi * (1.0 - math.exp(-4.0)))
    np.testing.assert_allclose(sg.diffuse_lobe(omega, normal), expected, rtol=1e-13)
    assert quadrature.sphere_quadrature(
        lambda w: sg.diffuse_lobe(w, normal), normal, n_phi=2
    ) == pytest.approx(1.0, rel=RTOL)


def test_diffuse_lobe_approximates_lambert():
    """Tolerances from the measured errors (docs/accuracy.md): LS-optimal lam_d 2.29 (normalized
    lobe) / 2.14 (free amplitude), relative L2 error 0.208 at lam_d = 2, leak 0.119."""
    lam_norm, lam_free = solvers.diffuse_fit()
    assert 2.2 < lam_norm < 2.4
    assert 2.05 < lam_free < 2.25
    # 2 is within ~15% of either optimum, and its L2 error is close to the optimum's.
    l2 = math.sqrt(solvers.diffuse_objective(2.0)) / (math.sqrt(2.0 * np.pi / 3.0) / np.pi)
    l2_best = math.sqrt(solvers.diffuse_objective(lam_norm)) / (math.sqrt(2.0 * np.pi / 3.0) / np.pi)
    assert 0.19 < l2 < 0.22
    assert l2_best < l2 < 1.15 * l2_best
    leak = quadrature.sphere_quadrature(lambda w: sg.diffuse_lobe(w, Z) * (w[..., 2] < 0.0), Z, n_phi=2)
    assert 0.11 < leak < 0.13
    # Same energy as <w, n>/pi (both 1).
    lambert = quadrature.sphere_quadrature(lambda w: np.maximum(w[..., 2], 0.0) / np.pi, Z, n_phi=2)
    assert lambert == pytest.approx(1.0, rel=1e-13)


def test_ndf_sharpness():
    np.testing.assert_allclose(sg.ndf_sharpness([1e-3, 0.5, 1.0]), [2e6, 8.0, 2.0], rtol=1e-15)


def test_specular_lobe_warp():
    normal = unit([0.1, 0.2, 1.0])
    theta = np.array([0.0, 0.3, 1.0, 1.5, 0.5 * np.pi])
    tangent = unit(np.cross(normal, X))
    incoming = np.cos(theta)[:, None] * normal + np.sin(theta)[:, None] * tangent
    axis, sharpness = sg.specular_lobe_warp(incoming, normal, 0.1)
    # Mirror direction: same angle to the normal, opposite tangent component.
    expected_axis = np.cos(theta)[:, None] * normal - np.sin(theta)[:, None] * tangent
    np.testing.assert_allclose(axis, expected_axis, atol=1e-15)
    cos = np.maximum(np.abs(np.cos(theta)), sg.COSINE_FLOOR)
    np.testing.assert_allclose(sharpness, 200.0 / (4.0 * cos), rtol=1e-12)
    assert sharpness[-1] == pytest.approx(200.0 / (4.0 * sg.COSINE_FLOOR))
    # Energy preserving: integrates to 1 for any incidence.
    quad = quadrature.sphere_quadrature(
        lambda w: sg.specular_lobe(w, incoming[:, None, None], normal, 0.1), axis, n_phi=4
    )
    np.testing.assert_allclose(quad, 1.0, rtol=RTOL)


def test_cosine_floor_keeps_float32_finite():
    # Largest sharpness the floor allows at the smallest roughness, and the products the shaders
    # form from it, stay below float32's maximum.
    lam_s = float(sg.ndf_sharpness(1e-3)) / (4.0 * sg.COSINE_FLOOR)
    eta_x = float(sg.ndf_sharpness(1e-3)) / (8.0 * sg.COSINE_FLOOR**2)
    f32 = np.finfo(np.float32).max
    assert lam_s * lam_s < f32 and eta_x * lam_s < f32
    assert np.isfinite(np.float32(lam_s) * np.float32(lam_s))


# --------------------------------------------------------------------------------------------------
# Extremes: no NaN or Inf anywhere.

EXTREME_SHARPNESS = np.array([0.0, 1e-6, 1.0, 1e6, 1e7])
EXTREME_COSINES = np.array([-1.0, -1e-7, 0.0, 1e-7, 0.5, 1.0])
EXTREME_ROUGHNESS = np.array([1e-3, 1e-2, 0.5, 1.0])


def _directions_with_cosines(cosines, normal=Z):
    sin = np.sqrt(np.maximum(1.0 - cosines**2, 0.0))
    return cosines[:, None] * normal + sin[:, None] * X


def test_extremes_finite_sg():
    axes = np.stack([Z, -Z, rotated(1e-7), X, unit([1.0, 1.0, 1.0])])
    a1 = axes[:, None, None, None, :]
    a2 = axes[None, :, None, None, :]
    l1 = EXTREME_SHARPNESS[None, None, :, None]
    l2 = EXTREME_SHARPNESS[None, None, None, :]
    for output in (*sg.sg_product(a1, l1, a2, l2), sg.sg_product_integral(a1, l1, a2, l2)):
        assert np.all(np.isfinite(output))
    omegas = np.concatenate((axes, _directions_with_cosines(EXTREME_COSINES)))
    w = omegas[:, None, None, :]
    ax = axes[None, :, None, :]
    lam = EXTREME_SHARPNESS[None, None, :]
    for output in (
        sg.sg_evaluate(w, ax, lam),
        sg.sg_lobe_normalized(w, ax, lam),
        sg.sg_integral(EXTREME_SHARPNESS),
    ):
        assert np.all(np.isfinite(output))
    assert np.all(np.isfinite(sg.diffuse_lobe(omegas, Z)))


def test_extremes_finite_specular_lobe():
    incoming = _directions_with_cosines(EXTREME_COSINES)[:, None, :]
    alpha = EXTREME_ROUGHNESS[None, :]
    axis, sharpness = sg.specular_lobe_warp(incoming, Z, alpha)
    assert np.all(np.isfinite(axis)) and np.all(np.isfinite(sharpness))
    assert np.all(np.isfinite(sharpness.astype(np.float32)))
    omegas = np.concatenate((_directions_with_cosines(EXTREME_COSINES), axis.reshape(-1, 3)))
    value = sg.specular_lobe(omegas[:, None, None, :], incoming[None], Z, alpha[None])
    assert np.all(np.isfinite(value))
