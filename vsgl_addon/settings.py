# SPDX-License-Identifier: GPL-3.0-or-later
"""The render parameters as plain values (no bpy): what the passes receive.

`scene.vsgl` (properties.py) stores them in the .blend; the command line overrides them for one
run. Ranges are the add-on's, shared by both (issue 3: N from 1 to 4096, K from 0.25 to 16).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

KERNEL_MODES = ("modified", "original", "two-vsgl")
# scene.vsgl.kernel identifiers (stored in .blend files) -> pass names (000 Eq. 3, Eqs. 1/4, 003).
KERNEL_FROM_PROPERTY = {"MODIFIED": "modified", "ORIGINAL": "original", "TWO_VSGL": "two-vsgl"}
# Where each VSGL's lobes sit (reference.vsgl.POSITIONAL_DISTRIBUTIONS): own power centroid per lobe,
# or 000 app. B.2's one Gaussian for both.
POSITIONAL_DISTRIBUTIONS = ("per-lobe", "shared")
POSITIONAL_FROM_PROPERTY = {"PER_LOBE": "per-lobe", "SHARED": "shared"}

VSGL_COUNT_RANGE = (1, 4096)
K_RANGE = (0.25, 16.0)
# VSGL generation walks a square mip chain, so the RSM side is a power of two (1 x 1 works).
RSM_SIZE_RANGE = (1, 2048)


class SettingsError(ValueError):
    """A parameter outside its range; the message names it, the range and the value."""


def _check_range(name, value, low, high):
    if not (low <= value <= high):
        raise SettingsError(f"{name} must be in [{low:g}, {high:g}], got {value:g}")


def nearest_power_of_two(size: int) -> int:
    """The power of two nearest to `size` in log scale, within RSM_SIZE_RANGE."""
    size = min(max(int(size), RSM_SIZE_RANGE[0]), RSM_SIZE_RANGE[1])
    return 2 ** round(math.log2(size))


@dataclass(frozen=True)
class VSGLSettings:
    vsgl_count: int = 256
    k: float = 1.0
    kernel: str = "modified"
    rsm_size: int = 128
    seed: int = 0
    positional_distribution: str = "per-lobe"

    def __post_init__(self):
        _check_range("VSGL count", self.vsgl_count, *VSGL_COUNT_RANGE)
        if not math.isfinite(self.k):
            raise SettingsError(f"K must be a finite number, got {self.k}")
        _check_range("K", self.k, *K_RANGE)
        if self.kernel not in KERNEL_MODES:
            raise SettingsError(f"kernel must be one of {', '.join(KERNEL_MODES)}, got {self.kernel!r}")
        _check_range("RSM size", self.rsm_size, *RSM_SIZE_RANGE)
        if self.rsm_size & (self.rsm_size - 1):
            raise SettingsError(f"RSM size must be a power of two, got {self.rsm_size}")
        if self.seed < 0:
            raise SettingsError(f"seed must be 0 or more, got {self.seed}")
        if self.positional_distribution not in POSITIONAL_DISTRIBUTIONS:
            raise SettingsError(f"positional distribution must be one of "
                                f"{', '.join(POSITIONAL_DISTRIBUTIONS)}, got {self.positional_distribution!r}")

    @classmethod
    def from_properties(cls, properties) -> "VSGLSettings":
        """From a `scene.vsgl` property group (or anything with its attribute names).

        The property allows any RSM resolution in its range; the passes use the nearest power of two.
        """
        return cls(vsgl_count=int(properties.vsgl_count), k=float(properties.k),
                   kernel=KERNEL_FROM_PROPERTY[properties.kernel],
                   rsm_size=nearest_power_of_two(properties.rsm_size), seed=int(properties.seed),
                   positional_distribution=POSITIONAL_FROM_PROPERTY[properties.positional_distribution])

    def overridden(self, **values) -> "VSGLSettings":
        """A copy with the given values (None means keep), validated."""
        return replace(self, **{name: value for name, value in values.items() if value is not None})
