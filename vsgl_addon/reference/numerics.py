# SPDX-License-Identifier: GPL-3.0-or-later
"""Numerics shared by every float64 reference module (twin of ``glsl/lib/math.glsl``).

Same conventions as the rest of the package: numpy broadcasting over leading dimensions, vectors in
a trailing axis of length 3. The guarded forms return a finite value where the plain formula would
divide by zero; they are written ``np.where(ok, x / np.where(ok, d, 1), fallback)`` so that the
masked lanes never compute 0/0 (no NaN, no floating-point warning).

``safe_normalize`` keeps the name and the fallback of its GLSL twin but not the GLSL's rescaling
by the largest component: that guards float32's range (|v| < 1e-19 underflows its squares), which
float64 reaches only below 1e-154, far outside the scenes and the tests.

The error-free transformations of math.glsl (``two_sum``, ``two_product``, ``dot_accurate``) and its
series ``expm1`` have no twin here: float64 holds the digits they recover in float32, and numpy has
``np.expm1``.
"""

from __future__ import annotations

import numpy as np


def f64(x):
    """``x`` as a float64 array (every reference function computes in float64)."""
    return np.asarray(x, dtype=np.float64)


def dot(a, b):
    """a . b over the trailing axis."""
    return np.sum(a * b, axis=-1)


def norm(a):
    """|a| over the trailing axis."""
    return np.sqrt(dot(a, a))


def one_minus_exp_ratio(x):
    """(1 - e^-x) / x for x >= 0, = 1 at x = 0: the integral of an SG over its naive bound
    (000 app. A).

    expm1 keeps full relative precision for tiny x, where 1 - exp(-x) would be all rounding.
    """
    x = f64(x)
    safe = np.where(x > 0.0, x, 1.0)
    return np.where(x > 0.0, -np.expm1(-safe) / safe, 1.0)


def safe_ratio(numerator, denominator):
    """numerator / denominator where denominator > 0, else 0 (the denominator broadcast over the
    numerator's extra trailing dimensions, e.g. an RGB sum over a scalar weight)."""
    den = np.asarray(denominator)
    ok = den > 0.0
    den = np.where(ok, den, 1.0)
    extra = (Ellipsis,) + (None,) * (np.ndim(numerator) - np.ndim(den))
    return np.where(ok[extra], numerator / den[extra], 0.0)


def safe_normalize(v, fallback, length=None):
    """v / |v| where |v| > 0, else ``fallback``. ``length``: |v| when the caller already has it."""
    if length is None:
        length = norm(v)
    ok = (length > 0.0)[..., None]
    return np.where(ok, v / np.where(ok, length[..., None], 1.0), fallback)
