# SPDX-License-Identifier: GPL-3.0-or-later
"""Where the indirect light of a scene goes (not a test): Cycles against brute-force VPLs from the
very RSM texels the GPU uses, against the VSGL model, against the GPU, on a pixel subset.

    .venv/bin/python benchmarks/energy_budget.py [--only NAME ...] [--stride S] [--samples K] [--counts N ...]
        [--results-dir DIR]

On every S-th pixel (both ways) of the suite's 240x180 camera G-buffer, the mean luminance of each
stage's indirect light over those pixels, as a ratio to Cycles' on the same pixels:

* direct: our direct light against Cycles' direct light (the lights' emission model at the surfaces
  the camera sees; the RSM's texels carry the same model);
* VPL exact, visible: every RSM texel (every view of every light, the GPU's read back) a VPL with
  its exact lobes, Φ Rd/π ⟨ω, n⟩ and Φ Rs · GGX(F = 1, α)(ω', ω) ⟨ω, n⟩ / E(μ') (the normalized GGX
  lobe carrying the RSM's Φ·Rs), the receiver's exact Lambert + GGX BRDF (the G-buffer's Rd, F0,
  α), exact visibility: the segments to K VPLs per pixel drawn ∝ their unshadowed light are
  ray-cast against every triangle (Möller–Trumbore), the visible share of the unshadowed sum
  estimated from them (its standard error printed). Cycles against this: what the RSM loses
  (resolution, light model, clipped or missing surfaces, the Principled layering) and the
  point-VPL near field;
* VPL exact, no visibility: the same, every VPL seen (the unshadowed sum is exact, not sampled);
* VPL SG lobes, no visibility: the VPLs' lobes replaced by 000 Eqs. 6-7 (the SGs the VSGLs are
  built from): the lobe fit alone; the diffuse SG as 000 prints it (normalized over the sphere)
  and normalized over the hemisphere (reference/sg.py DIFFUSE_HEMISPHERE_SCALE, what the VSGLs
  carry);
* VSGL ref, no visibility: the GPU's VSGL table (N = the scene's) shaded by the float64 reference
  (reference/vsgl_shading.shade): the lobe fit, clustering into Gaussians (000 app. B) and the
  shading approximations, with the separable diffuse (000 Eqs. 10-11, the default of the
  modified and original kernels), with 000 app. C's diffuse of Eq. 12's SG (cosine pulled out of
  the integral) and with that SG's clamped-cosine integral (Tokuyoshi et al. 2024); also at
  larger N (--counts);
* GPU off / on: the GPU's shading pass on the same VSGLs without and with visibility, in the
  scene's diffuse mode (reference/vsgl_shading.diffuse_mode_for_kernel).

Writes ``benchmarks/results/energy_budget.md``. The near-field share: the part of the exact unshadowed VPL sum from VPLs nearer the receiver than
two texel footprints (sqrt of the texel's area on its surface), where a point VPL is a poor model of
its texel (1/d² of a point against the integral over its area).
"""

from __future__ import annotations

import argparse
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
from vsgl_addon.reference.sg import DIFFUSE_HEMISPHERE_SCALE  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
# Ends of a shadow segment nearer than this to either end point are not occluders (both lie on
# surfaces: the receiver's and the VPL's own triangles).
SEGMENT_END_OFFSET = 2e-3


def segments_blocked(starts, ends, triangles, chunk_rays=8192, chunk_triangles=64, t_min=None, t_max=None):
    """(R,) True where a triangle crosses the segment start→end (Möller–Trumbore) at a parameter in
    (t_min, t_max) (per segment, of its length; by default hits within SEGMENT_END_OFFSET of either
    end are left out)."""
    d = ends - starts
    length = np.linalg.norm(d, axis=-1)
    if t_min is None:
        t_min = SEGMENT_END_OFFSET / np.maximum(length, 1e-30)
    if t_max is None:
        t_max = 1.0 - SEGMENT_END_OFFSET / np.maximum(length, 1e-30)
    blocked = np.zeros(len(starts), bool)
    v0, e1, e2 = triangles[:, 0], triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    for r0 in range(0, len(starts), chunk_rays):
        o, dd = starts[r0:r0 + chunk_rays], d[r0:r0 + chunk_rays]
        lo, hi = t_min[r0:r0 + chunk_rays, None], t_max[r0:r0 + chunk_rays, None]
        hit_any = np.zeros(len(o), bool)
        for t0 in range(0, len(v0), chunk_triangles):
            a0, a1, a2 = v0[t0:t0 + chunk_triangles], e1[t0:t0 + chunk_triangles], e2[t0:t0 + chunk_triangles]
            p = np.cross(dd[:, None, :], a2[None])
            det = np.einsum("rtk,tk->rt", p, a1)
            inv = 1.0 / np.where(np.abs(det) > 1e-14, det, np.inf)
            s = o[:, None, :] - a0[None]
            u = np.einsum("rtk,rtk->rt", s, p) * inv
            q = np.cross(s, a1[None])
            v = np.einsum("rk,rtk->rt", dd, q) * inv
            t = np.einsum("rtk,tk->rt", q, a2) * inv
            hit_any |= ((u >= 0) & (v >= 0) & (u + v <= 1) & (t > lo) & (t < hi)).any(axis=1)
        blocked[r0:r0 + chunk_rays] = hit_any
    return blocked


def view_vpls(view_arrays, light) -> dict:
    """Every covered, lit texel of one RSM view (its ``to_numpy()``) as a VPL: dict of flat arrays,
    with each one's flat texel index row · W + column (``texel``)."""
    from vsgl_addon.reference.principled import principled_alpha, principled_directional_albedos
    from vsgl_addon.reference.rsm import incoming_directions

    a = view_arrays
    keep = a.coverage & (a.flux_white > 0.0)
    y = a.rsm.position[keep]
    n = a.rsm.normal[keep]
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
    flux = a.flux[keep]
    safe = np.where(flux > 0.0, flux, 1.0)
    rd = np.where(flux > 0.0, a.rsm.flux_diffuse[keep] / safe, 0.0)
    rs = np.where(flux > 0.0, a.rsm.flux_specular[keep] / safe, 0.0)
    w = incoming_directions(light, y)
    mu = np.clip(np.einsum("ij,ij->i", w, n), 1e-4, 1.0)
    if light.type == "SUN":
        area = a.texel_measure[keep] / mu
    else:
        area = a.texel_measure[keep] * np.sum((np.asarray(light.position) - y) ** 2, axis=-1) / mu
    roughness = a.roughness[keep]
    e_white = principled_directional_albedos(mu, roughness, 0.04, 0.0, samples=16)[0]
    return {"position": y, "normal": n, "flux": flux, "rd": rd, "rs": rs, "incoming": w,
            "alpha": np.maximum(principled_alpha(roughness), 1e-3), "e_white": np.maximum(e_white, 1e-6),
            "footprint": np.sqrt(area), "texel": np.flatnonzero(keep.reshape(-1))}


def rsm_vpls(scene_gpu, size):
    """Every covered texel of every RSM view as a VPL: dict of flat float64 arrays."""
    from vsgl_addon.passes.rsm import render_rsm_views

    parts = []
    for index in range(len(scene_gpu.scene.lights)):
        for view in render_rsm_views(scene_gpu, index, size):
            a = view.to_numpy()
            light = view.light
            view.free()
            part = view_vpls(a, light)
            del part["texel"]
            parts.append(part)
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def vpl_light(v, position, normal, view, rd, f0, alpha, lobes="exact"):
    """(P, M) luminance of each VPL's unshadowed light at each receiver, (P,) the near-field part and
    (P,) the part of the VPLs' diffuse lobes."""
    from vsgl_addon.reference.ggx import microfacet_brdf
    from vsgl_addon.reference.sg import diffuse_lobe_hemisphere, sg_evaluate, sg_integral, specular_lobe_warp
    from vsgl_addon.reference.vsgl_shading import _ggx_rgb

    if lobes == "sg":
        s_axis, s_sharp = specular_lobe_warp(v["incoming"], v["normal"], v["alpha"])
    out = np.zeros((len(position), len(v["flux"])))
    near = np.zeros(len(position))
    diffuse_part = np.zeros(len(position))
    for p in range(len(position)):
        r = v["position"] - position[p]
        d2 = np.einsum("ij,ij->i", r, r)
        ok = d2 > 1e-12
        dist = np.sqrt(np.where(ok, d2, 1.0))
        omega = r / dist[:, None]  # receiver → VPL
        out_dir = -omega
        cos_v = np.maximum(np.einsum("ij,ij->i", out_dir, v["normal"]), 0.0)
        if lobes == "exact":
            i_d = v["flux"] * v["rd"] / np.pi * cos_v[:, None]
            spec = microfacet_brdf(v["incoming"], out_dir, v["normal"], v["alpha"], 1.0) / v["e_white"]
            i_s = v["flux"] * v["rs"] * (spec * cos_v)[:, None]
        else:
            i_d = v["flux"] * v["rd"] * diffuse_lobe_hemisphere(out_dir, v["normal"])[:, None]
            i_s = v["flux"] * v["rs"] * (sg_evaluate(out_dir, s_axis, s_sharp) / sg_integral(s_sharp))[:, None]
        cos_p = np.maximum(omega @ normal[p], 0.0)
        irr = (i_d + i_s) * (np.where(ok, cos_p / np.where(ok, d2, 1.0), 0.0))[:, None]
        brdf = rd[p] / np.pi + _ggx_rgb(omega, view[p], normal[p], alpha[p], f0[p])
        out[p] = (irr * brdf) @ LUMINANCE
        near[p] = out[p][dist < 2.0 * v["footprint"]].sum()
        diffuse_part[p] = ((i_d * (np.where(ok, cos_p / np.where(ok, d2, 1.0), 0.0))[:, None] * brdf) @ LUMINANCE).sum()
    return out, near, diffuse_part


def visible_share(contrib, v, position, triangles, samples, rng):
    """(P,) estimated visible share of each receiver's unshadowed VPL light and (P,) its standard
    error: K VPLs drawn ∝ contribution, their segments ray-cast."""
    share = np.ones(len(position))
    error = np.zeros(len(position))
    starts, ends, owner = [], [], []
    for p in range(len(position)):
        total = contrib[p].sum()
        if total <= 0.0:
            continue
        pick = rng.choice(len(contrib[p]), size=samples, p=contrib[p] / total)
        starts.append(np.broadcast_to(position[p], (samples, 3)))
        ends.append(v["position"][pick])
        owner.append(np.full(samples, p))
    if not owner:
        return share, error
    starts, ends, owner = np.concatenate(starts), np.concatenate(ends), np.concatenate(owner)
    visible = ~segments_blocked(starts, ends, triangles)
    for p in np.unique(owner):
        seen = visible[owner == p].astype(np.float64)
        share[p] = seen.mean()
        error[p] = seen.std() / np.sqrt(len(seen))
    return share, error


def budget(name, path, stride, samples, counts, seed=0):
    from vsgl_addon.pipeline import build_visibility
    from vsgl_addon.renderer import FrameRenderer
    from vsgl_addon.reference.vsgl_shading import diffuse_mode_for_kernel, shade

    width, height = RESOLUTION
    settings, truth, description = scene_with_truth(name, path, width, height)
    triangles = np.asarray(description.geometry.positions, np.float64)
    renderer = FrameRenderer()
    try:
        frame = renderer.render(description, settings.overridden(visibility=False), width, height)
    finally:
        renderer.free()
    bench = Bench(description, width, height)
    figures = {}
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride)
        cycles = float((truth["indirect"][pick] @ LUMINANCE).sum())
        figures["direct"] = float((frame.direct[pick] @ LUMINANCE).sum() / (truth["direct"][pick] @ LUMINANCE).sum())
        figures["frame_off"] = float((frame.indirect[pick] @ LUMINANCE).sum() / cycles)

        start = time.perf_counter()
        vpls = rsm_vpls(bench.scene_gpu, settings.rsm_size)
        exact, near, _ = vpl_light(vpls, position, normal, view, rd, f0, alpha, "exact")
        sg, _, sg_diffuse = vpl_light(vpls, position, normal, view, rd, f0, alpha, "sg")
        share, error = visible_share(exact, vpls, position, triangles, samples, np.random.default_rng(seed))
        per_pixel = exact.sum(axis=1)
        figures["vpls"] = len(vpls["flux"])
        figures["vpl_exact_visible"] = float((per_pixel * share).sum() / cycles)
        figures["vpl_exact_visible_se"] = float(np.sqrt(((per_pixel * error) ** 2).sum()) / cycles)
        figures["vpl_exact"] = float(per_pixel.sum() / cycles)
        figures["vpl_near_share"] = float(near.sum() / per_pixel.sum())
        figures["vpl_sg"] = float(sg.sum() / cycles)
        figures["vpl_sg_sphere"] = float((sg.sum() - sg_diffuse.sum() * (1.0 - 1.0 / DIFFUSE_HEMISPHERE_SCALE)) / cycles)
        figures["vpl_seconds"] = time.perf_counter() - start

        mode = diffuse_mode_for_kernel(settings.kernel)
        # The scene's own N always, since the GPU and frame columns are taken at it.
        for count in dict.fromkeys([*counts, settings.vsgl_count]):
            vsgls, _ = bench.vsgls(settings.overridden(vsgl_count=count, visibility=False))
            try:
                for ref_mode, key in (("separable", "vsgl_ref_separable"), ("cosine", "vsgl_ref"),
                                      ("clamped-cosine", "vsgl_ref_clamped")):
                    ref = np.zeros(len(position))
                    for _, _, generation in vsgls.generations:
                        table = {k: np.asarray(v, np.float64) for k, v in generation.read_table().items()}
                        d, s = shade(table, position, normal, view, rd, f0, alpha, diffuse_mode=ref_mode)
                        ref += (d + s) @ LUMINANCE
                    figures[f"{key}_{count}"] = float(ref.sum() / cycles)
                if count == settings.vsgl_count:
                    d, s, _ = bench.shade(vsgls.tables(), mode)
                    figures["gpu_off"] = float(((d + s)[pick] @ LUMINANCE).sum() / cycles)
                    build_visibility(bench.scene_gpu, vsgls, settings)
                    d, s, _ = bench.shade(vsgls.tables(), mode)
                    figures["gpu_on"] = float(((d + s)[pick] @ LUMINANCE).sum() / cycles)
            finally:
                vsgls.free()
    finally:
        bench.free()
    figures["pixels"] = int(pick.sum())
    figures["vsgl_count"] = settings.vsgl_count
    log(f"{name}: " + ", ".join(f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}" for k, v in figures.items()))
    return figures


def markdown(rows):
    lines = ["| scene | pixels | direct ours/Cycles | VPL exact, visible | VPL exact, no vis. | near-field share | "
             "VPL SG lobes (Eq. 6 sphere-normalized), no vis. | VPL SG lobes (hemisphere), no vis. | "
             "VSGL ref, separable, no vis. | VSGL ref, Eq. 12 cosine pulled out, no vis. | "
             "VSGL ref, Eq. 12 clamped cosine, no vis. | GPU off | GPU on | frame off |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, f in rows.items():
        def at_counts(prefix):
            return ", ".join(f"{f[k]:.3f} (N = {k.rsplit('_', 1)[1]})" for k in f
                             if k.startswith(prefix) and k.rsplit("_", 1)[1].isdigit())

        refs = ", ".join(f"{f[k]:.3f} (N = {k.rsplit('_', 1)[1]})" for k in f
                         if k.startswith("vsgl_ref_") and k.rsplit("_", 1)[0] == "vsgl_ref")
        separable, clamped = at_counts("vsgl_ref_separable_"), at_counts("vsgl_ref_clamped_")
        lines.append(f"| {name} | {f['pixels']} | {f['direct']:.3f} | {f['vpl_exact_visible']:.3f} ± "
                     f"{f['vpl_exact_visible_se']:.3f} | {f['vpl_exact']:.3f} | {f['vpl_near_share']:.3f} | "
                     f"{f['vpl_sg_sphere']:.3f} | {f['vpl_sg']:.3f} | {separable} | {refs} | {clamped} | {f['gpu_off']:.3f} | {f['gpu_on']:.3f} | {f['frame_off']:.3f} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["closed_room", "cornell_box"])
    parser.add_argument("--stride", type=int, default=8)
    parser.add_argument("--samples", type=int, default=256, help="ray-cast VPLs per pixel")
    parser.add_argument("--counts", type=int, nargs="+", default=[256, 1024])
    parser.add_argument("--results-dir", type=Path, default=REPO / "benchmarks" / "results")
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    rows = {}
    for name, path, _ in suite():
        if name in args.only:
            start = time.perf_counter()
            rows[name] = budget(name, path, args.stride, args.samples, args.counts)
            log(f"  ({time.perf_counter() - start:.0f} s)")
    text = (f"# Energy budget of the indirect light\n\n`.venv/bin/python benchmarks/energy_budget.py --only "
            f"{' '.join(args.only)} --stride {args.stride} --samples {args.samples} --counts "
            f"{' '.join(map(str, args.counts))}`: mean indirect luminance over the pixel subset, each stage / "
            "Cycles (the module documentation defines the stages).\n\n" + markdown(rows))
    args.results_dir.mkdir(parents=True, exist_ok=True)
    (args.results_dir / "energy_budget.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
