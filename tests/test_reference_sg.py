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


# --------------------------------------------------------------------------------------------------
# SG times the clamped cosine (Tokuyoshi et al. 2024) against an independent quadrature.


def _ring_clamped_cosine(a, b):
    """∫_0^2π max(a + b cos φ, 0) dφ (b ≥ 0), exact: 2πa above, 0 below, 2(a φ0 + b sin φ0) with
    cos φ0 = −a/b between."""
    a, b = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
    phi0 = np.arccos(np.clip(-a / np.where(b > 0.0, b, 1.0), -1.0, 1.0))
    crossing = (a < b) & (a > -b)
    return np.where(crossing, 2.0 * (a * phi0 + b * np.sin(phi0)), np.where(a >= b, 2.0 * np.pi * a, 0.0))


def clamped_cosine_quadrature(cosine, sharpness, nodes=48):
    """1/π ∫ G(ω; ξ, λ) max(ω·n, 0) dω with ξ·n = cosine, in coordinates about ξ: u = 1 − ω·ξ, so
    G = e^(−λu) and dω = du dφ; the φ integral of the clamped cosine in closed form
    (``_ring_clamped_cosine``), the u integral by composite Gauss-Legendre, split where the ring
    starts and stops crossing the horizon (u = 1 − cos(π/2 ∓ θ)) and graded geometrically towards
    every end (the lobe's peak at u = 0, the square-root kinks of the ring's length and crossing).
    Independent of reference/sg.py."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    theta = math.acos(min(max(cosine, -1.0), 1.0))
    sin_t = math.sin(theta)
    kinks = [1.0 - math.cos(abs(0.5 * math.pi - theta)), 1.0 - math.cos(0.5 * math.pi + theta)]
    edges = sorted({0.0, 2.0, *[k for k in kinks if 0.0 < k < 2.0]})
    grading = np.geomspace(1e-12, 0.5, 48)
    cuts = sorted(set(edges).union(*(np.concatenate((lo + (hi - lo) * grading, hi - (hi - lo) * grading))
                                      for lo, hi in zip(edges[:-1], edges[1:]))))
    total = 0.0
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        u = 0.5 * (hi - lo) * x + 0.5 * (hi + lo)
        ring = _ring_clamped_cosine((1.0 - u) * cosine, np.sqrt(np.maximum(u * (2.0 - u), 0.0)) * sin_t)
        total += 0.5 * (hi - lo) * np.sum(w * np.exp(-sharpness * u) * ring)
    return total / math.pi


CLAMPED_SHARPNESS = np.concatenate(([0.0], np.logspace(-6.0, 6.0, 25), [0.5, 0.5 + 1e-9, 1.0 - 1e-9]))
CLAMPED_COSINES = np.concatenate((np.linspace(-1.0, 1.0, 41), [1e-7, -1e-7, 1e-3, -1e-3, 0.999, -0.999]))
#: Measured worst absolute error of the closed form, in units of its peak S(1, λ): 9.6e-4.
CLAMPED_COSINE_BOUND = 1.5e-3


def test_clamped_cosine_quadrature_on_known_integrals():
    # λ = 0: ∫ max(ω·n, 0) dω = π for any axis; λ → ∞ at ξ = n: 2π/λ · 1/π.
    for cosine in (1.0, 0.3, -0.7):
        assert clamped_cosine_quadrature(cosine, 0.0) == pytest.approx(1.0, rel=1e-12)
    assert clamped_cosine_quadrature(1.0, 1e6) == pytest.approx(2e-6 * (1.0 - 1e-6), rel=1e-9)
    # Against a brute sphere quadrature at a mid sharpness and a grazing axis.
    axis = rotated(1.4)
    direct = quadrature.sphere_quadrature(lambda w: sg.sg_evaluate(w, axis, 7.0) * np.maximum(w[..., 2], 0.0),
                                          axis, n_phi=256, order=32, ratio=2.0) / math.pi
    assert clamped_cosine_quadrature(math.cos(1.4), 7.0) == pytest.approx(direct, rel=1e-6)


def test_clamped_cosine_hemisphere_integrals_are_exact():
    """Su, Sl (both closed forms and their series, on each side of the switch) against quadrature."""
    for lam in CLAMPED_SHARPNESS:
        assert 2.0 * sg.sg_upper_clamped_cosine(lam) == pytest.approx(clamped_cosine_quadrature(1.0, lam), rel=1e-10)
        lower = clamped_cosine_quadrature(-1.0, lam)
        assert 2.0 * sg.sg_lower_clamped_cosine(lam) == pytest.approx(lower, rel=1e-9, abs=1e-300)
        # The closed form is exact at μ = ±1 (s = 1 and 0 there).
        assert sg.sg_clamped_cosine_integral(1.0, lam) == pytest.approx(2.0 * sg.sg_upper_clamped_cosine(lam), rel=1e-12)
        assert sg.sg_clamped_cosine_integral(-1.0, lam) == pytest.approx(2.0 * sg.sg_lower_clamped_cosine(lam),
                                                                         rel=1e-12, abs=1e-300)


def test_clamped_cosine_integral_vs_quadrature():
    """Every sharpness 1e-6 … 1e6 and every angle, grazing and below the horizon included: within
    CLAMPED_COSINE_BOUND of the peak; relative 1e-4 for sharp lobes (λ ≥ 1e3) where the light is
    above 1e-3 of the peak; against 000 app. C's cosine pulled out it is exact where that is 64 % off."""
    worst = 0.0
    for lam in CLAMPED_SHARPNESS:
        exact = np.array([clamped_cosine_quadrature(mu, lam) for mu in CLAMPED_COSINES])
        approx = sg.sg_clamped_cosine_integral(CLAMPED_COSINES, lam)
        peak = exact[CLAMPED_COSINES == 1.0][0]
        error = np.abs(approx - exact) / peak
        worst = max(worst, float(error.max()))
        if lam >= 1e3:
            bright = exact > 1e-3 * peak
            np.testing.assert_allclose(approx[bright], exact[bright], rtol=1e-4)
    print(f"\nworst |S − quadrature| / S(1, λ): {worst:.2e}")
    assert worst < CLAMPED_COSINE_BOUND
    # 000 app. C at λ = 2, straight above: A(2)/π = 0.98 against 0.57.
    cosine_pulled_out = sg.sg_integral(2.0) / math.pi
    assert cosine_pulled_out / clamped_cosine_quadrature(1.0, 2.0) > 1.7
    assert sg.sg_clamped_cosine_integral(1.0, 2.0) == pytest.approx(clamped_cosine_quadrature(1.0, 2.0), rel=1e-12)


def test_clamped_cosine_integral_limits_and_shape():
    mu = np.linspace(-1.0, 1.0, 2001)
    # λ → 0: the whole sphere's clamped cosine, π/π = 1, for any axis.
    np.testing.assert_allclose(sg.sg_clamped_cosine_integral(mu, 1e-9), 1.0, rtol=1e-8)
    np.testing.assert_allclose(sg.sg_clamped_cosine_integral(mu, 0.0), 1.0, rtol=1e-15)
    # λ → ∞: A(λ)/π max(μ, 0) away from the horizon (the cosine pulled out becomes exact).
    lam = 1e8
    away = np.abs(mu) > 1e-2
    np.testing.assert_allclose(sg.sg_clamped_cosine_integral(mu, lam)[away],
                               (sg.sg_integral(lam) / math.pi * np.maximum(mu, 0.0))[away], rtol=1e-6, atol=1e-300)
    # Non-negative and non-decreasing in μ, bounded by its value at μ = 1, at every sharpness.
    for lam in (1e-6, 0.1, 0.5, 2.0, 10.0, 1e3, 1e6, 1e20):
        s = sg.sg_clamped_cosine_integral(mu, lam)
        assert np.all(np.isfinite(s)) and np.all(s >= 0.0)
        assert np.all(np.diff(s) >= -1e-15 * s.max())
        assert s.max() == pytest.approx(2.0 * sg.sg_upper_clamped_cosine(lam), rel=1e-12)
    # The smoothed clamped cosine: s(±1) = 1, 0, s = (μ + 1)/2 at t = 0, in [0, 1] for huge t.
    assert sg.sg_clamped_cosine_lerp(1.0, 3.0) == pytest.approx(1.0, rel=1e-15)
    assert sg.sg_clamped_cosine_lerp(-1.0, 3.0) == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(sg.sg_clamped_cosine_lerp(mu, 0.0), 0.5 * (mu + 1.0), rtol=1e-15)
    big = sg.sg_clamped_cosine_lerp(mu, 1e10)
    assert np.all((big >= 0.0) & (big <= 1.0))
    # Cosines outside [−1, 1] (rounding) are clamped, not extrapolated.
    assert sg.sg_clamped_cosine_integral(1.0 + 1e-7, 2.0) == sg.sg_clamped_cosine_integral(1.0, 2.0)
    # The steepness fit avoids λ³ (finite for λ up to 1e300) and is continuous at its switch.
    assert np.isfinite(sg.sg_clamped_cosine_steepness(1e300))
    assert sg.sg_clamped_cosine_steepness(1.0 - 1e-12) == pytest.approx(sg.sg_clamped_cosine_steepness(1.0), rel=1e-9)
