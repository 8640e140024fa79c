# SPDX-License-Identifier: GPL-3.0-or-later
"""Numerical solvers behind docs/accuracy.md: quadrature comparisons, fits and error measurements
of the SG / ASG / GGX approximations against integrals over the sphere.

``measurements`` turns their results into the table's rows; the tests of ``sg``, ``asg`` and
``ggx`` call them directly. Every "true" value is a ``quadrature.sphere_quadrature`` integral (or,
for the ASG integral, an exact 1D form) with the pole and the azimuthal stretch chosen for the lobe
at hand.
"""

from __future__ import annotations

import math

import numpy as np

from .asg import asg_evaluate, asg_specular_lobe, sg_asg_convolution
from .ggx import ggx_ndf, microfacet_brdf
from .numerics import dot, f64, norm
from .quadrature import composite_gauss_legendre, sphere_quadrature
from .sg import ndf_sharpness, sg_evaluate, sg_lobe_normalized, specular_lobe, specular_lobe_warp

#: The frame the measurements place their lobes in: z is the surface normal or the ASG axis.
X_AXIS = np.array([1.0, 0.0, 0.0])
Y_AXIS = np.array([0.0, 1.0, 0.0])
Z_AXIS = np.array([0.0, 0.0, 1.0])

#: Grids of the measurements (the tests reuse them).
ROUGHNESS = np.array([1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0])
WARP_ROUGHNESS = np.array([1e-3, 1e-2, 0.1, 0.3, 0.5])
WARP_INCIDENCE_DEG = np.array([0.0, 30.0, 60.0, 75.0, 85.0])
CONV_SHARPNESS = np.array([1.0, 10.0, 100.0, 1e3, 1e4, 1e5])
CONV_BANDWIDTH = np.array([1.0, 10.0, 50.0, 100.0, 1e3, 1e4])


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


def direction(theta, beta, x_axis=X_AXIS, y_axis=Y_AXIS, z_axis=Z_AXIS):
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
    half = 0.25 * np.pi * np.concatenate(([0.0], np.logspace(-14.0, 0.0, 57)))
    edges = np.concatenate((half, 0.5 * np.pi - half[::-1][1:]))
    phi, weights = composite_gauss_legendre(edges, 20)
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
        t1 = X_AXIS - cx[..., None] * omega
        t1 = np.where((norm(t1) < 0.5)[..., None], Y_AXIS - cy[..., None] * omega, t1)
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
    pole = np.where((np.minimum(eta_x, eta_y) + nu < 40.0)[..., None], Z_AXIS, pole)

    def integrand(omega):
        return sg_evaluate(omega, p[..., None, None, :], lam[..., None, None]) * asg_evaluate(
            omega, X_AXIS, Y_AXIS, Z_AXIS, eta_x[..., None, None], eta_y[..., None, None]
        )

    return sphere_quadrature(
        integrand, pole, tangent=X_AXIS, bandwidths=(eta_x + nu, eta_y + nu), n_phi=n_phi, order=order
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


def diffuse_objective(lam):
    def f(w):
        return (sg_lobe_normalized(w, Z_AXIS, lam) - np.maximum(w[..., 2], 0.0) / np.pi) ** 2

    return float(sphere_quadrature(f, Z_AXIS, n_phi=1))


def _diffuse_free_amplitude_objective(lam):
    """Least squares of a G(w; n, lam) vs <w, n> with the best amplitude a for this lam."""
    gc = sphere_quadrature(lambda w: sg_evaluate(w, Z_AXIS, lam) * np.maximum(w[..., 2], 0.0), Z_AXIS, n_phi=1)
    gg = sphere_quadrature(lambda w: sg_evaluate(w, Z_AXIS, 2.0 * lam), Z_AXIS, n_phi=1)
    cc = 2.0 * np.pi / 3.0
    return float(cc - gc * gc / gg)


def diffuse_fit():
    """(least-squares lam_d of the normalized lobe, least-squares lam_d with a free amplitude)."""
    return (
        golden_section_minimize(diffuse_objective, 0.5, 6.0),
        golden_section_minimize(_diffuse_free_amplitude_objective, 0.5, 6.0),
    )


def ndf_objective(lam, alpha):
    def f(w):
        c = w[..., 2]
        return (ggx_ndf(c, alpha) * (np.pi * alpha * alpha) - sg_evaluate(w, Z_AXIS, lam)) ** 2

    return float(sphere_quadrature(f, Z_AXIS, n_phi=1))


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
    x_axis, _, z_axis, _, _ = asg_specular_lobe(incoming, Z_AXIS, alpha)
    cos = np.abs(incoming[..., 2])
    lam_h = ndf_sharpness(alpha)
    across = lam_h / (8.0 * (cos + alpha) ** 2)
    along = lam_h / 8.0
    elevation = np.arcsin(np.clip(cos, 0.0, 1.0))
    cut = along * elevation**2 < 10.0
    pole = np.where(cut[..., None], Z_AXIS, z_axis)
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
    x_axis, y_axis, z_axis, eta_x, eta_y = asg_specular_lobe(incoming, Z_AXIS, alpha)
    axis, _ = specular_lobe_warp(incoming, Z_AXIS, alpha)
    b = (Ellipsis, None, None)
    bx = (Ellipsis, None, None, slice(None))

    def run(f):
        return specular_quadrature(f, incoming, alpha, n_phi=n_phi)

    def true_lobe(w):
        return microfacet_brdf(incoming[bx], w, Z_AXIS, alpha[b], 1.0) * np.maximum(w[..., 2], 0.0)

    def asg_lobe(w):
        return asg_evaluate(w, x_axis[bx], y_axis[bx], z_axis[bx], eta_x[b], eta_y[b])

    energy = run(true_lobe)
    sg_l1 = run(lambda w: np.abs(true_lobe(w) - energy[b] * specular_lobe(w, incoming[bx], Z_AXIS, alpha[b])))
    leak = run(lambda w: specular_lobe(w, incoming[bx], Z_AXIS, alpha[b]) * (w[..., 2] < 0.0))
    asg_total = run(asg_lobe)
    asg_l1 = run(lambda w: np.abs(true_lobe(w) - (energy / asg_total)[b] * asg_lobe(w)))
    peak_true = true_lobe(axis[..., None, None, :])[..., 0, 0]
    peak_sg = energy * specular_lobe(axis, incoming, Z_AXIS, alpha)
    return {
        "energy": energy,
        "sg_l1": sg_l1 / energy,
        "sg_peak": peak_sg / peak_true - 1.0,
        "sg_leak": leak,
        "asg_l1": asg_l1 / energy,
    }


def conv_errors(n_phi=48, order=16, **grid):
    """(grid, true integrals, approximation with nu = lam/2, with nu = lam) on ``conv_grid``."""
    lam, ex, ey, p, t = conv_grid(**grid)
    true = sg_asg_convolution_quadrature(p, lam, ex, ey, n_phi=n_phi, order=order)
    half = sg_asg_convolution(p, lam, X_AXIS, Y_AXIS, Z_AXIS, ex, ey)  # nu = lam / 2 (000 app. C)
    full = sg_asg_convolution(p, 2.0 * lam, X_AXIS, Y_AXIS, Z_AXIS, ex, ey)  # nu = lam (001 Eq. 11 literally)
    return (lam, ex, ey, p, t), true, half, full


def best_nu_factor(grid, true, selection, factors=np.linspace(0.3, 1.0, 71)):
    """The kappa of nu = kappa lam minimizing the median |log(approx / true)| on a selection."""
    lam, ex, ey, p, _ = grid
    scores = []
    for kappa in factors:
        approx = sg_asg_convolution(p, 2.0 * kappa * lam, X_AXIS, Y_AXIS, Z_AXIS, ex, ey)
        scores.append(np.median(np.abs(np.log(approx[selection] / true[selection]))))
    return float(factors[int(np.argmin(scores))])
