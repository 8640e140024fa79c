# SPDX-License-Identifier: GPL-3.0-or-later
"""MRP-ASG's accuracy against quadrature of 001 Eq. 3 (float64, no GPU; not a test).

    .venv/bin/python benchmarks/mrp_asg_accuracy.py

One rectangle (4 × 4 m, GGX metal F0 0.9), one point light, receivers (GGX F0 0.9) that see the
rectangle's specular peak: the truth is vsgl_addon.reference.mrp_asg.brute_force_rectangle (exact
GGX at both ends). Around a base configuration (reflector α 0.05, receiver α 0.2, light angle σ 30°,
receiver 1 m from the peak, disk radius 0.1 m) one parameter at a time is varied; per row, over 16
receivers (positions within ±10 % of the distance, views within ±3° of the mirror direction), the
relative RMSE of

* MRP-ASG (001 Eqs. 6–36 with Blender's units, the energy-matched k and the local-light spread,
  reference.mrp_asg docs), ASG mode with the pass's receiver (001's Eq. 8 NDF as two SGs, Eq. 11)
  and with the ASG light against the exact GGX receiver by quadrature
  (reference.mrp_asg.mrp_receiver_quadrature), and SG mode (Eq. 37);
* VSGLs: the rectangle as a 64² RSM of VPLs (texel flux = irradiance × area, Rs = F0, its GGX α),
  256 VSGLs (000, the modified kernel), shaded by reference.vsgl_shading (its specular term).

Also the two evidence tables of docs/accuracy.md: the radiance at the peak in Blender's units
against 001 Eq. 17, and the energy-matched k against Eq. 25's, both by quadrature of the total
reflected radiance C (Eq. 13).

Writes benchmarks/results/mrp_asg_accuracy.md and prints it.
"""

from __future__ import annotations

import math
import sys
import types
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from vsgl_addon.reference import mrp_asg as mrp  # noqa: E402
from vsgl_addon.reference import vsgl, vsgl_shading  # noqa: E402

RESULTS = REPO / "benchmarks" / "results" / "mrp_asg_accuracy.md"
BASE = dict(alpha_r=0.05, alpha_x=0.2, sigma=30.0, distance=1.0, radius=0.1)
SWEEPS = {
    "alpha_r": (0.02, 0.05, 0.1, 0.2, 0.5),
    "alpha_x": (0.05, 0.2, 0.5, 0.8),
    "sigma": (0.0, 30.0, 60.0, 80.0),
    "distance": (0.3, 1.0, 3.0),
    "radius": (0.01, 0.03, 0.1, 0.3, 1.0),
}
LIGHT_DISTANCE = 2.0
F0 = 0.9
RSM_SIZE = 64
VSGL_COUNT = 256


def unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def point_light(position, power=1000.0):
    return types.SimpleNamespace(type="POINT", position=np.asarray(position, float), direction=np.array([0, 0, -1.0]),
                                 power=power, matrix_world=np.eye(4), spot_size=0.0, spot_blend=0.0)


def configuration(alpha_r, alpha_x, sigma, distance, radius, receivers=16, seed=0):
    """The rectangle, the light and receivers that see its peak near the rectangle's centre."""
    s = math.radians(sigma)
    rect = dict(center=np.zeros(3), normal=np.array([0, 0, 1.0]), axis_u=np.array([1.0, 0, 0]),
                axis_v=np.array([0, 1.0, 0]), half_u=2.0, half_v=2.0, roughness=alpha_r, f0=F0)
    light = point_light(LIGHT_DISTANCE * np.array([-math.sin(s), 0.0, math.cos(s)]))
    mirror = np.array([math.sin(s), 0.0, math.cos(s)])
    rng = np.random.default_rng(seed)
    positions, normals, views = [], [], []
    for _ in range(receivers):
        p = distance * mirror + rng.uniform(-0.1, 0.1, 3) * distance
        p[2] = max(p[2], 0.02 * distance)
        peak, _ = mrp.mrp_peak_local(p, rect["center"], rect["normal"], light.position)
        w = unit(peak - p)
        n = unit(w + unit([0.3, 0.2, 0.5]) * 0.6)  # a receiver tilted towards the peak
        o = 2.0 * (w @ n) * n - w
        o = unit(o + rng.normal(size=3) * math.radians(3.0))
        if o @ n <= 0.05:
            o = unit(o + n * 0.2)
        positions.append(p)
        normals.append(n)
        views.append(o)
    return rect, light, np.array(positions), np.array(normals), np.array(views), radius, alpha_x


def rectangle_vsgls(rect, light, seed=0):
    """The rectangle as an RSM of RSM_SIZE² VPLs, and its VSGLs."""
    t = (np.arange(RSM_SIZE) + 0.5) / RSM_SIZE * 2.0 - 1.0
    y = (rect["center"] + t[:, None, None] * rect["half_u"] * rect["axis_u"]
         + t[None, :, None] * rect["half_v"] * rect["axis_v"])
    area = 4.0 * rect["half_u"] * rect["half_v"] / RSM_SIZE ** 2
    irradiance, incoming, _ = mrp.light_irradiance_at(light, y)
    cos = np.maximum(np.einsum("ijk,k->ij", incoming, rect["normal"]), 0.0)
    flux = (irradiance * cos * area)[..., None] * np.ones(3)
    normal = np.broadcast_to(rect["normal"], y.shape)
    vpls = vsgl_shading.VPLs(position=y, normal=normal, flux=flux, diffuse_reflectance=np.zeros_like(y),
                             specular_f0=np.full_like(y, F0), roughness=np.full(y.shape[:2], rect["roughness"]),
                             incoming=incoming)
    return vsgl.generate_vsgls(vpls.rsm(), VSGL_COUNT, seed=seed)


def rel_rmse(values, truth):
    return float(np.sqrt(np.mean((values - truth) ** 2)) / np.mean(truth))


def row(alpha_r, alpha_x, sigma, distance, radius):
    rect, light, p, n, o, radius, alpha_x = configuration(alpha_r, alpha_x, sigma, distance, radius)
    truth = np.array([mrp.brute_force_rectangle(p[i], n[i], o[i], alpha_x, F0, rect, light) for i in range(len(p))])
    asg = mrp.mrp_shade(p, n, o, alpha_x, F0, rect, light, radius, "asg")
    exact = mrp.mrp_shade(p, n, o, alpha_x, F0, rect, light, radius, "asg", receiver="quadrature")
    sg = mrp.mrp_shade(p, n, o, alpha_x, F0, rect, light, radius, "sg")
    vsgls = rectangle_vsgls(rect, light)
    _, specular = vsgl_shading.shade(vsgls, p, n, o, np.zeros_like(p), np.full_like(p, F0), np.full(len(p), alpha_x))
    return (rel_rmse(asg, truth), rel_rmse(exact, truth), rel_rmse(sg, truth), rel_rmse(specular[:, 0], truth),
            float(np.mean(truth)))


def error_table():
    lines = ["| varied | reflector α | receiver α | σ (°) | distance (m) | r_d (m) | MRP-ASG | MRP-ASG, exact receiver "
             "| ASG→SG (Eq. 37) | VSGL (N = 256) | best |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, values in SWEEPS.items():
        for value in values:
            c = {**BASE, name: value}
            asg, exact, sg, vs, _ = row(**c)
            best = min((asg, "MRP-ASG"), (exact, "exact receiver"), (sg, "ASG→SG"), (vs, "VSGL"))[1]
            lines.append(f"| {name} | {c['alpha_r']:g} | {c['alpha_x']:g} | {c['sigma']:g} | {c['distance']:g} | "
                         f"{c['radius']:g} | {asg:.3f} | {exact:.3f} | {sg:.3f} | {vs:.3f} | {best} |")
    return "\n".join(lines)


def evidence_tables():
    lines = ["| light | α_r | receiver at | C by quadrature | A·E, L_y Blender's (ratio) | A·E, L_y 001 Eq. 17 (ratio) | "
             "A·E, Eq. 25's k (ratio) | A·E, energy k (ratio) |", "|---|---|---|---|---|---|---|---|"]
    for kind in ("POINT", "SPOT", "AREA", "SUN"):
        for alpha_r, x in ((0.02, (1.0, 0.0, 0.8)), (0.02, (2.0, 0.0, 0.3)), (0.1, (1.0, 0.0, 0.8))):
            light = _light(kind)
            rect = dict(center=np.zeros(3), normal=np.array([0, 0, 1.0]), axis_u=np.array([1.0, 0, 0]),
                        axis_v=np.array([0, 1.0, 0]), half_u=20.0, half_v=20.0, roughness=alpha_r, f0=F0)
            x = np.array(x)
            truth = mrp.brute_force_rectangle(x, np.array([0, 0, -1.0]), np.array([0, 0, 1.0]), 0.5, F0, rect, light,
                                              receiver_brdf=False)
            if kind == "SUN":
                peak, _ = mrp.mrp_peak_distant(x, rect["center"], rect["normal"], -light.direction)
            else:
                peak, _ = mrp.mrp_peak_local(x, rect["center"], rect["normal"], light.position)
            irradiance, incoming, light_distance = mrp.light_irradiance_at(light, peak)
            c = float(incoming @ rect["normal"])
            d = float(np.linalg.norm(peak - x))
            spread = 1.0 + d / light_distance
            y_blender = float(mrp.mrp_peak_radiance(c, alpha_r, F0, irradiance))
            y_paper = float(mrp.mrp_peak_radiance_paper(c, alpha_r, F0))
            e = {fit: float(mrp.mrp_disk_integral(c, alpha_r, 3.0 / d, spread, fit)) for fit in mrp.K_FITS}
            lines.append(f"| {kind.lower()} | {alpha_r:g} | {tuple(x)} (cos σ {c:.2f}) | {truth:.4g} | "
                         f"{e['energy'] * y_blender / truth:.3f} | {e['energy'] * y_paper / truth:.2e} | "
                         f"{e['paper'] * y_blender / truth:.3f} | {e['energy'] * y_blender / truth:.3f} |")
    return "\n".join(lines)


def _light(kind):
    position = np.array([-1.0, 0.2, 1.5])
    direction = unit(-position) if kind != "SUN" else unit([0.5, 0.0, -1.0])
    m = np.eye(4)
    z = -direction
    xa = unit(np.cross([0.0, 1.0, 0.0], z))
    m[:3, :3] = np.stack((xa, np.cross(z, xa), z), axis=1)
    return types.SimpleNamespace(type=kind, position=position, direction=direction, power=1000.0, matrix_world=m,
                                 spot_size=math.radians(120.0), spot_blend=0.2)


def main() -> int:
    text = ("## MRP-ASG error table (relative RMSE over 16 receivers against quadrature of 001 Eq. 3)\n\n"
            + error_table() + "\n\n## Radiance at the peak and the disk integral's k (total C of Eq. 13, disk 3 m)\n\n"
            + evidence_tables() + "\n")
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
