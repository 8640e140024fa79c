# SPDX-License-Identifier: GPL-3.0-or-later
"""Where MRP-ASG's excess on sharp receivers comes from: its ASG light or its receiver lobe (not a test).

    .venv/bin/python benchmarks/mrp_asg_receiver_split.py [--receivers R]

On benchmarks/mrp_asg_accuracy.py's base configuration (a 4 x 4 m rectangle of GGX α 0.05, a point
light 2 m from its centre at σ 30°, receivers 1 m away seeing its peak) for receiver GGX α from
0.05 to 0.35 (MRP-ASG's range), three sums over the receivers, each over the quadrature of Eq. 3
(reference.mrp_asg.brute_force_rectangle, exact GGX at both ends):

1. MRP-ASG (reference.mrp_asg.mrp_shade, ASG mode, the frame's disk rule);
2. MRP-ASG's own ASG light (001 Eqs. 18, 28-35: its frame, bandwidths and amplitude) integrated
   against the receiver's exact GGX BRDF times cosine on an 801² tangent-plane grid: the error of the
   light's shape alone;
3. the ASG's integral over the sphere against C = A E L_y (the energy it carries; 1 by Eq. 34).

1 / 2 is then what the receiver's SG lobe (Eqs. 6, 8), its factor M and the SG x ASG convolution
(Eq. 11) add. Writes benchmarks/results/mrp_asg_receiver_split.md.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "benchmarks"):
    sys.path.insert(0, str(folder))

import mrp_asg_accuracy as accuracy  # noqa: E402
from vsgl_addon.reference import ggx, mrp_asg as mrp  # noqa: E402
from vsgl_addon.reference.asg import asg_evaluate  # noqa: E402
from vsgl_addon.reference.numerics import dot, f64  # noqa: E402

ALPHAS = (0.05, 0.09, 0.15, 0.2, 0.35)


def asg_light(x, rect, light, disk_radius):
    """MRP-ASG's ASG light at receiver x (mrp_shade's steps 1-5): m, n, z, λ, µ, amplitude, C."""
    n_r = f64(rect["normal"])
    peak, _ = mrp.mrp_peak_local(x, rect["center"], n_r, light.position)
    irradiance, incoming, light_distance = mrp.light_irradiance_at(light, peak)
    cos_sigma = float(np.clip(dot(incoming, n_r), 0.0, 1.0))
    radiance = mrp.mrp_peak_radiance(cos_sigma, rect["roughness"], rect["f0"], irradiance)
    m, n, z, distance, cos_n = mrp.mrp_asg_frame(x, peak, n_r)
    spread = 1.0 + distance / light_distance
    extent = max(disk_radius / distance,
                 mrp.DISK_LOBE_SCALE * float(mrp.mrp_lobe_extent(cos_sigma, rect["roughness"], spread)))
    total = (mrp.mrp_area_ratio(peak, rect["center"], rect["axis_u"], rect["axis_v"], rect["half_u"],
                                rect["half_v"], extent * distance)
             * mrp.mrp_disk_integral(cos_sigma, rect["roughness"], extent, spread) * radiance)
    bandwidth_m, bandwidth_n = mrp.mrp_bandwidth(extent), mrp.mrp_bandwidth(extent * abs(float(cos_n)))
    amplitude = math.sqrt(bandwidth_m) * math.sqrt(bandwidth_n) / math.pi * total
    return m, n, z, bandwidth_m, bandwidth_n, amplitude, float(total)


def tangent_grid(z, m, n, half=0.6, size=801):
    """Unit directions around z and their solid angles (a tangent-plane grid at distance 1)."""
    t = np.linspace(-half, half, size)
    a, b = np.meshgrid(t, t, indexing="ij")
    w = z + a[..., None] * m + b[..., None] * n
    length = np.linalg.norm(w, axis=-1)
    return w / length[..., None], (t[1] - t[0]) ** 2 / length ** 3


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--receivers", type=int, default=16)
    args = parser.parse_args(argv)
    lines = ["# MRP-ASG on sharp receivers: the ASG light against the receiver lobe", "",
             f"`.venv/bin/python benchmarks/mrp_asg_receiver_split.py --receivers {args.receivers}` (the module's "
             "documentation). Sums over the receivers, each over the quadrature of Eq. 3.", "",
             "| receiver α | MRP-ASG / truth | ASG light × exact GGX receiver / truth | receiver lobe's factor (1 / 2) | ASG integral / C |",
             "|---|---|---|---|---|"]
    for alpha_x in ALPHAS:
        c = {**accuracy.BASE, "alpha_x": alpha_x}
        rect, light, p, n, o, radius, _ = accuracy.configuration(**c, receivers=args.receivers)
        truth = got = exact = 0.0
        energy = []
        for i in range(len(p)):
            truth += mrp.brute_force_rectangle(p[i], n[i], o[i], alpha_x, accuracy.F0, rect, light)
            got += float(mrp.mrp_shade(p[i], n[i], o[i], alpha_x, accuracy.F0, rect, light, radius))
            m, t, z, bm, bn, amplitude, total = asg_light(p[i], rect, light, radius)
            w, solid_angle = tangent_grid(z, m, t)
            light_values = amplitude * asg_evaluate(w, m, t, z, bm, bn)
            brdf = ggx.microfacet_brdf(w, np.broadcast_to(o[i], w.shape), np.broadcast_to(n[i], w.shape), alpha_x,
                                       accuracy.F0)
            cosine = np.maximum(dot(w, np.broadcast_to(n[i], w.shape)), 0.0)
            exact += float(np.sum(light_values * brdf * cosine * solid_angle))
            energy.append(float(np.sum(light_values * solid_angle)) / total)
        lines.append(f"| {alpha_x:g} | {got / truth:.3f} | {exact / truth:.3f} | {got / exact:.3f} | {np.mean(energy):.3f} |")
        print(lines[-1], flush=True)
    (REPO / "benchmarks" / "results" / "mrp_asg_receiver_split.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
