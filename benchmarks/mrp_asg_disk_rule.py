# SPDX-License-Identifier: GPL-3.0-or-later
"""MRP-ASG's sampling disk: 001's fixed r_d against at least DISK_LOBE_SCALE lobe footprints (not a test).

    .venv/bin/python benchmarks/mrp_asg_disk_rule.py

On the configurations of benchmarks/mrp_asg_accuracy.py (a 4 x 4 m rectangle, a point light 2 m
from its centre, 16 receivers seeing its peak, one parameter varied at a time around reflector
α 0.05, receiver α 0.2, σ 30°, 1 m, r_d 0.1 m): relative RMSE of reference.mrp_asg.mrp_shade
(ASG mode) against the quadrature of Eq. 3 (brute_force_rectangle), and the mean over the truth's,
with ``disk="fixed"`` and ``disk="lobe"``. Writes benchmarks/results/mrp_asg_disk_rule.md.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "benchmarks"):
    sys.path.insert(0, str(folder))

import mrp_asg_accuracy as accuracy  # noqa: E402
from vsgl_addon.reference import mrp_asg as mrp  # noqa: E402


def main() -> int:
    lines = ["# MRP-ASG's sampling disk: fixed r_d (001) against at least "
             f"{mrp.DISK_LOBE_SCALE:g} lobe footprints", "",
             "`.venv/bin/python benchmarks/mrp_asg_disk_rule.py` (the module's documentation); relative RMSE "
             "against the quadrature of Eq. 3 (mean / truth's mean).", "",
             "| varied | reflector α | receiver α | σ (°) | distance (m) | r_d (m) | fixed r_d | lobe rule |",
             "|---|---|---|---|---|---|---|---|"]
    for name, values in accuracy.SWEEPS.items():
        for value in values:
            c = {**accuracy.BASE, name: value}
            rect, light, p, n, o, radius, alpha_x = accuracy.configuration(**c)
            truth = np.array([mrp.brute_force_rectangle(p[i], n[i], o[i], alpha_x, accuracy.F0, rect, light)
                              for i in range(len(p))])
            cells = []
            for disk in mrp.DISK_RULES:
                value_ = mrp.mrp_shade(p, n, o, alpha_x, accuracy.F0, rect, light, radius, "asg", disk=disk)
                cells.append(f"{accuracy.rel_rmse(value_, truth):.3f} ({value_.mean() / truth.mean():.2f})")
            lines.append(f"| {name} | {c['alpha_r']:g} | {c['alpha_x']:g} | {c['sigma']:g} | {c['distance']:g} | "
                         f"{c['radius']:g} | " + " | ".join(cells) + " |")
            print(lines[-1], flush=True)
    out = REPO / "benchmarks" / "results" / "mrp_asg_disk_rule.md"
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
