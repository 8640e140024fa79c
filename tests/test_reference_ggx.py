# SPDX-License-Identifier: GPL-3.0-or-later
"""vsgl_addon.reference.ggx (formulas.md section 3): normalization by quadrature, independent
textbook forms, reciprocity, white furnace, and finiteness at the extremes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vsgl_addon.reference import ggx, quadrature, sg, solvers

X = np.array([1.0, 0.0, 0.0])
Z = np.array([0.0, 0.0, 1.0])
ROUGHNESS = np.logspace(-3.0, 0.0, 13)


def direction(theta, beta=0.0):
    return solvers.direction(theta, beta)


def test_ndf_normalized():
    """Integral of D(h.n)(h.n) over the hemisphere = 1 (004 Eq. 6), alpha from 1e-3 to 1."""
    quad = quadrature.sphere_quadrature(
        lambda w: ggx.ggx_ndf(w[..., 2], ROUGHNESS[:, None, None]) * w[..., 2],
        np.broadcast_to(Z, ROUGHNESS.shape + (3,)),
        n_phi=2,
    )
    np.testing.assert_allclose(quad, 1.0, rtol=1e-9)


def test_ndf_textbook_forms():
    c = np.linspace(0.05, 0.95, 19)[:, None]
    alpha = np.array([0.05, 0.3, 0.8, 1.0])
    a2 = alpha**2
    textbook = a2 / (np.pi * (1.0 - (1.0 - a2) * c**2) ** 2)  # 001 Eq. 16 with m = alpha
    np.testing.assert_allclose(ggx.ggx_ndf(c, alpha), textbook, rtol=1e-12)
    theta = np.arccos(c)
    # 004 Eq. 6 with sin^2: alpha^2 / (pi (alpha^2 cos^2 + sin^2)^2).
    np.testing.assert_allclose(
        ggx.ggx_ndf(c, alpha), a2 / (np.pi * (a2 * c**2 + np.sin(theta) ** 2) ** 2), rtol=1e-12
    )
    np.testing.assert_allclose(ggx.ggx_ndf(1.0, ROUGHNESS), 1.0 / (np.pi * ROUGHNESS**2), rtol=1e-15)
    np.testing.assert_array_equal(ggx.ggx_ndf(np.array([-1.0, -1e-7, 0.0]), 0.3), 0.0)
    # Rounding above 1 must not blow up.
    assert ggx.ggx_ndf(1.0 + 1e-15, 1e-3) == pytest.approx(1.0 / (np.pi * 1e-6), rel=1e-6)


def test_g1_distant():
    c = np.linspace(-1.0, 1.0, 2001)[:, None]
    g1 = ggx.g1_distant(c, ROUGHNESS)
    assert np.all(g1 <= 1.0 + 1e-15) and np.all(g1 >= 0.0)
    np.testing.assert_allclose(ggx.g1_distant(np.array([1.0, -1.0]), ROUGHNESS[:, None]), 1.0, rtol=1e-15)
    assert np.all(ggx.g1_distant(0.0, ROUGHNESS) == 0.0)
    # Monotone in |c|.
    assert np.all(np.diff(g1[1000:], axis=0) >= -1e-15)
    # Independent form: Smith G1 = 1 / (1 + Lambda), Lambda = (-1 + sqrt(1 + alpha^2 tan^2)) / 2.
    theta = np.linspace(0.01, 1.55, 50)[:, None]
    lam = 0.5 * (-1.0 + np.sqrt(1.0 + ROUGHNESS**2 * np.tan(theta) ** 2))
    np.testing.assert_allclose(ggx.g1_distant(np.cos(theta), ROUGHNESS), 1.0 / (1.0 + lam), rtol=1e-12)


def test_fresnel_schlick():
    assert ggx.fresnel_schlick(1.0, 0.04) == pytest.approx(0.04)
    assert ggx.fresnel_schlick(0.0, 0.04) == pytest.approx(1.0)
    assert ggx.fresnel_schlick(0.5, 0.04) == pytest.approx(0.04 + 0.96 * 0.5**5)
    assert ggx.fresnel_schlick(-0.3, 0.04) == pytest.approx(1.0)  # clamped
    np.testing.assert_allclose(ggx.fresnel_schlick(np.linspace(0, 1, 11), 1.0), 1.0)


def _random_pairs(n, seed=3):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(2, n, 3))
    v[..., 2] = np.abs(v[..., 2]) + 0.05  # upper hemisphere, not grazing
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    return v[0], v[1]


def test_microfacet_brdf_matches_eq7():
    wi, wo = _random_pairs(200)
    alpha = np.array([[0.02], [0.3], [1.0]])
    f0 = 0.04
    h = (wi + wo) / np.linalg.norm(wi + wo, axis=-1, keepdims=True)
    ci, co = wi[:, 2], wo[:, 2]
    naive = (
        ggx.fresnel_schlick(np.sum(wi * h, -1), f0)
        * ggx.g1_distant(ci, alpha)
        * ggx.g1_distant(co, alpha)
        * ggx.ggx_ndf(h[:, 2], alpha)
        / (4.0 * ci * co)
    )
    np.testing.assert_allclose(ggx.microfacet_brdf(wi, wo, Z, alpha, f0), naive, rtol=1e-12)


def test_microfacet_brdf_reciprocal_and_zero_below():
    wi, wo = _random_pairs(300, seed=5)
    for alpha in (1e-3, 0.1, 0.7):
        np.testing.assert_allclose(
            ggx.microfacet_brdf(wi, wo, Z, alpha, 0.3), ggx.microfacet_brdf(wo, wi, Z, alpha, 0.3), rtol=1e-12
        )
    below = wo * np.array([1.0, 1.0, -1.0])
    assert np.all(ggx.microfacet_brdf(wi, below, Z, 0.3, 1.0) == 0.0)
    assert np.all(ggx.microfacet_brdf(below, wi, Z, 0.3, 1.0) == 0.0)
    assert ggx.microfacet_brdf(X, -X, Z, 0.3, 1.0) == 0.0


def test_microfacet_brdf_grazing_finite_and_continuous():
    # f -> F D / (alpha (c + s)) as one cosine -> 0: finite and continuous, no 0/0.
    wo = direction(0.4, 2.0)
    for alpha in (1e-3, 0.3, 1.0):
        values = [
            float(ggx.microfacet_brdf(direction(0.5 * np.pi - e), wo, Z, alpha, 1.0))
            for e in (1e-4, 1e-7, 1e-10)
        ]
        assert all(np.isfinite(values))
        if alpha > 0.01:
            assert values[2] == pytest.approx(values[1], rel=1e-5)


def _albedo(theta, alpha, n_phi=128):
    """Directional albedo int f(wi, w) <w, n> dw with F = 1."""
    theta, alpha = np.broadcast_arrays(np.asarray(theta, float), np.asarray(alpha, float))
    wi = direction(theta)

    def f(w):
        return ggx.microfacet_brdf(wi[..., None, None, :], w, Z, alpha[..., None, None], 1.0) * np.maximum(
            w[..., 2], 0.0
        )

    return solvers.specular_quadrature(f, wi, alpha, n_phi=n_phi)


def test_white_furnace():
    theta, alpha = np.meshgrid(np.radians([0.0, 30.0, 60.0, 80.0, 89.0]), ROUGHNESS[::3], indexing="ij")
    albedo = _albedo(theta, alpha, n_phi=64)
    assert np.all(albedo <= 1.0 + 1e-6)
    # alpha = 1 at normal incidence: D = 1/pi, f = 1 / (pi (1 + c_i)(1 + c_o)), albedo 1 - ln 2.
    assert albedo[0, -1] == pytest.approx(1.0 - math.log(2.0), rel=1e-9)
    assert np.all(albedo >= albedo[0, -1] - 1e-9)
    # Glossy and not grazing: the separable Smith model loses almost nothing.
    glossy = (alpha <= 0.01) & (theta <= np.radians(60.0))
    assert np.all(albedo[glossy] > 0.999)
    # The rougher, the more energy lost (no multiple scattering): monotone at normal incidence.
    assert np.all(np.diff(albedo[0]) < 0.0)


def test_white_furnace_quadrature_converged():
    theta, alpha = np.meshgrid(np.radians([0.0, 45.0, 75.0]), [1e-3, 0.1, 0.5])
    np.testing.assert_allclose(_albedo(theta, alpha), _albedo(theta, alpha, n_phi=256), rtol=1e-5)
    # Grazing, where the horizon cuts the lobe: ~1e-3 (what docs/accuracy.md claims).
    theta, alpha = np.radians([85.0, 85.0]), np.array([0.01, 0.1])
    np.testing.assert_allclose(_albedo(theta, alpha), _albedo(theta, alpha, n_phi=1024), rtol=1e-3)


EXTREME_COSINES = np.array([-1.0, -1e-7, 0.0, 1e-7, 0.5, 1.0])
EXTREME_ROUGHNESS = np.array([1e-3, 1e-2, 0.5, 1.0])


def test_extremes_finite_ggx():
    c = EXTREME_COSINES[:, None]
    a = EXTREME_ROUGHNESS[None, :]
    for output in (ggx.ggx_ndf(c, a), ggx.g1_distant(c, a), ggx.fresnel_schlick(c, 0.04)):
        assert np.all(np.isfinite(output))
    sin = np.sqrt(np.maximum(1.0 - EXTREME_COSINES**2, 0.0))
    dirs = np.concatenate(
        (
            EXTREME_COSINES[:, None] * Z + sin[:, None] * X,
            EXTREME_COSINES[:, None] * Z - sin[:, None] * X,
            EXTREME_COSINES[:, None] * Z + sin[:, None] * np.array([0.0, 1.0, 0.0]),
        )
    )
    value = ggx.microfacet_brdf(
        dirs[:, None, None, :], dirs[None, :, None, :], Z, EXTREME_ROUGHNESS[None, None, :], 0.04
    )
    assert np.all(np.isfinite(value)) and np.all(value >= 0.0)
    # The NDF's SG sharpness and the warped lobe at the extremes (sg.py) in float32 too.
    assert np.all(np.isfinite(np.float32(sg.ndf_sharpness(EXTREME_ROUGHNESS))))
    assert math.isfinite(float(ggx.ggx_ndf(np.float32(1.0), np.float32(1e-3))))
