# SPDX-License-Identifier: GPL-3.0-or-later
"""Where the VSGLs lose light against the SG-lobe VPLs of their own texels (not a test), per VSGL,
without visibility, on a pixel subset of the suite's camera G-buffer.

    .venv/bin/python benchmarks/vsgl_aggregation.py [--only NAME ...] [--stride S] [--count N] [--name STEM]

For every VSGL i of the scene's frame (its N, its kernels, the GPU's table), the texels of its
cluster and their weights c_ij: 000 Eq. 5's estimate is M F̄(x_i, l_i) / (N p̄(x_i, l_i)) with F̄
the trilinear filter of the moments, so c_ij = M w_ij(x_i, l_i) / (N p̄(x_i, l_i)) with w_ij the
trilinear weight of texel j (read from the GPU's own PDF mip chain; the reconstructed cluster
powers are checked against the table's). Then, at the receivers (the receivers' exact Lambert +
GGX BRDF in every stage but the last), the luminance of the light of the cluster's reflector
diffuse lobes as

* texels: Σ_j c_ij · the texel's own 000 Eq. 6 SG, hemisphere-normalized (energy_budget.py's "VPL
  SG lobes (hemisphere)"), at y_j — what the VSGL stands for;
* lobe: Σ_j c_ij Φ_j Rd_j · the VSGL's aggregated lobe (its ξ_v, λ_v, c_v / Σ ΦRd, 000 app. B.1) at
  y_j — the aggregation of the lobes alone; "lobe, front only": the same with each texel's lobe cut
  to its own front hemisphere (the part of "lobe" sent from directions behind a texel's surface is
  light the texels cannot give);
* point: the VSGL's diffuse lobe as a point light at its µ_v (far-field limit of 000 Eq. 12):
  the positions collapsed;
* VSGL: the reference's separable shading of the VSGL's diffuse lobe (vsgl_shading.shade, 000
  Eqs. 10-11, the default), receivers' BRDF as the GPU shades it (SG×ASG for the glossy lobe);
* what-if, split: the cluster's VSGL as two, its texels split in two groups by normal (2-means),
  each group's VSGL from its own c_ij-weighted moments (000 app. B.1-B.2), shaded as "VSGL"
  (twice the VSGLs); "one per plane": up to six, the texels binned by their normal's dominant axis
  and sign (the suite's rooms are axis-aligned): what clusters kept to one plane would give; its
  light split by receiver: where the receiver's plane passes within 2 σ_v of the plane VSGL's mean
  (the VSGL's isotropic Gaussian reaches behind the receiver's horizon) and elsewhere; "blocks d":
  the same six bins, each texel binned by the class of its 2^b-texel block's mean normal, b =
  max(⌊l⌋ − d, 0) (the mip texels d levels under the kernel's taps: what reference.vsgl's
  plane-split clusters read, d = PLANE_SPLIT_DEPTH);
* what-if, VSGL with its lobe normalized over the hemisphere around its own axis ξ_v: c_v scaled by
  (1 + e^-λv) / (1 + e^-λd), which is 1 for a flat cluster (λv = λd).

The sum over i of "texels" against every texel's lobe once ("all texels"): the kernels' coverage
(000 Eq. 5's overlaps and gaps). Splits: by the cluster's |ξ̄_v| against a flat cluster's 2/3
(corner clusters), by the light's VSGL count, by the receivers' distance to µ_v in σ_v.

Writes ``benchmarks/results/STEM.md`` and ``.json`` (STEM: vsgl_aggregation).
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

from validation_suite import sampled_pixels, scene_with_truth, suite  # noqa: E402
from build_validation_scenes import RESOLUTION  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.demo import log  # noqa: E402
from energy_budget import LUMINANCE, view_vpls  # noqa: E402
from vsgl_addon.reference.sg import DIFFUSE_HEMISPHERE_SCALE  # noqa: E402

FLAT_LENGTH = 2.0 / 3.0  # |ξ̄| of a flat cluster: λ_d/(λ_d + 1), λ_d = 2 (000 Eq. 6, app. B.1)
STAGES = ("texels", "lobe", "lobe_front", "point", "vsgl", "vsgl_axis_hemisphere", "vsgl_split", "vsgl_planes",
          "vsgl_blocks1", "vsgl_blocks2", "vsgl_blocks3")


def split_by_normal(normal, weight):
    """(M,) bool: two groups of texels by normal (2-means on the unit normals weighted by
    ``weight``, started from the mean normal's farthest texel)."""
    live = weight > 0.0
    mean = (weight[:, None] * normal).sum(axis=0)
    first = normal[np.argmin(np.where(live, normal @ mean, np.inf))]
    second = mean / max(np.linalg.norm(mean), 1e-30)
    group = np.zeros(len(normal), bool)
    for _ in range(8):
        group = normal @ first > normal @ second
        for g, target in ((True, "first"), (False, "second")):
            w = weight * (group == g)
            if w.sum() > 0.0:
                centre = (w[:, None] * normal).sum(axis=0)
                centre /= max(np.linalg.norm(centre), 1e-30)
                if target == "first":
                    first = centre
                else:
                    second = centre
    return group


def normal_class(normal):
    """Class 0-5 of each normal: its dominant axis and sign."""
    dominant = np.argmax(np.abs(normal), axis=-1)
    return 2 * dominant + (np.take_along_axis(normal, dominant[..., None], -1)[..., 0] < 0.0)


def block_bins(v, levels, size, depth):
    """(N, M) class of each texel for each VSGL: the class of the mean normal of its block at mip
    level max(⌊l⌋ − depth, 0) (the mip chain's children of the kernel's taps)."""
    w = (v["flux"] * v["rd"]) @ LUMINANCE
    row, col = np.divmod(np.asarray(v["texel"]), size)
    out = np.zeros((len(levels), len(w)), np.int64)
    cache = {}
    for i, l in enumerate(levels):
        b = max(int(np.floor(l)) - depth, 0)
        if b not in cache:
            key = (row >> b) * (size >> b) + (col >> b)
            sums = np.zeros(((size >> b) ** 2, 3))
            np.add.at(sums, key, w[:, None] * v["normal"])
            cache[b] = normal_class(sums[key])
        out[i] = cache[b]
    return out


def split_vsgls(v, c, table, planes=False, bins_per_vsgl=None):
    """What-if: each cluster's diffuse VSGL as two, its texels split by normal (split_by_normal),
    each part's VSGL from its own moments (000 app. B.1-B.2 on the part's c_ij-weighted texels);
    ``planes``: as six, the texels binned by their normal's dominant axis and sign."""
    from vsgl_addon.reference import vsgl as ref

    phi_rd = v["flux"] * v["rd"]
    w = ref.luminance(phi_rd)
    y, n = v["position"], v["normal"]
    moments = np.zeros((len(w), ref.MOMENT_CHANNELS))
    moments[:, ref.CH_DIFFUSE] = phi_rd
    moments[:, ref.CH_DIFFUSE_DIRECTION] = w[:, None] * FLAT_LENGTH * n
    moments[:, ref.CH_DIFFUSE_POSITION] = w[:, None] * y
    moments[:, ref.CH_DIFFUSE_POSITION_SQUARED] = w * np.einsum("ij,ij->i", y, y)
    parts = 6 if planes or bins_per_vsgl is not None else 2
    totals = np.zeros((len(c), parts, ref.MOMENT_CHANNELS))
    dominant = np.argmax(np.abs(n), axis=1)
    bins = 2 * dominant + (n[np.arange(len(n)), dominant] < 0.0)
    for i in range(len(c)):
        if bins_per_vsgl is not None:
            for b in range(6):
                totals[i, b] = (c[i] * (bins_per_vsgl[i] == b)) @ moments
        elif planes:
            for b in range(6):
                totals[i, b] = (c[i] * (bins == b)) @ moments
        else:
            group = split_by_normal(n, c[i] * w)
            totals[i, 0] = (c[i] * group) @ moments
            totals[i, 1] = (c[i] * ~group) @ moments
    mean = np.asarray(table["mean"]).reshape(-1, 3)
    variance = np.asarray(table["variance"]).reshape(-1)
    params = ref.vsgl_parameters(totals.reshape(-1, ref.MOMENT_CHANNELS), np.repeat(mean, parts, axis=0),
                                 np.repeat(variance, parts))
    return params



def cluster_weights(pdf_chain, center, level, vsgl_count_total, size):
    """(N, M) c_ij = M w_ij / (N p̄(x_i, l_i)) of 000 Eq. 5 (trilinear weights of the level-0 texels)."""
    from vsgl_addon.reference import mipmap

    m = size * size
    one_hot = np.eye(m).reshape(size, size, m)
    chain = mipmap.build_mip_chain(one_hot)
    weights = mipmap.trilinear(chain, center, level)
    denominator = vsgl_count_total * mipmap.trilinear(pdf_chain, center, level)
    return m * weights / np.maximum(denominator, 1e-300)[:, None]


def receiver_brdf_lum(omega, view, normal, rd, f0, alpha):
    """(P, M, 3) receivers' exact Lambert + GGX BRDF toward directions omega (P, M, 3)."""
    from vsgl_addon.reference.vsgl_shading import _ggx_rgb

    out = np.empty(omega.shape)
    for p in range(len(view)):
        out[p] = rd[p] / np.pi + _ggx_rgb(omega[p], view[p], normal[p], alpha[p], f0[p])
    return out


def view_stages(v, table, c, position, normal, view, rd, f0, alpha, size):
    """(N, P) luminance of each stage for each VSGL of one view."""
    from vsgl_addon.reference.sg import diffuse_lobe_hemisphere, sg_evaluate
    from vsgl_addon.reference.vsgl_shading import shade

    y, n = v["position"], v["normal"]
    phi_rd = v["flux"] * v["rd"]  # (M, 3)
    r = y[None] - position[:, None]  # receiver → texel
    d2 = np.einsum("pmk,pmk->pm", r, r)
    ok = d2 > 1e-12
    dist = np.sqrt(np.where(ok, d2, 1.0))
    omega = r / dist[..., None]
    cos_p = np.maximum(np.einsum("pmk,pk->pm", omega, normal), 0.0)
    geometry = np.where(ok, cos_p / np.where(ok, d2, 1.0), 0.0)  # (P, M)
    brdf = receiver_brdf_lum(omega, view, normal, rd, f0, alpha)  # (P, M, 3)
    out_dir = -omega
    own = diffuse_lobe_hemisphere(out_dir, n[None])  # (P, M)
    texel_light = ((phi_rd[None] * own[..., None] * brdf) @ LUMINANCE) * geometry  # (P, M)
    front = np.einsum("pmk,mk->pm", out_dir, n) > 0.0
    count = len(c)
    stages = {k: np.zeros((count, len(position))) for k in STAGES}
    stages["texels"] = c @ texel_light.T
    axis = np.asarray(table["diffuse_axis"]).reshape(-1, 3)
    sharp = np.asarray(table["diffuse_sharpness"]).reshape(-1)
    amp = np.asarray(table["diffuse_amplitude"]).reshape(-1, 3)
    mean = np.asarray(table["diffuse_mean"]).reshape(-1, 3)
    for i in range(count):
        w = c[i]
        power = (w[:, None] * phi_rd).sum(axis=0)  # Σ c ΦRd (3)
        if not np.any(power > 0.0):
            continue
        lobe = sg_evaluate(out_dir, axis[i], sharp[i])  # (P, M)
        # amplitude c_v per unit of the cluster's power: the texel's share of c_v.
        per_power = amp[i] / np.maximum(power, 1e-300)
        emitted = (w[:, None] * phi_rd)[None] * per_power * lobe[..., None]  # (P, M, 3)
        lit = ((emitted * brdf) @ LUMINANCE) * geometry
        stages["lobe"][i] = lit.sum(axis=1)
        stages["lobe_front"][i] = (lit * front).sum(axis=1)
        rp = mean[i][None] - position
        dp2 = np.einsum("pk,pk->p", rp, rp)
        wp = rp / np.sqrt(np.maximum(dp2, 1e-24))[:, None]
        cosp = np.maximum(np.einsum("pk,pk->p", wp, normal), 0.0)
        brdf_p = receiver_brdf_lum(wp[:, None], view, normal, rd, f0, alpha)[:, 0]
        ip = amp[i][None] * sg_evaluate(-wp, axis[i], sharp[i])[:, None]
        stages["point"][i] = ((ip * brdf_p) @ LUMINANCE) * cosp / np.maximum(dp2, 1e-24)
    diffuse_only = {k: np.asarray(table[k], np.float64) for k in table}
    diffuse_only["specular_amplitude"] = np.zeros_like(diffuse_only["specular_amplitude"])
    d, s, terms = shade(diffuse_only, position, normal, view, rd, f0, alpha, diffuse_mode="separable",
                        per_term=True)
    stages["vsgl"] = ((terms[:, :, 0, 0] + terms[:, :, 0, 1]) @ LUMINANCE).T
    # What-if: the aggregated lobe normalized over the hemisphere around its own axis, as each
    # texel's lobe is around its normal: (1 + e^-λv) in place of (1 + e^-λd), the same for a flat cluster.
    stages["vsgl_axis_hemisphere"] = stages["vsgl"] * ((1.0 + np.exp(-sharp)) / DIFFUSE_HEMISPHERE_SCALE)[:, None]
    split = split_vsgls(v, c, table)
    _, _, terms = shade(split, position, normal, view, rd, f0, alpha, diffuse_mode="separable", per_term=True)
    per_part = ((terms[:, :, 0, 0] + terms[:, :, 0, 1]) @ LUMINANCE).T  # (2N, P)
    stages["vsgl_split"] = per_part[0::2] + per_part[1::2]
    split = split_vsgls(v, c, table, planes=True)
    _, _, terms = shade(split, position, normal, view, rd, f0, alpha, diffuse_mode="separable", per_term=True)
    per_plane = ((terms[:, :, 0, 0] + terms[:, :, 0, 1]) @ LUMINANCE).T.reshape(len(c), 6, -1)  # (N, 6, P)
    stages["vsgl_planes"] = per_plane.sum(axis=1)
    levels = np.asarray(table["kernel_level"]).reshape(-1)
    for depth in (1, 2, 3):
        blocks = split_vsgls(v, c, table, bins_per_vsgl=block_bins(v, levels, size, depth))
        _, _, terms = shade(blocks, position, normal, view, rd, f0, alpha, diffuse_mode="separable", per_term=True)
        stages[f"vsgl_blocks{depth}"] = ((terms[:, :, 0, 0] + terms[:, :, 0, 1]) @ LUMINANCE).T.reshape(
            len(c), 6, -1).sum(axis=1)
    # The per-plane VSGLs' near field: receivers whose own plane passes within 2 σ_v of the plane
    # VSGL's mean (its isotropic Gaussian reaches behind the receiver's horizon) against the rest.
    dominant = np.argmax(np.abs(n), axis=1)
    bins = 2 * dominant + (n[np.arange(len(n)), dominant] < 0.0)
    plane_texels = np.stack([(c * (bins == b)) @ texel_light.T for b in range(6)], axis=1)  # (N, 6, P)
    plane_mean = np.asarray(split["diffuse_mean"]).reshape(len(c), 6, 3)
    plane_sigma = np.sqrt(np.asarray(split["diffuse_variance"]).reshape(len(c), 6))
    height = np.einsum("nbpk,pk->nbp", plane_mean[:, :, None] - position[None, None], normal)
    straddle = height < 2.0 * plane_sigma[..., None]
    for key, values in (("planes_texels", plane_texels), ("planes_vsgl", per_plane)):
        stages[key + "_straddle"] = (values * straddle).sum(axis=1)
        stages[key + "_clear"] = (values * ~straddle).sum(axis=1)
    dominant = np.argmax(np.abs(n), axis=1)
    bins = 2 * dominant + (n[np.arange(len(n)), dominant] < 0.0)
    w = (phi_rd @ LUMINANCE)
    per_bin = np.stack([(c * (bins == b)) @ w for b in range(6)], axis=1)  # (N, 6)
    planes = (per_bin > 0.02 * np.maximum(per_bin.sum(axis=1, keepdims=True), 1e-300)).sum(axis=1)
    return stages, texel_light.sum(axis=1), planes


def aggregation(name, path, stride, count=None):
    from vsgl_addon.reference.vsgl import luminance

    width, height = RESOLUTION
    settings, truth, description = scene_with_truth(name, path, width, height)
    bench = Bench(description, width, height)
    rows = []
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride)
        cycles = float((truth["indirect"][pick] @ LUMINANCE).sum())
        if count is not None:
            settings = settings.overridden(vsgl_count=count)
        vsgls, _ = bench.vsgls(settings.overridden(visibility=False))
        total_n = settings.vsgl_count
        per_light = {}
        for light_index, _, generation in vsgls.generations:
            per_light[light_index] = per_light.get(light_index, 0) + generation.vsgl_count
        all_texels = 0.0
        check = []
        try:
            for light_index, view_index, generation in vsgls.generations:
                rsm_view = vsgls.views_by_light[light_index][view_index]
                a = rsm_view.to_numpy()
                v = view_vpls(a, rsm_view.light)
                table = generation.read_table()
                _, pdf = generation.read_mip_chains()
                size = pdf[0].shape[0]
                count = generation.vsgl_count
                c_full = cluster_weights(pdf, np.asarray(table["kernel_center"]).reshape(-1, 2),
                                         np.asarray(table["kernel_level"]).reshape(-1), count, size)
                c = c_full[:, v["texel"]]
                rebuilt = luminance(c @ (v["flux"] * (v["rd"] + v["rs"])))
                check.append((rebuilt.sum(), luminance(np.asarray(table["power"]).reshape(-1, 3)).sum()))
                stages, every, planes = view_stages(v, table, c, position, normal, view, rd, f0, alpha, size)
                all_texels += float(every.sum())
                length = np.asarray(table["diffuse_sharpness"]).reshape(-1)
                length = length / (1.0 + length)
                mean = np.asarray(table["diffuse_mean"]).reshape(-1, 3)
                sigma = np.sqrt(np.asarray(table["diffuse_variance"]).reshape(-1))
                for i in range(count):
                    weight = stages["texels"][i]
                    dist = np.linalg.norm(mean[i][None] - position, axis=-1)
                    near = float((weight * (dist < 3.0 * sigma[i])).sum())
                    rows.append({"light": light_index, "view": view_index, "light_count": per_light[light_index],
                                 "length_ratio": float(length[i] / FLAT_LENGTH),
                                 "level": float(np.asarray(table["kernel_level"]).reshape(-1)[i]),
                                 "sigma": float(sigma[i]), "near_3sigma": near,
                                 "planes": int(planes[i]),
                                 **{k: float(stages[k][i].sum()) for k in stages}})
        finally:
            vsgls.free()
    finally:
        bench.free()
    return {"name": name, "cycles": cycles, "all_texels": all_texels, "vsgls": rows, "pixels": int(pick.sum()),
            "vsgl_count": total_n, "power_check": [float(sum(x for x, _ in check)), float(sum(y for _, y in check))]}


def summarize(result):
    rows = result["vsgls"]
    cyc = result["cycles"]
    total = {k: sum(r[k] for r in rows) for k in STAGES}
    lines = [f"## {result['name']} (N = {result['vsgl_count']}, {len(rows)} VSGLs, {result['pixels']} pixels)\n",
             f"All texels' SG lobes once / Cycles: {result['all_texels'] / cyc:.3f}; the clusters' texels "
             f"(Σ_i Σ_j c_ij): {total['texels'] / cyc:.3f} (coverage {total['texels'] / result['all_texels']:.3f}).\n",
             "| VSGLs | share of the clusters' light | texels | lobe / texels | lobe, front only / texels | "
             "point / texels | VSGL / texels | VSGL, lobe normalized over its axis' hemisphere / texels | split by normal (2 VSGLs) / texels | one per plane / texels | "
             "one per class of the mip blocks at ⌊l⌋−1 / ⌊l⌋−2 / ⌊l⌋−3 |||",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]

    def line(label, chosen):
        t = sum(r["texels"] for r in chosen)
        if t <= 0.0:
            return
        lines.append(f"| {label} ({len(chosen)}) | {t / total['texels']:.3f} | {t / cyc:.3f} | "
                     + " | ".join(f"{sum(r[k] for r in chosen) / t:.3f}" for k in STAGES[1:]) + " |")

    lines.insert(2, f"Planes per cluster (normal bins holding over 2 % of its diffuse power): mean "
                    f"{np.mean([r['planes'] for r in rows]):.2f}, weighted by the clusters' light "
                    f"{sum(r['planes'] * r['texels'] for r in rows) / max(total['texels'], 1e-300):.2f}.\n")
    line("all", rows)
    line("flat (|ξ̄| ≥ 0.97 of 2/3)", [r for r in rows if r["length_ratio"] >= 0.97])
    line("bent (0.85-0.97)", [r for r in rows if 0.85 <= r["length_ratio"] < 0.97])
    line("corner (< 0.85)", [r for r in rows if r["length_ratio"] < 0.85])
    for lo, hi in ((0, 4), (4, 8), (8, 16), (16, 10 ** 6)):
        line(f"light with {lo}-{hi - 1} VSGLs", [r for r in rows if lo <= r["light_count"] < hi])
    near = [r for r in rows if r["texels"] > 0 and r["near_3sigma"] / r["texels"] > 0.5]
    line("most light to receivers within 3 σ_v", near)
    line("most light to receivers beyond 3 σ_v", [r for r in rows if r not in near])
    for lo, hi in ((0, 1), (1, 2), (2, 3), (3, 6)):
        line(f"kernel level {lo}-{hi}", [r for r in rows if lo <= r["level"] < hi])
    near = {k: sum(r[k] for r in rows) for k in ("planes_texels_straddle", "planes_vsgl_straddle",
                                                   "planes_texels_clear", "planes_vsgl_clear")}
    lines.append(f"\nOne VSGL per plane, by receiver: where the receiver's plane passes within 2 σ_v of the plane "
                 f"VSGL's mean (share {near['planes_texels_straddle'] / total['texels']:.3f} of the texels' light) "
                 f"VSGL / texels {near['planes_vsgl_straddle'] / max(near['planes_texels_straddle'], 1e-300):.3f}; "
                 f"elsewhere {near['planes_vsgl_clear'] / max(near['planes_texels_clear'], 1e-300):.3f}.")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["many_lights"])
    parser.add_argument("--stride", type=int, default=12)
    parser.add_argument("--count", type=int, default=None, help="N (default: the scene's)")
    parser.add_argument("--name", default="vsgl_aggregation", help="results file stem")
    parser.add_argument("--results-dir", type=Path, default=REPO / "benchmarks" / "results")
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    results = []
    for name, path, _ in suite():
        if name in args.only:
            start = time.perf_counter()
            results.append(aggregation(name, path, args.stride, args.count))
            log(f"{name} ({time.perf_counter() - start:.0f} s): power check {results[-1]['power_check']}")
    text = (f"# VSGL aggregation against the clusters' own texels, no visibility\n\n`.venv/bin/python "
            f"benchmarks/vsgl_aggregation.py --only {' '.join(args.only)} --stride {args.stride}"
            + (f" --count {args.count} --name {args.name}" if args.count else "") + "`: the reflectors' "
            "diffuse lobes only; the stages are defined in the module documentation (ratios of summed "
            "luminance over the pixel subset).\n\n" + "\n".join(summarize(r) for r in results))
    args.results_dir.mkdir(parents=True, exist_ok=True)
    (args.results_dir / f"{args.name}.md").write_text(text)
    (args.results_dir / f"{args.name}.json").write_text(json.dumps(results, indent=1))
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
