# SPDX-License-Identifier: GPL-3.0-or-later
"""The figures of docs/accuracy.md: ``measure()`` runs the ``solvers`` and returns one ``Row`` per
figure, which ``accuracy.to_markdown`` renders.

Rows with ``exact=True`` are closed forms checked against the quadrature: their value is rounding
and quadrature noise, bounded by ``EXACT_BOUND`` rather than reproduced digit for digit.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .asg import asg_evaluate, asg_integral
from .ggx import ggx_ndf
from .quadrature import sphere_quadrature
from .sg import (
    DIFFUSE_SHARPNESS,
    ndf_sharpness,
    sg_evaluate,
    sg_integral,
    sg_lobe_normalized,
    sg_product,
    sg_product_integral,
)
from .solvers import (
    ROUGHNESS,
    WARP_INCIDENCE_DEG,
    WARP_ROUGHNESS,
    X_AXIS,
    Y_AXIS,
    Z_AXIS,
    asg_integral_1d,
    best_nu_factor,
    conv_errors,
    diffuse_fit,
    diffuse_objective,
    direction,
    golden_section_minimize,
    ndf_objective,
    specular_lobe_errors,
)

#: Exact identities must match the quadrature to this relative error (the tests use it too).
EXACT_BOUND = 1e-9


class Row(NamedTuple):
    name: str
    parameters: str
    metric: str
    value: float
    exact: bool = False


def _identity_rows():
    rows = []
    lam = np.logspace(-6.0, 7.0, 14)
    quad = sphere_quadrature(
        lambda w: sg_evaluate(w, Z_AXIS, lam[:, None, None]), np.broadcast_to(Z_AXIS, (14, 3)), n_phi=1
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
    a1 = np.broadcast_to(Z_AXIS, l1.shape + (3,))
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
        np.broadcast_to(Z_AXIS, alpha.shape + (3,)),
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
        lambda w: asg_evaluate(w, X_AXIS, Y_AXIS, Z_AXIS, ex[:, None, None], ey[:, None, None]),
        np.broadcast_to(Z_AXIS, ex.shape + (3,)),
        tangent=X_AXIS,
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


def _diffuse_rows():
    lam_norm, lam_free = diffuse_fit()
    lam = DIFFUSE_SHARPNESS
    cosine_l2 = math.sqrt(2.0 * np.pi / 3.0) / np.pi  # ||<w, n>/pi||_2

    def errors(lam):
        l2 = math.sqrt(diffuse_objective(lam)) / cosine_l2
        l1 = sphere_quadrature(
            lambda w: np.abs(sg_lobe_normalized(w, Z_AXIS, lam) - np.maximum(w[..., 2], 0.0) / np.pi), Z_AXIS, n_phi=1
        )
        return l2, float(l1)

    l2, l1 = errors(lam)
    l2_opt, _ = errors(lam_norm)
    leak = sphere_quadrature(lambda w: sg_lobe_normalized(w, Z_AXIS, lam) * (w[..., 2] < 0.0), Z_AXIS, n_phi=1)
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
    ] + _diffuse_hemisphere_rows(lam)


def _diffuse_hemisphere_rows(lam):
    """The lobe VPLs and VSGLs emit with: 000 Eq. 6's SG normalized over the hemisphere
    (sg.DIFFUSE_HEMISPHERE_SCALE), which carries Lambert's energy above the horizon."""
    scale = 1.0 + math.exp(-lam)
    lobe = lambda w: scale * sg_lobe_normalized(w, Z_AXIS, lam)  # noqa: E731
    above = sphere_quadrature(lambda w: lobe(w) * (w[..., 2] > 0.0), Z_AXIS, n_phi=1, equator=True)
    l1 = sphere_quadrature(lambda w: np.abs(lobe(w) * (w[..., 2] > 0.0) - np.maximum(w[..., 2], 0.0) / np.pi),
                           Z_AXIS, n_phi=1, equator=True)
    name = "Diffuse SG lobe normalized over the hemisphere, (1 + e^(−λd)) G(ω;n,λd)/A(λd) ≈ ⟨ω,n⟩/π"
    return [
        Row(name, "λd = 2", "energy above the horizon (Lambert: 1)", float(above)),
        Row(name, "λd = 2", "L1 error above the horizon (total energy 1)", float(l1)),
        Row(name, "λd = 2", "peak relative error, at ω = n", float(scale * lam / (2.0 * -math.expm1(-2.0 * lam)) - 1.0)),
    ]


def _ndf_rows():
    alpha = ROUGHNESS
    n = alpha.size
    axes = np.broadcast_to(Z_AXIS, (n, 3))
    lam = ndf_sharpness(alpha)
    a = alpha[:, None, None]
    ratio = lambda w: ggx_ndf(w[..., 2], a) * np.pi * a * a  # noqa: E731 - D / D(1)
    sg = lambda w: sg_evaluate(w, Z_AXIS, lam[:, None, None])  # noqa: E731
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
                    lambda t, a=al: ndf_objective(math.exp(t) * 2.0 / a**2, a), -2.0, 2.0, 50
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
