# SPDX-License-Identifier: GPL-3.0-or-later
"""Accuracy of the SG / ASG / GGX approximations, measured by quadrature (docs/accuracy.md).

``measure()`` returns one ``Row`` per figure; ``to_markdown(rows)`` renders the committed table;
``python -m vsgl_addon.reference.accuracy --write docs/accuracy.md`` regenerates it, and
tests/test_accuracy_table.py checks that the committed figures are current.

Rows with ``exact=True`` are closed forms checked against the quadrature: their value is rounding
and quadrature noise, bounded by ``EXACT_BOUND`` rather than reproduced digit for digit.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import NamedTuple

import numpy as np

from .asg import asg_evaluate, asg_integral, asg_specular_lobe, sg_asg_convolution
from .ggx import ggx_ndf, microfacet_brdf
from .quadrature import sphere_quadrature
from .numerics import dot, f64, norm
from .sg import (
    DIFFUSE_SHARPNESS,
    ndf_sharpness,
    sg_evaluate,
    sg_integral,
    sg_lobe_normalized,
    sg_product,
    sg_product_integral,
    specular_lobe,
    specular_lobe_warp,
)

#: Exact identities must match the quadrature to this relative error (the tests use it too).
EXACT_BOUND = 1e-9

_X = np.array([1.0, 0.0, 0.0])
_Y = np.array([0.0, 1.0, 0.0])
_Z = np.array([0.0, 0.0, 1.0])

#: Grids of the measurements (the tests reuse them).
ROUGHNESS = np.array([1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0])
WARP_ROUGHNESS = np.array([1e-3, 1e-2, 0.1, 0.3, 0.5])
WARP_INCIDENCE_DEG = np.array([0.0, 30.0, 60.0, 75.0, 85.0])
CONV_SHARPNESS = np.array([1.0, 10.0, 100.0, 1e3, 1e4, 1e5])
CONV_BANDWIDTH = np.array([1.0, 10.0, 50.0, 100.0, 1e3, 1e4])


class Row(NamedTuple):
    name: str
    parameters: str
    metric: str
    value: float
    exact: bool = False


# --------------------------------------------------------------------------------------------------
# Helpers shared with the tests.


def golden_section_minimize(fn, lo, hi, iterations=60):
    """Minimizer of a unimodal scalar function on [lo, hi] (golden-section search)."""
    inv_phi = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = lo, hi
    c, d = b - inv_phi * (b - a), a + inv_phi * (b - a)
    fc, fd = fn(c), fn(d)
    for _ in range(iterations):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - inv_phi * (b - a)
            fc = fn(c)
        else:
            a, c, fc = c, d, fd
            d = a + inv_phi * (b - a)
            fd = fn(d)
    return 0.5 * (a + b)


def direction(theta, beta, x_axis=_X, y_axis=_Y, z_axis=_Z):
    """z rotated by theta towards cos(beta) x + sin(beta) y (broadcasts)."""
    theta = f64(theta)[..., None]
    beta = f64(beta)[..., None]
    return np.cos(theta) * z_axis + np.sin(theta) * (np.cos(beta) * x_axis + np.sin(beta) * y_axis)


def asg_integral_1d(eta_x, eta_y):
    """Exact ASG integral as a 1D integral: (1/2) int_0^2pi (1 - e^-k) / k dphi.

    k = eta_x cos^2 phi + eta_y sin^2 phi. Project the upper hemisphere of z onto the tangent disk,
    (a, b) = (w.x, w.y): dw = da db / (w.z), so <w, z> dw = da db, and the radial integral of
    exp(-k r^2) r dr over [0, 1] is (1 - e^-k) / (2k). Composite Gauss-Legendre on [0, pi/2] with
    breakpoints geometric towards both ends resolves anisotropy up to ~1e28. Returns
    ``(integral, integral of e^-k / (2k))``: the second is exactly Eq. 34 minus the integral, so the
    relative error of Eq. 34 is their ratio with no cancellation.
    """
    eta_x = f64(eta_x)[..., None]
    eta_y = f64(eta_y)[..., None]
    t, w = np.polynomial.legendre.leggauss(20)
    half = 0.25 * np.pi * np.concatenate(([0.0], np.logspace(-14.0, 0.0, 57)))
    edges = np.concatenate((half, 0.5 * np.pi - half[::-1][1:]))
    a, b = edges[:-1, None], edges[1:, None]
    phi = (0.5 * (b - a) * t + 0.5 * (b + a)).ravel()
    weights = (0.5 * (b - a) * w).ravel()
    k = eta_x * np.cos(phi) ** 2 + eta_y * np.sin(phi) ** 2
    safe = np.where(k > 0.0, k, 1.0)
    kept = np.where(k > 0.0, -np.expm1(-safe) / safe, 1.0)
    dropped = np.where(k > 0.0, np.exp(-safe) / safe, np.inf)
    # Four quarters of the circle, times the 1/2 of the radial integral.
    return 2.0 * np.sum(weights * kept, axis=-1), 2.0 * np.sum(weights * dropped, axis=-1)


def _log_sg_asg(omega, lam, p, eta_x, eta_y):
    cz = np.maximum(omega[..., 2], 1e-300)
    return lam * dot(omega, p) + np.log(cz) - eta_x * omega[..., 0] ** 2 - eta_y * omega[..., 1] ** 2


def sg_asg_peak(p, lam, eta_x, eta_y, iterations=40):
    """Direction maximizing G(w; p, lam) Ga(w; x, y, z, eta_x, eta_y), frame x, y, z = the axes.

    Riemannian Newton on the sphere with backtracking, started at the tangent-plane Gaussian
    estimate (nu p_x / (nu + eta_x), nu p_y / (nu + eta_y)). Only used to place the quadrature's
    pole at the peak of the integrand; any point near the peak would do.
    """
    p = f64(p)
    lam, eta_x, eta_y = np.broadcast_arrays(f64(lam), f64(eta_x), f64(eta_y))
    nu = 0.5 * lam
    a = nu * p[..., 0] / (nu + eta_x)
    b = nu * p[..., 1] / (nu + eta_y)
    omega = np.stack((a, b, np.sqrt(np.maximum(1.0 - a * a - b * b, 1e-4))), axis=-1)
    omega = omega / norm(omega)[..., None]
    g = _log_sg_asg(omega, lam, p, eta_x, eta_y)
    for _ in range(iterations):
        cx, cy, cz = omega[..., 0], omega[..., 1], omega[..., 2]
        grad = lam[..., None] * p + np.stack((-2.0 * eta_x * cx, -2.0 * eta_y * cy, 1.0 / cz), axis=-1)
        # Tangent basis at omega: x (or y near the x axis) projected.
        t1 = _X - cx[..., None] * omega
        t1 = np.where((norm(t1) < 0.5)[..., None], _Y - cy[..., None] * omega, t1)
        t1 = t1 / norm(t1)[..., None]
        t2 = np.cross(omega, t1)
        basis = (t1, t2)
        radial = dot(omega, grad)
        g_t = np.stack([dot(t, grad) for t in basis], axis=-1)
        hess = np.empty(g_t.shape + (2,))
        for i in range(2):
            for j in range(2):
                ti, tj = basis[i], basis[j]
                hess[..., i, j] = (
                    -ti[..., 2] * tj[..., 2] / cz**2
                    - 2.0 * eta_x * ti[..., 0] * tj[..., 0]
                    - 2.0 * eta_y * ti[..., 1] * tj[..., 1]
                    - (radial if i == j else 0.0)
                )
        det = hess[..., 0, 0] * hess[..., 1, 1] - hess[..., 0, 1] * hess[..., 1, 0]
        concave = (hess[..., 0, 0] < 0.0) & (det > 0.0)
        safe_det = np.where(concave, det, 1.0)
        newton = -np.stack(
            (
                (hess[..., 1, 1] * g_t[..., 0] - hess[..., 0, 1] * g_t[..., 1]) / safe_det,
                (hess[..., 0, 0] * g_t[..., 1] - hess[..., 1, 0] * g_t[..., 0]) / safe_det,
            ),
            axis=-1,
        )
        scale = np.maximum(np.abs(radial) + 2.0 * (eta_x + eta_y) + lam, 1.0)
        step = np.where(concave[..., None], newton, g_t / scale[..., None])
        length = np.ones(lam.shape)
        for _ in range(40):
            trial = (
                omega + (length[..., None] * step[..., :1]) * t1 + (length[..., None] * step[..., 1:]) * t2
            )
            trial = trial / norm(trial)[..., None]
            g_trial = _log_sg_asg(trial, lam, p, eta_x, eta_y)
            better = g_trial >= g
            if better.all():
                break
            length = np.where(better, length, 0.5 * length)
        omega = np.where(better[..., None], trial, omega)
        g = np.where(better, g_trial, g)
    return omega


def sg_asg_convolution_quadrature(p, lam, eta_x, eta_y, n_phi=64, order=16):
    """Integral of G(w; p, lam) Ga(w; x, y, z, eta_x, eta_y) by sphere quadrature, (x, y, z) = the
    coordinate axes; batch over leading dimensions of p (a flat batch).

    The pole is the integrand's peak, except for lobes wide enough to reach the ASG's horizon
    (min(eta) + lam/2 < 40, where e^-40 is below the target precision no longer holds): there the
    pole is z, so the <w, z> kink lies on the quadrature's u = 1 breakpoint.
    """
    p = f64(p)
    lam, eta_x, eta_y = (np.broadcast_to(f64(v), p.shape[:-1]) for v in (lam, eta_x, eta_y))
    nu = 0.5 * lam
    pole = sg_asg_peak(p, lam, eta_x, eta_y)
    pole = np.where((np.minimum(eta_x, eta_y) + nu < 40.0)[..., None], _Z, pole)

    def integrand(omega):
        return sg_evaluate(omega, p[..., None, None, :], lam[..., None, None]) * asg_evaluate(
            omega, _X, _Y, _Z, eta_x[..., None, None], eta_y[..., None, None]
        )

    return sphere_quadrature(
        integrand, pole, tangent=_X, bandwidths=(eta_x + nu, eta_y + nu), n_phi=n_phi, order=order
    )


def conv_grid(sharpness=CONV_SHARPNESS, bandwidth=CONV_BANDWIDTH, offsets=(0.0, 1.0, 2.0)):
    """(lam, eta_x, eta_y, p, t) of the SG x ASG grid: eta_x >= eta_y (the other half is the same
    by symmetry), p = z rotated towards azimuth beta in {0, 45, 90} deg by t / sqrt(eta'(beta)),
    where eta' are the reduced bandwidths of the nu = lam/2 form, so that the approximation predicts
    exp(-t^2) of its peak; the angle is capped at 1.2 rad."""
    rows = set()
    betas = (0.0, 0.25 * np.pi, 0.5 * np.pi)
    for lam in sharpness:
        nu = 0.5 * lam
        for i, ex in enumerate(bandwidth):
            for ey in bandwidth[: i + 1]:
                rx, ry = ex * nu / (ex + nu), ey * nu / (ey + nu)
                for t in offsets:
                    for beta in betas if t > 0 else (0.0,):
                        reduced = rx * math.cos(beta) ** 2 + ry * math.sin(beta) ** 2
                        theta = min(t / math.sqrt(reduced), 1.2)
                        rows.add((float(lam), float(ex), float(ey), theta, beta, float(t)))
    lam, ex, ey, theta, beta, t = (np.array(v) for v in zip(*sorted(rows)))
    return lam, ex, ey, direction(theta, beta), t


# --------------------------------------------------------------------------------------------------
# Measurements.


def _identity_rows():
    rows = []
    lam = np.logspace(-6.0, 7.0, 14)
    quad = sphere_quadrature(
        lambda w: sg_evaluate(w, _Z, lam[:, None, None]), np.broadcast_to(_Z, (14, 3)), n_phi=1
    )
    rows.append(
        Row(
            "SG integral A(λ) (000 app. A)",
            "λ ∈ [1e-6, 1e7]",
            "max relative error vs quadrature",
            float(np.max(np.abs(sg_integral(lam) / quad - 1.0))),
            exact=True,
        )
    )
    l1, l2, ang = np.meshgrid(
        np.logspace(-6.0, 6.0, 7), np.logspace(-6.0, 6.0, 7), [0.0, 1e-3, 0.5, 2.0, np.pi]
    )
    l1, l2, ang = l1.ravel(), l2.ravel(), ang.ravel()
    a1 = np.broadcast_to(_Z, l1.shape + (3,))
    a2 = direction(ang, 0.0)
    axis, _, _ = sg_product(a1, l1, a2, l2)

    def product(w):
        return sg_evaluate(w, a1[:, None, None], l1[:, None, None]) * sg_evaluate(
            w, a2[:, None, None], l2[:, None, None]
        )

    quad = sphere_quadrature(product, axis, n_phi=8)
    exact = sg_product_integral(a1, l1, a2, l2)
    ok = exact > 1e-250  # both sides underflow alike beyond (checked separately in the tests)
    rows.append(
        Row(
            "SG product integral (000 app. A, 003)",
            "λ1, λ2 ∈ [1e-6, 1e6], angle ∈ [0, π]",
            "max relative error vs quadrature",
            float(np.max(np.abs(exact[ok] / quad[ok] - 1.0))),
            exact=True,
        )
    )
    alpha = ROUGHNESS
    normalization = sphere_quadrature(
        lambda w: ggx_ndf(w[..., 2], alpha[:, None, None]) * w[..., 2],
        np.broadcast_to(_Z, alpha.shape + (3,)),
        n_phi=1,
    )
    rows.append(
        Row(
            "GGX NDF normalization ∫D(h·n)(h·n)dh = 1 (004 Eq. 6)",
            "α ∈ [1e-3, 1]",
            "max absolute error vs quadrature",
            float(np.max(np.abs(normalization - 1.0))),
            exact=True,
        )
    )
    ex, ey = np.meshgrid([1e-6, 1e-2, 1.0, 50.0, 1e3, 1e7], [1e-6, 1e-2, 1.0, 50.0, 1e3, 1e7])
    ex, ey = ex.ravel(), ey.ravel()
    quad = sphere_quadrature(
        lambda w: asg_evaluate(w, _X, _Y, _Z, ex[:, None, None], ey[:, None, None]),
        np.broadcast_to(_Z, ex.shape + (3,)),
        tangent=_X,
        bandwidths=(ex, ey),
        n_phi=128,
    )
    rows.append(
        Row(
            "Exact ASG integral as a 1D integral (reference for 001 Eq. 34)",
            "ηx, ηy ∈ [1e-6, 1e7]",
            "max relative error vs sphere quadrature",
            float(np.max(np.abs(asg_integral_1d(ex, ey)[0] / quad - 1.0))),
            exact=True,
        )
    )
    return rows


def _diffuse_objective(lam):
    def f(w):
        return (sg_lobe_normalized(w, _Z, lam) - np.maximum(w[..., 2], 0.0) / np.pi) ** 2

    return float(sphere_quadrature(f, _Z, n_phi=1))


def _diffuse_free_amplitude_objective(lam):
    """Least squares of a G(w; n, lam) vs <w, n> with the best amplitude a for this lam."""
    gc = sphere_quadrature(lambda w: sg_evaluate(w, _Z, lam) * np.maximum(w[..., 2], 0.0), _Z, n_phi=1)
    gg = sphere_quadrature(lambda w: sg_evaluate(w, _Z, 2.0 * lam), _Z, n_phi=1)
    cc = 2.0 * np.pi / 3.0
    return float(cc - gc * gc / gg)


def diffuse_fit():
    """(least-squares lam_d of the normalized lobe, least-squares lam_d with a free amplitude)."""
    return (
        golden_section_minimize(_diffuse_objective, 0.5, 6.0),
        golden_section_minimize(_diffuse_free_amplitude_objective, 0.5, 6.0),
    )


def _diffuse_rows():
    lam_norm, lam_free = diffuse_fit()
    lam = DIFFUSE_SHARPNESS
    cosine_l2 = math.sqrt(2.0 * np.pi / 3.0) / np.pi  # ||<w, n>/pi||_2

    def errors(lam):
        l2 = math.sqrt(_diffuse_objective(lam)) / cosine_l2
        l1 = sphere_quadrature(
            lambda w: np.abs(sg_lobe_normalized(w, _Z, lam) - np.maximum(w[..., 2], 0.0) / np.pi), _Z, n_phi=1
        )
        return l2, float(l1)

    l2, l1 = errors(lam)
    l2_opt, _ = errors(lam_norm)
    leak = sphere_quadrature(lambda w: sg_lobe_normalized(w, _Z, lam) * (w[..., 2] < 0.0), _Z, n_phi=1)
    name = "Diffuse SG lobe G(ω;n,λd)/A(λd) ≈ ⟨ω,n⟩/π (000 Eq. 6)"
    return [
        Row(name, "fit over the sphere", "least-squares λd of the normalized lobe", lam_norm),
        Row(name, "fit over the sphere", "least-squares λd with a free amplitude", lam_free),
        Row(name, "λd = 2", "relative L2 error", l2),
        Row(name, "λd = least-squares optimum", "relative L2 error", l2_opt),
        Row(name, "λd = 2", "L1 error (total energy 1)", l1),
        Row(name, "λd = 2", "energy below the horizon (leak)", float(leak)),
        Row(
            name,
            "λd = 2",
            "peak relative error, at ω = n",
            float(lam / (2.0 * -math.expm1(-2.0 * lam)) - 1.0),
        ),
    ]


def _ndf_objective(lam, alpha):
    def f(w):
        c = w[..., 2]
        return (ggx_ndf(c, alpha) * (np.pi * alpha * alpha) - sg_evaluate(w, _Z, lam)) ** 2

    return float(sphere_quadrature(f, _Z, n_phi=1))


def _ndf_rows():
    alpha = ROUGHNESS
    n = alpha.size
    axes = np.broadcast_to(_Z, (n, 3))
    lam = ndf_sharpness(alpha)
    a = alpha[:, None, None]
    ratio = lambda w: ggx_ndf(w[..., 2], a) * np.pi * a * a  # noqa: E731 - D / D(1)
    sg = lambda w: sg_evaluate(w, _Z, lam[:, None, None])  # noqa: E731
    cos_theta = np.linspace(-1.0, 1.0, 200001)
    max_abs = np.max(
        np.abs(
            ggx_ndf(cos_theta, alpha[:, None]) * np.pi * alpha[:, None] ** 2
            - np.exp(lam[:, None] * (cos_theta - 1.0))
        ),
        axis=-1,
    )
    diff2 = sphere_quadrature(lambda w: (ratio(w) - sg(w)) ** 2, axes, n_phi=1)
    ref2 = sphere_quadrature(lambda w: ratio(w) ** 2, axes, n_phi=1)
    rel_l2 = np.sqrt(diff2 / ref2)
    # Energy: D(1) G(h) in place of D in the normalization integral, which is 1 for D.
    energy = sphere_quadrature(lambda w: sg(w) * np.maximum(w[..., 2], 0.0), axes, n_phi=1) / (
        np.pi * alpha**2
    )
    best = np.array(
        [
            math.exp(
                golden_section_minimize(
                    lambda t, a=al: _ndf_objective(math.exp(t) * 2.0 / a**2, a), -2.0, 2.0, 50
                )
            )
            for al in alpha
        ]
    )
    name = "GGX NDF as an SG: D(h)/D(1) ≈ G(h;n,2/α²) (000 app. A.1, 003)"
    glossy = alpha <= 0.1
    rows = [
        Row(name, "α ∈ [1e-3, 0.1]", "max over h of the absolute error", float(max_abs[glossy].max())),
        Row(name, "α ∈ [1e-3, 1]", "max over h of the absolute error", float(max_abs.max())),
        Row(name, "α ∈ [1e-3, 0.1]", "relative L2 error (max)", float(rel_l2[glossy].max())),
        Row(name, "α ∈ [1e-3, 1]", "relative L2 error (max)", float(rel_l2.max())),
        Row(name, "α ∈ [1e-3, 0.1]", "energy ratio ∫D(1)G(h)(h·n)dh, min", float(energy[glossy].min())),
        Row(name, "α ∈ [1e-3, 1]", "energy ratio ∫D(1)G(h)(h·n)dh, min", float(energy.min())),
        Row(name, "α ∈ [1e-3, 0.1]", "least-squares λh / (2/α²), min", float(best[glossy].min())),
        Row(name, "α ∈ [1e-3, 0.1]", "least-squares λh / (2/α²), max", float(best[glossy].max())),
        Row(name, "α = 1", "least-squares λh / (2/α²)", float(best[-1])),
    ]
    return rows


def specular_quadrature(f, incoming, roughness, n_phi=128, order=16):
    """Integral over the sphere of a function concentrated like the GGX lobe f(w', w) <w, n> of
    ``incoming`` w' (normal n = z, batch over leading dimensions).

    Pole at the mirror direction xi_s, tangent across the plane of incidence, azimuthal stretch for
    the lobe's widths: in the plane 2 alpha (bandwidth lam_h / 8, as the ASG lobe of 003), across
    it ~2 alpha (|w'.n| + alpha) (the ASG's lam_h / (8 cos^2) with the cosine widened by alpha, so
    that the hint never claims a narrower lobe than a rough one at grazing incidence really is).
    Lobes that reach the horizon (in-plane bandwidth * (angle of xi_s above the horizon)^2 < 10)
    get the pole at n instead, so that the kink of <w, n> lies on the u = 1 breakpoint, refined
    geometrically from both sides. Accuracy: ~1e-9 away from grazing; the horizon cut limits it to
    ~1e-3 at 85 deg incidence (measured against 4096 azimuth points).
    """
    incoming = f64(incoming)
    alpha = np.broadcast_to(f64(roughness), incoming.shape[:-1])
    x_axis, _, z_axis, _, _ = asg_specular_lobe(incoming, _Z, alpha)
    cos = np.abs(incoming[..., 2])
    lam_h = ndf_sharpness(alpha)
    across = lam_h / (8.0 * (cos + alpha) ** 2)
    along = lam_h / 8.0
    elevation = np.arcsin(np.clip(cos, 0.0, 1.0))
    cut = along * elevation**2 < 10.0
    pole = np.where(cut[..., None], _Z, z_axis)
    return sphere_quadrature(
        f,
        pole,
        tangent=x_axis,
        bandwidths=(across, np.where(cut, 0.0, along)),
        n_phi=n_phi,
        order=order,
        equator=True,
    )


def specular_lobe_errors(alpha, incidence_deg, n_phi=128):
    """Measured errors of the SG (000 Eq. 7) and ASG (003) specular lobes against the GGX lobe
    T(w) = f(w', w) <w, n> with F = 1, for incoming w' at ``incidence_deg`` from the normal.

    Both lobes are scaled to T's energy E (Rs = E): returns a dict with E, the SG lobe's L1 error
    / E, its peak error S(xi_s)/T(xi_s) - 1, its energy below the horizon / E, and the ASG lobe's L1
    error / E (ASG scaled by E / integral of the ASG).
    """
    alpha = f64(alpha)
    theta = np.radians(f64(incidence_deg))
    alpha, theta = np.broadcast_arrays(alpha, theta)
    incoming = direction(theta, 0.0)
    x_axis, y_axis, z_axis, eta_x, eta_y = asg_specular_lobe(incoming, _Z, alpha)
    axis, _ = specular_lobe_warp(incoming, _Z, alpha)
    b = (Ellipsis, None, None)
    bx = (Ellipsis, None, None, slice(None))

    def run(f):
        return specular_quadrature(f, incoming, alpha, n_phi=n_phi)

    def true_lobe(w):
        return microfacet_brdf(incoming[bx], w, _Z, alpha[b], 1.0) * np.maximum(w[..., 2], 0.0)

    def asg_lobe(w):
        return asg_evaluate(w, x_axis[bx], y_axis[bx], z_axis[bx], eta_x[b], eta_y[b])

    energy = run(true_lobe)
    sg_l1 = run(lambda w: np.abs(true_lobe(w) - energy[b] * specular_lobe(w, incoming[bx], _Z, alpha[b])))
    leak = run(lambda w: specular_lobe(w, incoming[bx], _Z, alpha[b]) * (w[..., 2] < 0.0))
    asg_total = run(asg_lobe)
    asg_l1 = run(lambda w: np.abs(true_lobe(w) - (energy / asg_total)[b] * asg_lobe(w)))
    peak_true = true_lobe(axis[..., None, None, :])[..., 0, 0]
    peak_sg = energy * specular_lobe(axis, incoming, _Z, alpha)
    return {
        "energy": energy,
        "sg_l1": sg_l1 / energy,
        "sg_peak": peak_sg / peak_true - 1.0,
        "sg_leak": leak,
        "asg_l1": asg_l1 / energy,
    }


def _specular_rows():
    alpha, incidence = np.meshgrid(WARP_ROUGHNESS, WARP_INCIDENCE_DEG, indexing="ij")
    err = specular_lobe_errors(alpha, incidence)
    glossy = alpha <= 1e-2
    normal = incidence == 0.0
    oblique = incidence <= 60.0
    grazing = incidence >= 75.0
    albedo = "GGX BRDF, F = 1, separable Smith (004 Eq. 7-8)"
    sg_name = "Specular SG lobe Rs·G(ω;ξs,λs)/A(λs) ≈ GGX f·⟨ω,n⟩, Rs = albedo (000 Eq. 7)"
    asg_name = "Specular ASG lobe (003), scaled to the albedo, ≈ GGX f·⟨ω,n⟩"
    every = "α ∈ [1e-3, 0.5], θ' ∈ [0°, 85°]"
    selections = (
        ("α ∈ [1e-3, 1e-2], θ' = 0°", glossy & normal),
        ("α ∈ [1e-3, 1e-2], θ' ∈ [75°, 85°]", glossy & grazing),
        ("α ∈ [1e-3, 0.5], θ' ∈ [0°, 60°]", oblique),
        ("α ∈ [1e-3, 0.5], θ' ∈ [75°, 85°]", grazing),
    )
    rows = [
        Row(albedo, every, "directional albedo, min", float(err["energy"].min())),
        Row(albedo, every, "directional albedo, max", float(err["energy"].max())),
    ]
    for name, key in ((sg_name, "sg_l1"), (asg_name, "asg_l1")):
        for label, sel in selections:
            rows.append(Row(name, label, "L1 error / energy, max", float(err[key][sel].max())))
    peak = err["sg_peak"]
    rows += [
        Row(
            sg_name,
            "α ∈ [1e-3, 1e-2], θ' ∈ [0°, 85°]",
            "peak relative error at ξs, max abs",
            float(np.abs(peak[glossy]).max()),
        ),
        Row(
            sg_name,
            "α ∈ [1e-3, 0.5], θ' ∈ [0°, 60°]",
            "peak relative error at ξs, min",
            float(peak[oblique].min()),
        ),
        Row(
            sg_name,
            "α ∈ [1e-3, 0.5], θ' ∈ [75°, 85°]",
            "peak relative error at ξs, max",
            float(peak[grazing].max()),
        ),
        Row(
            sg_name,
            "α ∈ [1e-3, 0.1], θ' ∈ [0°, 60°]",
            "energy below the horizon, max",
            float(err["sg_leak"][(alpha <= 0.1) & oblique].max()),
        ),
        Row(sg_name, every, "energy below the horizon, max", float(err["sg_leak"].max())),
    ]
    return rows


def _asg_integral_rows():
    etas = np.logspace(-6.0, 7.0, 27)
    ex, ey = np.meshgrid(etas, etas)
    exact, dropped = asg_integral_1d(ex, ey)
    rel = dropped / exact  # = asg_integral / exact - 1 >= 0
    low = np.minimum(ex, ey)
    name = "ASG integral π/sqrt(ηx·ηy) (001 Eq. 34)"
    rows = []
    for lo, hi, label in (
        (50.0, np.inf, "min η ∈ [50, 1e7]"),
        (10.0, 50.0, "min η ∈ [10, 50)"),
        (1.0, 10.0, "min η ∈ [1, 10)"),
        (0.0, 1.0, "min η ∈ [1e-6, 1)"),
    ):
        sel = (low >= lo) & (low < hi)
        rows.append(
            Row(name, label + ", max η ≤ 1e7", "max relative error (overestimate)", float(rel[sel].max()))
        )
    # A check that Eq. 34 is the function the add-on evaluates.
    assert np.allclose(asg_integral(ex, ey), exact + dropped, rtol=EXACT_BOUND, atol=0.0)
    return rows


def conv_errors(n_phi=48, order=16, **grid):
    """(grid, true integrals, approximation with nu = lam/2, with nu = lam) on ``conv_grid``."""
    lam, ex, ey, p, t = conv_grid(**grid)
    true = sg_asg_convolution_quadrature(p, lam, ex, ey, n_phi=n_phi, order=order)
    half = sg_asg_convolution(p, lam, _X, _Y, _Z, ex, ey)  # nu = lam / 2 (000 app. C)
    full = sg_asg_convolution(p, 2.0 * lam, _X, _Y, _Z, ex, ey)  # nu = lam (001 Eq. 11 literally)
    return (lam, ex, ey, p, t), true, half, full


def best_nu_factor(grid, true, selection, factors=np.linspace(0.3, 1.0, 71)):
    """The kappa of nu = kappa lam minimizing the median |log(approx / true)| on a selection."""
    lam, ex, ey, p, _ = grid
    scores = []
    for kappa in factors:
        approx = sg_asg_convolution(p, 2.0 * kappa * lam, _X, _Y, _Z, ex, ey)
        scores.append(np.median(np.abs(np.log(approx[selection] / true[selection]))))
    return float(factors[int(np.argmin(scores))])


def _conv_rows():
    grid, true, half, full = conv_errors()
    lam, ex, ey, _, t = grid
    err_half = np.abs(half / true - 1.0)
    err_full = np.abs(full / true - 1.0)
    sharp = np.minimum(ex, ey) >= 50.0
    name_half = "SG×ASG convolution, ν = λ/2 (000 app. C)"
    name_full = "SG×ASG convolution, ν = λ (001 Eq. 11 as printed)"
    rows = []
    etas = "ηx, ηy ∈ [50, 1e4]"
    for offset, label in ((0.0, "p = z"), (1.0, "p at 1 predicted width"), (2.0, "p at 2 predicted widths")):
        sel = sharp & (lam >= 10.0) & (t == offset)
        params = f"λ ∈ [10, 1e5], {etas}, {label}"
        for name, err in ((name_half, err_half), (name_full, err_full)):
            rows.append(Row(name, params, "median relative error", float(np.median(err[sel]))))
            rows.append(Row(name, params, "max relative error", float(err[sel].max())))
    at_z = sharp & (t == 0.0)
    rows.append(
        Row(
            name_full,
            f"λ ∈ [1, 1e5], {etas}, p = z",
            "min of approximation / quadrature",
            float((full / true)[at_z].min()),
        )
    )
    rows.append(
        Row(
            name_full,
            f"λ ∈ [10, 1e5], {etas}, p within 2 widths",
            "min of approximation / quadrature",
            float((full / true)[sharp & (lam >= 10.0)].min()),
        )
    )
    rows.append(
        Row(
            name_half,
            f"λ = 1, {etas}, p = z",
            "max relative error",
            float(err_half[at_z & (lam == 1.0)].max()),
        )
    )
    rows.append(
        Row(
            name_half,
            f"λ = 1, {etas}, p at 1.2 rad",
            "max relative error",
            float(err_half[sharp & (lam == 1.0) & (t > 0.0)].max()),
        )
    )
    rows.append(
        Row(
            name_half,
            "λ ∈ [10, 1e5], min η ∈ [1, 50), p = z",
            "max relative error",
            float(err_half[~sharp & (lam >= 10.0) & (t == 0.0)].max()),
        )
    )
    rows.append(
        Row(
            name_half,
            "λ ∈ [10, 1e5], min η ∈ [1, 50), p within 2 widths",
            "max relative error",
            float(err_half[~sharp & (lam >= 10.0)].max()),
        )
    )
    rows.append(
        Row(
            "SG×ASG convolution, ν = κλ",
            f"λ ∈ [1, 1e5], {etas}, p within 2 widths",
            "κ minimizing the median abs log(approx/quadrature), grid step 0.01",
            best_nu_factor(grid, true, sharp),
        )
    )
    return rows


def measure():
    """Every figure of docs/accuracy.md, as a list of ``Row``."""
    rows = []
    for part in (_identity_rows, _diffuse_rows, _ndf_rows, _specular_rows, _asg_integral_rows, _conv_rows):
        rows.extend(part())
    return rows


# --------------------------------------------------------------------------------------------------
# Markdown.

HEADER = """\
# Accuracy of the SG / ASG / GGX approximations

Generated by `python -m vsgl_addon.reference.accuracy --write docs/accuracy.md` from the float64
reference in `vsgl_addon/reference/` (formulas in `../shared/reference/formulas.md` sections 1-3;
papers: 000 = Tokuyoshi, VSGL, CVM 2016; 001 = rectangle-based MRP-ASG; 003 = Square Enix SG talk;
004 = Tokuyoshi and Harada, stochastic light culling for GGX). `tests/test_accuracy_table.py`
recomputes every figure and fails when this file is out of date.

How: every "true" value is a numerical integral over the sphere (`vsgl_addon/reference/quadrature.py`:
spherical coordinates about a chosen pole, composite Gauss-Legendre in u = 1 - cos θ with geometric
panels from 1e-12 to 2, periodic trapezoid in a stretched azimuth for anisotropic lobes). The
"exact" rows check closed forms against it: their figures are rounding and quadrature noise, held
below {bound:g}. The other rows measure approximations:

* relative L2 / L1 errors are integrals over the sphere of the difference, divided by the
  integral of the true function (squared for L2);
* "peak" errors compare the two functions at the approximation's axis;
* the specular lobes: incoming direction at θ' ∈ {{0, 30, 60, 75, 85}}° from the normal, α ∈
  {{1e-3, 1e-2, 0.1, 0.3, 0.5}}, F = 1; the quadrature is accurate to ~1e-9 away from grazing
  incidence and ~1e-3 at 85° (where the horizon cuts the lobe);
* the SG×ASG grid: λ ∈ {{1, 10, …, 1e5}}, ηx ≥ ηy from {{1, 10, 50, 100, 1e3, 1e4}}, SG axis p = z
  (the ASG axis) or rotated towards x, x+y or y by t = 1 or 2 "predicted widths" (the ν = λ/2
  form then predicts e^(-t²) of its peak; angle capped at 1.2 rad).

Reading the table: λd = 2 (000 Eq. 6) is close to, not at, the least-squares optimum; the SG
fit λh = 2/α² of the GGX NDF preserves its energy for glossy α but is wider than the
least-squares fit (GGX's tails); Eq. 34 errs by ~e^(−min η) (5e-5 at η = 10, nothing left above
~35), so 001's "large error below 50" is the convolution's (rough surfaces: the ASG lobe of 003 has
ηy = 1/(4α²), below 50 for α > 0.07), as is its error for broad SGs (λ = 1) off axis.

**SG×ASG convolution, ν (issue item).** 000 app. C uses ν = λ/2 for an SG of sharpness λ
(exp(λ(ω·p − 1)) = exp(−(λ/2)|ω − p|²), a Gaussian of the same "bandwidth" units as the ASG's
η); 001 Eq. 11 writes the SG's sharpness itself in that place. The quadrature settles it: with
ν = λ/2 the convolution is accurate to a fraction of a percent on axis and a few percent one
predicted width off axis where 001 says the approximation holds (η ≥ 50); with ν = λ it is off
by up to a factor 2 at p = z and by far more off axis; and the best ν = κλ over the grid is
κ = 0.5. The reference uses ν = λ/2 (the GLSL twins are tested against it).

"""


def _format(value, exact):
    if exact:
        return f"{value:.1e}"
    return f"{value:.4g}"


def to_markdown(rows, header=True):
    lines = [HEADER.format(bound=EXACT_BOUND)] if header else []
    lines.append("| Approximation | Parameters | Metric | Measured |")
    lines.append("|---|---|---|---|")
    for row in rows:
        kind = " (exact)" if row.exact else ""
        lines.append(
            f"| {row.name}{kind} | {row.parameters} | {row.metric} | {_format(row.value, row.exact)} |"
        )
    return "\n".join(lines) + "\n"


def parse_markdown(text):
    """{(name, parameters, metric): (value, exact)} from a table written by ``to_markdown``."""
    table = {}
    for line in text.splitlines():
        if not line.startswith("| ") or line.startswith("| Approximation |"):
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 4:
            continue
        name, parameters, metric, value = cells
        exact = name.endswith(" (exact)")
        if exact:
            name = name[: -len(" (exact)")]
        table[(name, parameters, metric)] = (float(value), exact)
    return table


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", metavar="PATH", help="write the markdown table to PATH")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    text = to_markdown(measure())
    elapsed = time.perf_counter() - start
    if args.write:
        with open(args.write, "w", encoding="utf-8") as fh:
            fh.write(text)
        print(f"wrote {args.write} ({elapsed:.1f} s)", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
