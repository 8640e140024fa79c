# SPDX-License-Identifier: GPL-3.0-or-later
"""The view-dependent PDF of VSGL generation (000 §5, bidirectional reflective shadow maps), float64.

000 §5 samples the VSGLs' kernel centres from "a dynamic and high-frequency view-dependent PDF
p(x) given by the bidirectional reflective shadow mapping method": light that reaches no pixel the
camera sees needs no VSGL. The paper estimates each RSM texel's importance from 2048 VSGLs without
shadow maps generated on the camera G-buffer (reflectance as PDF). Here the G-buffer's receivers
are kept as points (a few hundred eye samples, each weighted by its diffuse reflectance ρ_d), and
texel y's importance is their unshadowed diffuse-to-diffuse form factor with it,

    I(y) = Σ_x ρ_d(x) max(0, n_y·ω) max(0, −n_x·ω) / (|x − y|² + r²),   ω = (x − y) / |x − y|,

r a length that keeps the 1/d² pole of a receiver next to a texel finite (texels and receivers are
points standing for patches). It weighs the receivers' diffuse lobes only, and the VSGL sets that
light only specular lobes keep the light PDF (pipeline.view_pdf_serves): on the validation suite's
polished metal floor (GGX α 0.02, benchmarks/results/view_pdf.md's occluded_reflector) every view
PDF measured on the specular sets raised the error against Cycles, by 6-12 % with this form factor
(weighted by the base colour, metals included), 23-27 % with the receivers' GGX lobes towards the
eye in its place, 35-46 % with the texels' specular emission lobes as well (three lattice seeds
each): the kernels shrink where the PDF rises (000 Eq. 3) and a near-mirror receiver resolves them
one by one, as streaks, where the light PDF's larger kernels blend. The view PDF is the light PDF's weight w(y) = lum Φ(Rd + Rs) times
I(y); VSGL generation gets the defensive mixture

    p(y) = (1 − β) w(y) I(y) / Σ w I + β w(y) / Σ w,

so every texel with bounce power keeps a probability of at least β times the light PDF's (and the
view PDF alone where nothing in view is lit falls back to the light PDF). Generation stays
unbiased whatever p is (000 Eq. 5 divides each kernel's filtered flux by its filtered PDF mass).
"""

from __future__ import annotations

import numpy as np

from .numerics import f64

#: β, the light PDF's share of the mixture (Hesterberg's defensive importance sampling).
DEFENSIVE_SHARE = 0.25
#: Texel rows per block of the importance sum (keeps the (texels × receivers) block small).
_BLOCK = 4096


def view_importance(positions, normals, receiver_positions, receiver_normals, receiver_weights,
                    radius: float) -> np.ndarray:
    """I(y) of the module docstring for texels (..., 3) (positions, unit normals) and receivers
    (M, 3) with weights (M,) ≥ 0; texels with a zero normal (no geometry) get 0."""
    p = f64(positions).reshape(-1, 3)
    n = f64(normals).reshape(-1, 3)
    rx = f64(receiver_positions).reshape(-1, 3)
    rn = f64(receiver_normals).reshape(-1, 3)
    rw = np.maximum(f64(receiver_weights).reshape(-1), 0.0)
    r2 = float(radius) ** 2
    out = np.zeros(len(p))
    if len(rx) == 0:
        return out.reshape(np.shape(positions)[:-1])
    for start in range(0, len(p), _BLOCK):
        d = rx[None, :, :] - p[start:start + _BLOCK, None, :]  # (B, M, 3) texel -> receiver
        dist2 = np.einsum("bmk,bmk->bm", d, d)
        inv = 1.0 / np.sqrt(np.maximum(dist2, 1e-30))
        cos_y = np.maximum(np.einsum("bmk,bk->bm", d, n[start:start + _BLOCK]) * inv, 0.0)
        cos_x = np.maximum(-np.einsum("bmk,mk->bm", d, rn) * inv, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):  # r = 0 at a receiver on a texel: 0/0, set to 0 below
            out[start:start + _BLOCK] = (cos_y * cos_x / (dist2 + r2)) @ rw
    return np.where(np.isfinite(out), out, 0.0).reshape(np.shape(positions)[:-1])


def view_pdf(light_weight, importance, defensive: float | None = None) -> np.ndarray:
    """The defensive mixture p of the module docstring (sums to 1 where any texel has weight; all
    zeros where none has). ``light_weight`` w(y) ≥ 0 and ``importance`` I(y) ≥ 0, same shape;
    ``defensive`` β, DEFENSIVE_SHARE (read when called) when None."""
    defensive = DEFENSIVE_SHARE if defensive is None else float(defensive)
    w = np.maximum(np.where(np.isfinite(f64(light_weight)), f64(light_weight), 0.0), 0.0)
    i = np.maximum(np.where(np.isfinite(f64(importance)), f64(importance), 0.0), 0.0)
    total = w.sum()
    if total <= 0.0:
        return np.zeros_like(w)
    light = w / total
    product = w * i
    if product.sum() <= 0.0:
        return light
    return (1.0 - defensive) * product / product.sum() + defensive * light
