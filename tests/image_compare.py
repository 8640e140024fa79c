# SPDX-License-Identifier: GPL-3.0-or-later
"""Comparing two GPU renders of the same passes: the same floats, but for sub-1e-18 residue.

llvmpipe flushes denormals in fragment shaders but keeps them in compute shaders (their threads
take the process's MXCSR when the context is made; measured with a 1e-20² probe). Values near
the float32 denormal range therefore depend on which kind of shader, and which machine's JIT code,
carried them. Two renders of the same passes have been seen to differ only there, in some full
test runs and not in others (CI's machine: at 15 of 76,800 pixels by 1e-44, 6 by 7e-40, and at 3
pixels a 2e-21 against a 0; once on the development machine). Not reproduced alone, with every new
texture poisoned, or with denormals flushed before the context was made.
Anything at or above 1e-18 (some 60 stops below a visible value) must be bit for bit equal, so a
one-ulp change of any visible pixel still fails.
"""

from __future__ import annotations

import numpy as np

#: The largest absolute difference treated as denormal residue rather than another image.
RESIDUE = 1e-18


def same_floats(actual, desired) -> bool:
    """Equal shapes, and equal floats wherever either differs from the other by more than RESIDUE."""
    actual, desired = np.asarray(actual), np.asarray(desired)
    if actual.shape != desired.shape:
        return False
    different = actual != desired
    return bool(np.all(np.abs(actual[different].astype(np.float64) - desired[different]) <= RESIDUE))


def assert_same_floats(actual, desired, err_msg: str = "") -> None:
    """Raise, with numpy's report of the mismatch, unless same_floats(actual, desired)."""
    if not same_floats(actual, desired):
        np.testing.assert_array_equal(actual, desired, err_msg=err_msg)
        raise AssertionError(f"{err_msg}: NaN at the same pixels (numpy counts them equal)")
