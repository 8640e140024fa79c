# SPDX-License-Identifier: GPL-3.0-or-later
"""image_compare: two renders are the same floats but for denormal residue, and nothing else passes."""

from __future__ import annotations

import numpy as np

from image_compare import RESIDUE, assert_same_floats, same_floats


def test_residue_passes_and_every_visible_change_fails():
    image = np.linspace(0.0, 4.0, 48, dtype=np.float32).reshape(4, 3, 4)
    image[3, 2] = 0.0
    assert same_floats(image, image.copy())
    residue = image.copy()
    residue[0, 0, 0] = np.float32(1e-44)
    residue[3, 2, 2] = np.float32(7e-40)
    residue[3, 2, 1] = np.float32(2e-21)
    assert same_floats(residue, image)
    assert_same_floats(residue, image)
    one_ulp = image.copy()
    one_ulp[2, 2, 2] = np.nextafter(one_ulp[2, 2, 2], np.float32(np.inf))
    assert not same_floats(one_ulp, image)
    beyond = image.copy()
    beyond[0, 0, 0] = np.float32(10 * RESIDUE)
    assert not same_floats(beyond, image)
    assert not same_floats(image[:2], image)
    poisoned = image.copy()
    poisoned[3, 0, 0] = np.nan
    assert not same_floats(poisoned, poisoned.copy())
    for bad in (one_ulp, beyond, poisoned):
        try:
            assert_same_floats(bad, image if bad is not poisoned else poisoned.copy(), err_msg="x")
        except AssertionError:
            continue
        raise AssertionError("a changed image passed")
