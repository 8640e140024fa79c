# SPDX-License-Identifier: GPL-3.0-or-later
"""Anisotropic spherical Gaussians (ASG), float64 (formulas.md section 2).

``Ga(w; x, y, z, eta_x, eta_y) = <w, z> exp(-eta_x (w.x)^2 - eta_y (w.y)^2)`` with an orthonormal
frame (x, y, z) and bandwidths eta_x, eta_y >= 0 (000 app. C; 001 Eq. 2; Xu et al. 2013). Same
conventions as ``sg``: numpy broadcasting over leading dimensions, vectors in a trailing axis of
length 3, unit vectors in.

Papers: 000 = Tokuyoshi VSGL (CVM 2016); 001 = rectangle-based MRP-ASG; 003 = Square Enix SG talk.
"""

from __future__ import annotations

import numpy as np

from .numerics import dot, f64, norm, safe_ratio
from .sg import COSINE_FLOOR, ndf_sharpness

# Below this sine between view and normal the plane of incidence is undefined in float64 (n x w_o
# is rounding noise), and the lobe is isotropic anyway: 1/cos^2 - 1 < 1e-14.
_PARALLEL_SINE = 1e-7


def asg_evaluate(omega, x_axis, y_axis, z_axis, eta_x, eta_y):
    """Ga(w) = max(w.z, 0) exp(-eta_x (w.x)^2 - eta_y (w.y)^2) (000 app. C; 001 Eq. 2)."""
    omega = f64(omega)
    cx = dot(omega, f64(x_axis))
    cy = dot(omega, f64(y_axis))
    cz = dot(omega, f64(z_axis))
    return np.maximum(cz, 0.0) * np.exp(-f64(eta_x) * cx * cx - f64(eta_y) * cy * cy)


def asg_any_tangent(z):
    """A unit vector perpendicular to z, a smooth function of z except at z.z = 0 (sign flip).

    Duff et al., "Building an orthonormal basis, revisited" (JCGT 2017): branchless and exact for
    unit z, so the GLSL twin can use the same lines.
    """
    sign = np.where(z[..., 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z[..., 2])
    b = z[..., 0] * z[..., 1] * a
    return np.stack((1.0 + sign * z[..., 0] ** 2 * a, sign * b, -sign * z[..., 0]), axis=-1)


def asg_specular_lobe(view, normal, roughness):
    """The microfacet specular lobe at a shading point as an ASG (003; 000 app. C).

    ``view`` = w_o points from the surface to the viewer. Lobe axis z = 2 (w_o.n) n - w_o (mirror
    direction), x perpendicular to the plane of incidence (normalize(n x w_o); any deterministic
    tangent when w_o is parallel to n, where the lobe is isotropic), y = z x x (in the plane).
    Bandwidths: eta_x = lam_h / (8 max((w_o.n)^2, COSINE_FLOOR^2)) (narrows at grazing incidence:
    the warp dw = 2 (w_o.h) dh shrinks the lobe across the plane), eta_y = lam_h / 8; lam_h =
    2 / alpha^2. Why: near the peak an offset e of w moves h by e/2 in the plane and by
    e / (2 (w_o.n)) across it, and G(h; n, lam_h) ~ exp(-lam_h |dh|^2 / 2). (The isotropic warp of
    000 Eq. 7, lam_h / (4 |w_o.n|), is twice the geometric mean of the two bandwidths.)

    Returns ``(x_axis, y_axis, z_axis, eta_x, eta_y)``; the frame is right-handed (x cross y = z).
    """
    view = f64(view)
    normal = f64(normal)
    view, normal = np.broadcast_arrays(view, normal)
    cos_o = dot(view, normal)
    z_axis = 2.0 * cos_o[..., None] * normal - view
    x_raw = np.cross(normal, view)
    parallel = (norm(x_raw) <= _PARALLEL_SINE)[..., None]
    x_raw = np.where(parallel, asg_any_tangent(z_axis), x_raw)
    # Gram-Schmidt against z: near normal incidence n x w_o has only a few correct digits.
    x_raw = x_raw - dot(x_raw, z_axis)[..., None] * z_axis
    x_axis = x_raw / norm(x_raw)[..., None]
    y_axis = np.cross(z_axis, x_axis)
    lam_h = ndf_sharpness(roughness)
    cos2 = np.maximum(cos_o * cos_o, COSINE_FLOOR * COSINE_FLOOR)
    eta_x = lam_h / (8.0 * cos2)
    eta_y = np.broadcast_to(lam_h / 8.0, eta_x.shape).copy()
    return x_axis, y_axis, z_axis, eta_x, eta_y


def sg_asg_convolution(sg_axis, sg_sharpness, x_axis, y_axis, z_axis, eta_x, eta_y):
    """Approximate integral of G(w; p, lam) Ga(w; x, y, z, eta_x, eta_y) over the sphere.

    000 app. C (after Xu et al. 2013), also 001 Eq. 11:
        pi / sqrt((eta_x + nu)(eta_y + nu))
        * Ga(p; x, y, z, eta_x nu / (eta_x + nu), eta_y nu / (eta_y + nu)),   nu = lam / 2.
    nu = lam / 2 because exp(lam (w.p - 1)) = exp(-nu |w - p|^2): the SG is a Gaussian of
    "bandwidth" nu in the same units as the ASG's eta. 001 Eq. 11 puts lam itself there; the
    quadrature in docs/accuracy.md shows lam / 2 is the accurate choice.

    The prefactor is pi / (sqrt(eta_x + nu) sqrt(eta_y + nu)): the product (eta_x + nu)(eta_y + nu)
    reaches ~1e27 for grazing glossy lobes and overflows float32 in the GLSL twin. Finite whenever
    eta_x + nu > 0 and eta_y + nu > 0.
    """
    nu = 0.5 * f64(sg_sharpness)
    eta_x = f64(eta_x)
    eta_y = f64(eta_y)
    sum_x = eta_x + nu
    sum_y = eta_y + nu
    # eta nu / (eta + nu) -> 0 when both are 0 (a constant times a constant).
    reduced_x = safe_ratio(eta_x * nu, sum_x)
    reduced_y = safe_ratio(eta_y * nu, sum_y)
    scale = np.pi / (np.sqrt(sum_x) * np.sqrt(sum_y))
    return scale * asg_evaluate(sg_axis, x_axis, y_axis, z_axis, reduced_x, reduced_y)


def asg_integral(eta_x, eta_y, amplitude=1.0):
    """Approximate integral of amplitude * Ga over the sphere: pi t / sqrt(eta_x eta_y) (001 Eq. 34).

    Exactly, the integral is (1/2) * integral over phi of (1 - e^(-k)) / k,
    k = eta_x cos^2 phi + eta_y sin^2 phi (the cosine of Ga cancels the Jacobian of the projection to
    the tangent disk); Eq. 34 drops the e^(-k), so it is exact up to ~e^(-min(eta)) and
    overestimates for small bandwidths (docs/accuracy.md). sqrt(eta_x) sqrt(eta_y) for the same
    float32 reason as ``sg_asg_convolution``.
    """
    return np.pi * f64(amplitude) / (np.sqrt(f64(eta_x)) * np.sqrt(f64(eta_y)))
