# SPDX-License-Identifier: GPL-3.0-or-later
"""The validation suite's plot (per scene, visibility off and on against Cycles) and the README's
before/after image of an occluded scene (Cycles | VSGL visibility off | on)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def plot(rows: list[dict], path: Path) -> None:
    """Two panels per scene, visibility off and on: mean indirect ours / Cycles (1 is right, the
    ±10 % band shaded) and the noise-corrected relative RMSE."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [row["scene"] for row in rows]
    x = np.arange(len(rows))
    fig, (ratio_axes, error_axes) = plt.subplots(1, 2, figsize=(11, 3.8))
    for offset, key, colour in ((-0.2, "off", "#999999"), (0.2, "on", "#2b6cb0")):
        ratio_axes.bar(x + offset, [row["visibility"][key]["mean_ratio"] for row in rows], 0.4, color=colour,
                       label=f"visibility {key}")
        error_axes.bar(x + offset, [row["visibility"][key]["rel"] for row in rows], 0.4, color=colour,
                       label=f"visibility {key}")
    ratio_axes.axhspan(0.9, 1.1, color="#c6f6d5", zorder=0)
    ratio_axes.axhline(1.0, color="black", linewidth=0.8)
    ratio_axes.set_ylabel("mean indirect, ours / Cycles")
    error_axes.set_ylabel("relative RMSE against Cycles")
    for axes in (ratio_axes, error_axes):
        axes.set_xticks(x, names, rotation=30, ha="right")
        axes.legend(frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _display(image: np.ndarray, white: float) -> np.ndarray:
    """Linear radiance → 8-bit sRGB, `white` mapped to 1 (one exposure for all three panels)."""
    linear = np.clip(np.asarray(image, np.float64) / max(white, 1e-30), 0.0, 1.0)
    srgb = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1.0 / 2.4) - 0.055)
    return np.rint(srgb * 255.0).astype(np.uint8)


def before_after(truth: np.ndarray, off: np.ndarray, on: np.ndarray, path: Path, title: str,
                 labels=("VSGL visibility off", "VSGL visibility on")) -> None:
    """Cycles | ours with a technique off | with it on (default: VSGL visibility), indirect light only,
    one exposure (the truth's 99th percentile is white); rows bottom-up as the passes give them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    white = float(np.percentile(truth, 99.0))
    fig, axes = plt.subplots(1, 3, figsize=(10.5, 3.1))
    for axis, image, label in zip(axes, (truth, off, on), ("Cycles (max bounces 1)", *labels)):
        axis.imshow(_display(image[::-1], white))
        axis.set_title(label, fontsize=10)
        axis.axis("off")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
