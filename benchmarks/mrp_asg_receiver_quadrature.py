# SPDX-License-Identifier: GPL-3.0-or-later
"""MRP-ASG's receiver: 001's Eq. 8 + Eq. 11 against the exact GGX receiver, per served pixel (not a test).

    .venv/bin/python benchmarks/mrp_asg_receiver_quadrature.py [--only NAME ...]

On the pixels MRP-ASG serves (the frame's own, 240x180, visibility off as in path_partition.py's
stages) of the demo's gold sphere (every 2nd pixel) and the occluded reflector (every 6th), for every
light and lit proxy (green channel), the ASG light of reference.mrp_asg.mrp_asg_light integrated
against the receiver:

* "exact": the receiver's exact GGX BRDF on a dense tangent-plane grid (path_partition.py's
  ``_asg_exact_receiver``, 601² points), the truth of this table;
* "Eq. 11 (the pass)": Eq. 8's NDF as two SGs, Eq. 11, M and the cosine pulled out (``receiver="sg"``);
* "003 ASG receiver": ``receiver="asg"`` (``mrp_convolve_asg_receiver``);
* "quadrature L/R×S": ``mrp_receiver_quadrature`` with L × L Gauss–Hermite nodes on the light and
  R rings × S sectors on the GGX lobe (4/3×4 is its default).

Per scene: the sum over pixels against exact's, and the relative RMSE against exact over the pixels
above 1e-3 of the brightest. Frames against Cycles with the pass's receiver switched to the
quadrature: benchmarks/results/mrp_asg_suite_quadrature_receiver.md (benchmarks/mrp_asg_suite.py at
the commit that made that switch, reverted after it). Writes
benchmarks/results/mrp_asg_receiver_quadrature.{md,json} and prints the markdown.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from path_partition import _asg_exact_receiver, served_pixels  # noqa: E402
from tradeoff.demo import RESULTS_DIR, log  # noqa: E402
from validation_suite import suite  # noqa: E402

SCENES = {"demo": (2, ["Glossy gold"]), "occluded_reflector": (6, None)}
RULES = ((3, 3, 4), (4, 3, 4), (4, 4, 8), (6, 3, 4))
GRID = 601


def measure(name, path, stride, materials) -> dict:
    from vsgl_addon.reference import mrp_asg as mrp

    with served_pixels(name, path, stride, materials) as px:
        settings, description, lights = px.settings, px.description, px.lights
        position, normal, view, f0, alpha = px.position, px.normal, px.view, px.f0, px.alpha
        served = np.flatnonzero(px.served)
        labels = ["exact", "Eq. 11 (the pass)", "003 ASG receiver"] + [f"quadrature {l}/{r}×{s}" for l, r, s in RULES]
        values = {label: np.zeros(len(served)) for label in labels}
        start = time.perf_counter()
        for row, i in enumerate(served):
            for index, light in enumerate(description.lights):
                scale = float(light.color[1]) * float(light.specular_factor)
                for proxy, mask in lights.proxies:
                    if not mask[index]:
                        continue
                    rect = proxy.as_rect(1)
                    a = mrp.mrp_asg_light(position[i], rect, light, settings.disk_radius)
                    if not bool(a["valid"]):
                        continue
                    shade = dict(position=position[i], normal=normal[i], view=view[i], roughness=alpha[i],
                                 f0=f0[i, 1], rect=rect, light=light, disk_radius=settings.disk_radius)
                    values["exact"][row] += scale * _asg_exact_receiver(a, position[i], normal[i], view[i], alpha[i],
                                                                        f0[i, 1], size=GRID)
                    values["Eq. 11 (the pass)"][row] += scale * float(mrp.mrp_shade(**shade, receiver="sg"))
                    values["003 ASG receiver"][row] += scale * float(mrp.mrp_shade(**shade, receiver="asg"))
                    args = (view[i], normal[i], alpha[i], f0[i, 1], a["m"], a["n"], a["z"], a["bandwidth_m"],
                            a["bandwidth_n"], a["amplitude"])
                    for l, r, s in RULES:
                        values[f"quadrature {l}/{r}×{s}"][row] += scale * float(
                            mrp.mrp_receiver_quadrature(*args, light_nodes=l, rings=r, sectors=s))
            if row % 100 == 0:
                log(f"{name}: {row}/{len(served)} served pixels, {time.perf_counter() - start:.0f} s")
    exact = values["exact"]
    bright = exact > 1e-3 * max(float(exact.max()), 1e-30)
    cos_o = np.einsum("ij,ij->i", view[served], normal[served])
    out = {"scene": name, "stride": stride, "materials": materials, "served": int(len(served)),
           "compared": int(bright.sum()), "cos_o_percentiles_10_50_90": np.percentile(cos_o, [10, 50, 90]).tolist(),
           "rows": {}}
    for label, v in values.items():
        error = v[bright] - exact[bright]
        out["rows"][label] = {"sum_over_exact": float(v[bright].sum() / max(exact[bright].sum(), 1e-30)),
                              "rel_rmse": float(np.sqrt(np.mean(error ** 2)) / max(float(exact[bright].mean()), 1e-30))}
    return out


def markdown(results, command) -> str:
    lines = ["# MRP-ASG's receiver against the exact GGX receiver, per served pixel", "",
             f"`{command}`: the ASG light of each served pixel (green channel, every light and lit proxy) "
             "integrated against the receiver's exact GGX BRDF on a dense grid (\"exact\", the truth here) "
             "and by each receiver model; sum over the pixels against exact's, and relative RMSE against exact.", ""]
    for r in results:
        lines += [f"## {r['scene']}", "",
                  f"{r['compared']} of {r['served']} served pixels (every {r['stride']}th"
                  + (f", {', '.join(r['materials'])}" if r["materials"] else "") + ") above 1e-3 of the brightest; "
                  f"view cosines o·n 10th / 50th / 90th percentile "
                  + " / ".join(f"{c:.2f}" for c in r["cos_o_percentiles_10_50_90"]) + ".", "",
                  "| receiver | sum / exact | rel. RMSE against exact |", "|---|---|---|"]
        for label, row in r["rows"].items():
            if label != "exact":
                lines.append(f"| {label} | {row['sum_over_exact']:.3f} | {row['rel_rmse']:.3f} |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=sorted(SCENES))
    args = parser.parse_args(argv)
    ensure_gpu_context()
    register()
    paths = {name: path for name, path, _ in suite()}
    results = [measure(name, paths[name], *SCENES[name]) for name in (args.only or SCENES)]
    command = ".venv/bin/python benchmarks/mrp_asg_receiver_quadrature.py" + (
        f" --only {' '.join(args.only)}" if args.only else "")
    text = markdown(results, command)
    (RESULTS_DIR / "mrp_asg_receiver_quadrature.json").write_text(json.dumps(results, indent=1), encoding="utf-8")
    (RESULTS_DIR / "mrp_asg_receiver_quadrature.md").write_text(text, encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
