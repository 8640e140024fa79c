# SPDX-License-Identifier: GPL-3.0-or-later
"""Is any one-bounce light path counted twice or dropped by the frame's techniques? (not a test)

    .venv/bin/python benchmarks/path_partition.py [--only NAME ...] [--stride S] [--results-dir DIR]

The path-partition check of ../shared/reference/light-paths.md on the frame the renderer builds
(renderer.SceneLights: with a rectangle proxy that is also a sharp reflector, three VSGL sets, the
glossy VPLs and MRP-ASG), visibility off (brute force has none; the light's own shadow at the
reflector is in the RSM either way), the VPL pass without its denoise filter, interleave 1 and
δ = 1e-6 (its smallest: nearly every VPL accepted, weight 1), 240x180, on every S-th pixel both ways:

1. texels: every RSM texel of each set read back against the whole RSM (the "all" set): the
   diffuse flux Φ Rd is in every set unchanged; the diffuse receivers' set keeps the specular flux
   Φ Rs of every texel but the sharp ones (GGX α < α_c), which the VPL table holds instead (matched
   texel by texel); the glossy receivers' set keeps every texel's Φ Rs but those on a kept proxy
   (tested in float64 against the proxies' rectangles), which MRP-ASG carries. Reported as the
   largest residual |set + its complement − whole| / max |whole| per identity.
2. cells: float64 brute force (every texel of the whole RSM a VPL: Φ Rd/π ⟨ω, n⟩ and
   Φ Rs f_GGX(ω', ω; F = 1) ⟨ω, n⟩, as 004's glossy VPLs shine; the receiver's exact Lambert and
   GGX) restricted to the table's cells (reflector diffuse / specular α ≥ α_c / sharp on a proxy /
   sharp elsewhere × receiver diffuse / specular), summed over the cells against the unrestricted
   brute force; and the same brute force of each technique's own input (each set's texels, the VPL
   table) so that the inputs' sum per receiver lobe, set by set as the frame composes them, can be
   compared with the whole: a path counted twice shows as a sum above 1, a dropped one below.
3. techniques: each pass's own image on the same pixels against the brute force of its cell(s):
   the diffuse receivers' VSGLs (diffuse image), the VPL pass (Indirect Caustics), the glossy
   receivers' VSGLs (specular image), MRP-ASG (Indirect Glossy Reflectors), the whole set's
   VSGLs, and the composed Indirect Diffuse / Indirect Specular against the whole brute force,
   as luminance ratios of the pixel sums, served (MRP-ASG's receiver range) and unserved pixels.

Writes ``path_partition.{md,json}`` in the results directory.

``--stages``: instead, MRP-ASG's own error on the pixels it serves, stage by stage (:func:`stages`),
written to ``mrp_asg_stages.{md,json}``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
for folder in (REPO, REPO / "tests", REPO / "benchmarks", REPO / "tools"):
    sys.path.insert(0, str(folder))

from build_validation_scenes import RESOLUTION  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.demo import RESULTS_DIR, log  # noqa: E402
from validation_suite import sampled_pixels, scene_with_truth, suite  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
SCENES = ("demo", "polished_metal_floor", "occluded_reflector")


def partition_settings(settings):
    """``settings`` for the check: no visibility, δ at its smallest, no VPL filter."""
    return settings.overridden(visibility=False, delta=1e-6, vpl_filter_radius=0, vpl_interleave="1",
                               vpl_samples=1)


def lum(image) -> float:
    return float(np.sum(np.asarray(image, np.float64)[..., :3] @ LUMINANCE))


def relative_residual(value, whole) -> float:
    scale = float(np.max(np.abs(whole))) if np.size(whole) else 0.0
    return float(np.max(np.abs(value - whole))) / scale if scale > 0.0 else float(np.max(np.abs(value - whole), initial=0.0))


def check(name, path, stride) -> dict:
    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.passes.vpl_culling import read_vpls
    from vsgl_addon.reference.path_partition import (brute_force_one_bounce as brute_force, cell_fluxes,
                                                     match_vpl_flux, rsm_on_proxy, set_texels)
    from vsgl_addon.reference.principled import principled_alpha
    from vsgl_addon.renderer import RECEIVER_ALPHA_RANGE, FrameRenderer, SceneLights

    width, height = RESOLUTION
    settings, truth, description = scene_with_truth(name, path, width, height)
    settings = partition_settings(settings)
    camera = description.camera
    view_matrix, projection = camera.view_matrix(), camera.projection_matrix()
    bench = Bench(description, width, height)
    renderer = FrameRenderer()
    lights = SceneLights.build(description, settings, view=(view_matrix, projection))
    result = {"scene": name, "stride": stride, "receiver_sets": list(lights.plan.receiver_sets),
              "proxies": len(lights.proxies), "caustic_roughness": settings.caustic_roughness}
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride)
        served = (alpha >= RECEIVER_ALPHA_RANGE[0]) & (alpha <= RECEIVER_ALPHA_RANGE[1]) if lights.proxies \
            else np.zeros(len(alpha), bool)
        frame = renderer.render_view(lights, settings, width, height, view_matrix, projection)
        images = {"frame_diffuse": frame.indirect_diffuse[pick], "frame_specular": frame.indirect_specular[pick],
                  "vsgl_diffuse_set_diffuse": renderer._shading.read()[0][..., :3][pick]}
        if frame.indirect_caustics is not None:
            images["vpl"] = frame.indirect_caustics[pick]
        if frame.indirect_glossy_reflectors is not None:
            images["mrp"] = frame.indirect_glossy_reflectors[pick]
            served_gpu = read_texture(renderer._mrp.texture, width, height)[..., 3][pick] > 0.0
            result["served_agrees"] = float(np.mean(served_gpu == served))
            served = served_gpu
        if lights.glossy_vsgls is not None:
            images["vsgl_glossy_set_specular"] = renderer._glossy_shading.read()[1][..., :3][pick]
        if lights.whole_vsgls is not None:
            images["vsgl_whole_set_specular"] = renderer._whole_shading.read()[1][..., :3][pick]
        else:
            images["vsgl_whole_set_specular"] = renderer._shading.read()[1][..., :3][pick]
        result["pixels"], result["served"] = int(pick.sum()), int(served.sum())

        sets = {"first": lights.vsgls, "glossy": lights.glossy_vsgls, "whole": lights.whole_vsgls}
        names = dict(zip(("first", "glossy", "whole"), lights.plan.receiver_sets))
        texels = {key: set_texels(value, description.lights) for key, value in sets.items() if value is not None}
        whole = texels.get("whole", texels["first"] if names["first"] == "all" else None)
        if whole is None:
            raise RuntimeError(f"{name}: no set of every reflector to compare with ({names})")
        sharp = principled_alpha(whole["roughness"]) < settings.caustic_roughness
        proxy = rsm_on_proxy(whole["position"], whole["normal"], whole["roughness"], lights.proxies, whole["light"])
        lit = np.abs(whole["flux_specular"]).sum(-1) > 0.0
        # Texels on a proxy of a light outside its lit-by mask: before the glossy set followed the
        # masks, their specular flux was in neither the VSGLs nor MRP-ASG.
        anywhere = rsm_on_proxy(whole["position"], whole["normal"], whole["roughness"], [p for p, _ in lights.proxies])
        result["proxy_texels_outside_masks"] = int((anywhere & ~proxy & lit).sum())
        residuals = {}
        # 1. Texel identities (same views, same texel order: the sets share the plan's view specs).
        for key, t in texels.items():
            residuals[f"{key}: position"] = relative_residual(t["position"], whole["position"])
            residuals[f"{key}: flux_diffuse"] = relative_residual(t["flux_diffuse"], whole["flux_diffuse"])
        vpl_flux = np.zeros_like(whole["flux_specular"])
        if lights.vpls is not None:
            vpls = read_vpls(lights.vpls)
            # The VPL table comes from its own RSM render of the same views: matched by position.
            vpl_flux, unmatched = match_vpl_flux(whole, vpls["position"], vpls["flux"])
            result["vpls"], result["vpls_unmatched"] = int(len(vpls["flux"])), unmatched
        if "first" in texels and names["first"] == "diffuse":
            residuals["first Φs + VPL Φs vs whole Φs"] = relative_residual(
                texels["first"]["flux_specular"] + vpl_flux, whole["flux_specular"])
            residuals["first Φs on sharp texels"] = relative_residual(
                texels["first"]["flux_specular"][sharp], 0.0 * whole["flux_specular"][sharp])
        mrp_cell = np.where((proxy & sharp)[:, None], whole["flux_specular"], 0.0)
        if "glossy" in texels:
            residuals["glossy Φs + proxy-cell Φs vs whole Φs"] = relative_residual(
                texels["glossy"]["flux_specular"] + mrp_cell, whole["flux_specular"])
            cut = lit & ~(np.abs(texels["glossy"]["flux_specular"]).sum(-1) > 0.0)
            result["cut_texels"], result["proxy_texels_lit"] = int(cut.sum()), int((proxy & lit).sum())
            result["cut_not_sharp"] = int((cut & ~sharp).sum())
        result["residuals"] = residuals

        # 2. Cells (float64 brute force of the whole RSM, restricted).
        receivers = (position, normal, view, rd, f0, alpha)
        zero = np.zeros_like(whole["flux_diffuse"])
        fs = whole["flux_specular"]
        cells = cell_fluxes(whole, lights.proxies, settings.caustic_roughness)
        start = time.perf_counter()
        brute = {key: brute_force(whole, *flux, *receivers) for key, flux in cells.items()}
        brute["whole"] = brute_force(whole, whole["flux_diffuse"], fs, *receivers)
        inputs = {}
        if "first" in texels:
            inputs["first set"] = brute_force(whole, texels["first"]["flux_diffuse"], texels["first"]["flux_specular"], *receivers)
        if lights.vpls is not None:
            inputs["VPL table"] = brute_force(whole, zero, vpl_flux, *receivers)
        if "glossy" in texels:
            inputs["glossy set"] = brute_force(whole, texels["glossy"]["flux_diffuse"], texels["glossy"]["flux_specular"], *receivers)
        log(f"{name}: brute force of {int(whole['covered'].sum())} texels at {len(position)} pixels, "
            f"{time.perf_counter() - start:.0f} s")
        masks = {"all": np.ones(len(position), bool), "served": served, "unserved": ~served}
        table = {}
        for key, (d, s) in brute.items():
            table[key] = {f"{lobe} {m}": lum(img[mask]) for lobe, img in (("diffuse", d), ("specular", s))
                          for m, mask in masks.items()}
        result["cells"] = table
        cell_sum_d = sum(brute[key][0] for key in cells)
        cell_sum_s = sum(brute[key][1] for key in cells)
        result["cells_sum_residual"] = {"diffuse": relative_residual(cell_sum_d, brute["whole"][0]),
                                        "specular": relative_residual(cell_sum_s, brute["whole"][1])}
        # The frame's composition of inputs, per receiver lobe, against the whole brute force.
        whole_d, whole_s = brute["whole"]
        compose_d = inputs["first set"][0] + (inputs["VPL table"][0] if "VPL table" in inputs else 0.0) \
            if names["first"] == "diffuse" else inputs["first set"][0]
        if "glossy set" in inputs:
            spec_served = inputs["glossy set"][1] + brute["specular, sharp, on a proxy"][1]
            spec_unserved = whole_s if lights.whole_vsgls is not None else inputs["first set"][1]
            compose_s = np.where(served[:, None], spec_served, spec_unserved)
        else:
            compose_s = inputs["first set"][1]
        result["composed_inputs"] = {
            "diffuse / whole": lum(compose_d) / max(lum(whole_d), 1e-30),
            "specular / whole": lum(compose_s) / max(lum(whole_s), 1e-30),
            "diffuse max |Δ| / max": relative_residual(compose_d, whole_d),
            "specular max |Δ| / max": relative_residual(compose_s, whole_s)}

        # 3. Techniques against their cells.
        b = brute
        tech = {}

        def ratio(label, image, reference, mask):
            ref = lum(reference[mask])
            tech[label] = {"ours": lum(image[mask]), "cell": ref, "ratio": lum(image[mask]) / ref if ref > 0 else None}

        sharp_d = b["specular, sharp, on a proxy"][0] + b["specular, sharp, elsewhere"][0]
        ratio("diffuse receivers' VSGLs (diffuse) vs diffuse lobe + specular alpha >= alpha_c -> diffuse",
              images["vsgl_diffuse_set_diffuse"], b["diffuse lobe"][0] + b["specular, alpha >= alpha_c"][0], masks["all"])
        if "vpl" in images:
            ratio("VPL pass vs sharp -> diffuse", images["vpl"], sharp_d, masks["all"])
        if "vsgl_glossy_set_specular" in images:
            ratio("glossy receivers' VSGLs (specular) vs all but sharp-on-proxy -> specular, served",
                  images["vsgl_glossy_set_specular"], whole_s - b["specular, sharp, on a proxy"][1], served)
        if "mrp" in images:
            ratio("MRP-ASG vs sharp-on-proxy -> specular, served", images["mrp"], b["specular, sharp, on a proxy"][1], served)
            ratio("MRP-ASG on unserved pixels (must be 0) vs sharp-on-proxy -> specular", images["mrp"],
                  b["specular, sharp, on a proxy"][1], ~served)
        ratio("whole set's VSGLs (specular) vs whole -> specular, unserved", images["vsgl_whole_set_specular"], whole_s, ~served)
        ratio("frame Indirect Diffuse vs whole -> diffuse", images["frame_diffuse"], whole_d, masks["all"])
        ratio("frame Indirect Specular vs whole -> specular", images["frame_specular"], whole_s, masks["all"])
        ratio("frame Indirect Specular vs whole -> specular, served", images["frame_specular"], whole_s, served)
        ratio("frame Indirect Specular vs whole -> specular, unserved", images["frame_specular"], whole_s, ~served)
        # The frame's composition of its own images (renderer.render_view_textures).
        recomposed_d = images["vsgl_diffuse_set_diffuse"] + images.get("vpl", 0.0)
        if "mrp" in images:
            recomposed_s = np.where(served[:, None], images.get("vsgl_glossy_set_specular", images["vsgl_whole_set_specular"])
                                    + images["mrp"], images["vsgl_whole_set_specular"])
        else:
            recomposed_s = images["vsgl_whole_set_specular"]
        result["frame_composition"] = {"diffuse": relative_residual(images["frame_diffuse"], recomposed_d),
                                       "specular": relative_residual(images["frame_specular"], recomposed_s)}
        result["techniques"] = tech
        # Per-pixel error of the specular layer against the brute force (no visibility, float64),
        # luminance: relative RMSE and where its squared error is (served / unserved pixels; on
        # served ones the glossy set's part and MRP-ASG's part of the error, e = e_vsgl + e_mrp).
        error = (images["frame_specular"] - whole_s) @ LUMINANCE
        mean = max(float(np.mean(whole_s @ LUMINANCE)), 1e-30)
        total = max(float(np.sum(error ** 2)), 1e-30)
        split = {"rel_rmse": float(np.sqrt(np.mean(error ** 2))) / mean,
                 "served share": float(np.sum(error[served] ** 2)) / total,
                 "unserved share": float(np.sum(error[~served] ** 2)) / total}
        if "mrp" in images and "vsgl_glossy_set_specular" in images:
            cell = b["specular, sharp, on a proxy"][1]
            e_vsgl = ((images["vsgl_glossy_set_specular"] - (whole_s - cell)) @ LUMINANCE)[served]
            e_mrp = ((images["mrp"] - cell) @ LUMINANCE)[served]
            split["served: glossy set's own error²"] = float(np.sum(e_vsgl ** 2)) / total
            split["served: MRP-ASG's own error²"] = float(np.sum(e_mrp ** 2)) / total
            split["served: cross term 2 e_vsgl e_mrp"] = float(2.0 * np.sum(e_vsgl * e_mrp)) / total
        materials = np.asarray(bench.material_index[pick])
        cycles = 0.5 * (truth["glossy_a"] + truth["glossy_b"])[..., :3][pick].astype(np.float64)
        split["Cycles (visibility, all paths) / brute"] = lum(cycles) / max(lum(whole_s), 1e-30)
        for index in np.unique(materials):
            here = materials == index
            split[f"material {bench.materials[index]} Cycles/brute"] = lum(cycles[here]) / max(lum(whole_s[here]), 1e-30)
            split[f"material {bench.materials[index]} share"] = float(np.sum(error[here] ** 2)) / total
            split[f"material {bench.materials[index]} ours/brute"] = lum(images["frame_specular"][here]) / max(lum(whole_s[here]), 1e-30)
        result["specular_error"] = split
    finally:
        lights.free()
        renderer.free()
        bench.free()
    return result


STAGE_QUADRATURE = dict(order=8, smallest=1e-3)  # 1e-9 of the default rule's value on the accuracy base


def _asg_exact_receiver(light_asg, position, normal, view, alpha, f0, size=801):
    """∫ ASG(ω) f_x(ω, o) (ω·n_x) dω, MRP-ASG's ASG light (001 Eqs. 18, 28–35) against the
    receiver's exact GGX BRDF, on a tangent-plane grid around the narrower of the two lobes: the
    ASG's axis (6 / √bandwidth wide) or the receiver's mirror direction (12 α / √(o·n) wide, the
    GGX tail beyond it under 1 %), at most 1.5 (56°) either way."""
    from vsgl_addon.reference import ggx
    from vsgl_addon.reference.asg import asg_any_tangent, asg_evaluate

    m, n, z = light_asg["m"], light_asg["n"], light_asg["z"]
    lam, mu = float(light_asg["bandwidth_m"]), float(light_asg["bandwidth_n"])
    asg_half = 6.0 / np.sqrt(max(min(lam, mu), 1e-6))
    cos_o = max(float(view @ normal), 1e-3)
    receiver_half = 12.0 * alpha / np.sqrt(cos_o)
    if asg_half <= receiver_half:
        axis, t1, half = z, m, asg_half
    else:
        axis = 2.0 * cos_o * normal - view
        axis = axis / np.linalg.norm(axis)
        t1, half = asg_any_tangent(axis), receiver_half
    t2 = np.cross(axis, t1)
    half = min(half, 1.5)
    t = np.linspace(-half, half, size)
    a, b = np.meshgrid(t, t, indexing="ij")
    w = axis + a[..., None] * t1 + b[..., None] * t2
    length = np.linalg.norm(w, axis=-1)
    w = w / length[..., None]
    solid_angle = (t[1] - t[0]) ** 2 / length ** 3
    values = float(light_asg["amplitude"]) * asg_evaluate(w, m, n, z, lam, mu)
    brdf = ggx.microfacet_brdf(w, np.broadcast_to(view, w.shape), np.broadcast_to(normal, w.shape), alpha, f0)
    cosine = np.maximum(w @ normal, 0.0)
    return float(np.sum(values * brdf * cosine * solid_angle))


def _gaussian_lobes_integral(axis, lobes):
    """∫ Π_j exp(−η_j1 (ω·e_j1)² − η_j2 (ω·e_j2)²) dω in the tangent plane at the unit ``axis``
    (lobes: (e1, e2, η1, η2)): with ω ≈ axis + u, u in the plane, the exponent is −uᵀPu + 2bᵀu − c,
    so the integral is π / √det P · exp(bᵀP⁻¹b − c); also the product's peak direction. For an SG
    and an ASG this is Eq. 11's small-angle form (000 app. C, after Xu et al. 2013)."""
    from vsgl_addon.reference.asg import asg_any_tangent

    t1 = asg_any_tangent(axis)
    t2 = np.cross(axis, t1)
    p_mat, b_vec, c = np.zeros((2, 2)), np.zeros(2), 0.0
    for e1, e2, h1, h2 in lobes:
        for e, h in ((e1, h1), (e2, h2)):
            offset, g = float(e @ axis), np.array([e @ t1, e @ t2])
            p_mat += h * np.outer(g, g)
            b_vec -= h * offset * g
            c += h * offset * offset
    u = np.linalg.solve(p_mat, b_vec)
    peak = axis + u[0] * t1 + u[1] * t2
    return np.pi / np.sqrt(np.linalg.det(p_mat)) * np.exp(b_vec @ u - c), peak / np.linalg.norm(peak)


def _asg_receiver_shade(light_asg, position, normal, view, alpha, f0):
    """MRP-ASG with the receiver's NDF warped anisotropically (003's ASG lobe,
    reference.asg.asg_specular_lobe: η = λ_h/(8 cos²θ_o) across the plane of incidence, λ_h/8 in
    it, per SG of RECEIVER_NDF_LOBES) instead of Eq. 8's isotropic λ_h/(4 cos θ_o), convolved with
    the ASG light in the tangent plane of the narrower lobe (``_gaussian_lobes_integral``), the
    light's cosine max(ω·z, 0) at the product's peak; M of Eq. 10 as mrp_shade."""
    from vsgl_addon.reference import mrp_asg as mrp
    from vsgl_addon.reference.asg import asg_specular_lobe

    a = light_asg
    x, y, z, eta_x, eta_y = asg_specular_lobe(view, normal, alpha)
    light_lobe = (a["m"], a["n"], float(a["bandwidth_m"]), float(a["bandwidth_n"]))
    total = 0.0
    for weight, scale in mrp.RECEIVER_NDF_LOBES:
        receiver_lobe = (x, y, scale * float(eta_x), scale * float(eta_y))
        axis = a["z"] if min(light_lobe[2:]) > min(receiver_lobe[2:]) else z
        value, peak = _gaussian_lobes_integral(axis, [receiver_lobe, light_lobe])
        total += weight * value * max(float(peak @ a["z"]), 0.0)
    factor = float(mrp.mrp_receiver_factor(a["z"], view, normal, alpha, f0))
    return factor * float(a["amplitude"]) * total / (np.pi * max(alpha, mrp.ALPHA_MIN) ** 2)


def stage_values(position, normal, view, alpha, f0, lit, lights, disk_radius) -> dict:
    """One receiver's stages, RGB, summed over the lights and the lit proxies (``lit``: (proxy,
    lit-by mask) pairs), each light's colour × glossy factor, no shadows:

    - ``ref``: reference.mrp_asg.mrp_shade with Eq. 8's receiver (two SGs, ``receiver="sg"``);
    - ``quad``: Eq. 3 by quadrature over the rectangle (brute_force_rectangle, exact GGX at both
      ends): the cell's truth;
    - ``C_ref``, ``C_quad``: the ASG light's energy C = A E L_y (Eqs. 17, 25–27, 35, 36) and its
      truth, the solid-angle integral at x of R's reflected radiance (Eq. 13) by quadrature;
    - ``C_plane``: that integral over the whole plane (a rectangle of 1000× the proxy around the
      peak): against E L_y the disk integral's error alone, C_quad / C_plane what A should be;
    - ``asg_exact``: the ASG light against the exact receiver BRDF (``_asg_exact_receiver``): ref /
      asg_exact is the receiver's two-SG NDF, M and Eq. 11; asg_exact C_quad / C_ref / quad the
      ASG's shape (its frame, extents, bandwidths) alone;
    - ``asg_receiver``: the candidate fix, the receiver lobe as 003's ASG (``_asg_receiver_shade``)."""
    from vsgl_addon.reference import mrp_asg as mrp

    out = {key: np.zeros(3) for key in ("ref", "quad", "C_ref", "C_quad", "C_plane", "E_Ly", "asg_exact", "asg_receiver")}
    for index, light in enumerate(lights):
        scale = np.asarray(light.color, np.float64) * float(light.specular_factor)
        for proxy, mask in lit:
            if not mask[index]:
                continue
            for ch in range(3):
                rect = proxy.as_rect(ch)
                a = mrp.mrp_asg_light(position, rect, light, disk_radius)
                if not bool(a["valid"]):
                    continue
                out["ref"][ch] += scale[ch] * float(mrp.mrp_shade(position, normal, view, alpha, f0[ch], rect, light,
                                                                   disk_radius, receiver="sg"))
                out["quad"][ch] += scale[ch] * mrp.brute_force_rectangle(position, normal, view, alpha, f0[ch], rect,
                                                                        light, **STAGE_QUADRATURE)
                out["C_ref"][ch] += scale[ch] * float(a["total"])
                out["E_Ly"][ch] += scale[ch] * float(a["disk_integral"] * a["radiance"])
                out["C_quad"][ch] += scale[ch] * mrp.brute_force_rectangle(position, normal, view, alpha, f0[ch], rect,
                                                                          light, receiver_brdf=False, **STAGE_QUADRATURE)
                plane = dict(rect, center=a["peak"], half_u=1000.0 * max(rect["half_u"], rect["half_v"]),
                             half_v=1000.0 * max(rect["half_u"], rect["half_v"]))
                out["C_plane"][ch] += scale[ch] * mrp.brute_force_rectangle(
                    position, normal, view, alpha, f0[ch], plane, light, receiver_brdf=False,
                    order=STAGE_QUADRATURE["order"], smallest=STAGE_QUADRATURE["smallest"] / 1000.0)
                out["asg_exact"][ch] += scale[ch] * _asg_exact_receiver(a, position, normal, view, alpha, f0[ch])
                out["asg_receiver"][ch] += scale[ch] * _asg_receiver_shade(a, position, normal, view, alpha, f0[ch])
    return out


@contextlib.contextmanager
def served_pixels(name, path, stride, materials=None):
    """The frame of ``name`` (visibility off, path_partition's settings) and the pixels MRP-ASG serves
    among every ``stride``-th one (of ``materials`` only, when given): a namespace with ``settings``,
    ``description``, ``lights`` (SceneLights), ``bench``, ``frame``, ``pick`` and the sampled
    ``position``, ``normal``, ``view``, ``rd``, ``f0``, ``alpha`` (validation_suite.sampled_pixels)
    and ``served`` (a mask over them). The GPU resources are freed on exit."""
    import types

    from vsgl_addon.passes.gpu_util import read_texture
    from vsgl_addon.renderer import FrameRenderer, SceneLights

    width, height = RESOLUTION
    settings, truth, description = scene_with_truth(name, path, width, height)
    settings = partition_settings(settings)
    camera = description.camera
    view_matrix, projection = camera.view_matrix(), camera.projection_matrix()
    bench = Bench(description, width, height)
    renderer = FrameRenderer()
    lights = SceneLights.build(description, settings, view=(view_matrix, projection))
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride, materials)
        frame = renderer.render_view(lights, settings, width, height, view_matrix, projection)
        if frame.indirect_glossy_reflectors is None:
            raise RuntimeError(f"{name}: MRP-ASG did not run")
        served = read_texture(renderer._mrp.texture, width, height)[..., 3][pick] > 0.0
        yield types.SimpleNamespace(settings=settings, description=description, lights=lights, bench=bench,
                                    frame=frame, pick=pick, position=position, normal=normal, view=view, rd=rd,
                                    f0=f0, alpha=alpha, served=served)
    finally:
        lights.free()
        renderer.free()
        bench.free()


def stages(name, path, stride, materials=None) -> dict:
    """MRP-ASG's error on the pixels it serves, by stage, against quadrature of the same cell
    (``stage_values``) and against the texel brute force of path_partition's cell "specular, sharp,
    on a proxy" (which has the light's shadows at the reflector; the quadrature has none)."""
    from vsgl_addon.reference.path_partition import brute_force_one_bounce as brute_force, cell_fluxes, set_texels

    with served_pixels(name, path, stride, materials) as px:
        settings, description, lights, bench, pick = px.settings, px.description, px.lights, px.bench, px.pick
        position, normal, view, rd, f0, alpha = px.position, px.normal, px.view, px.rd, px.f0, px.alpha
        gpu = px.frame.indirect_glossy_reflectors[pick].astype(np.float64)
        served = px.served
        whole = set_texels(lights.whole_vsgls if lights.whole_vsgls is not None else lights.vsgls, description.lights)
        cell = cell_fluxes(whole, lights.proxies, settings.caustic_roughness)["specular, sharp, on a proxy"]
        idx = np.flatnonzero(served)
        receivers = (position[idx], normal[idx], view[idx], rd[idx], f0[idx], alpha[idx])
        texel = brute_force(whole, *cell, *receivers)[1]
        # The quadratures only where the cell or MRP-ASG is above 1e-3 of the brightest (either one's
        # light elsewhere is reported as the share left out).
        from vsgl_addon.reference import mrp_asg as mrp
        ref = np.zeros((len(idx), 3))
        for index, light in enumerate(description.lights):
            for proxy, mask in lights.proxies:
                if mask[index]:
                    for ch in range(3):
                        ref[:, ch] += (light.color[ch] * light.specular_factor
                                       * mrp.mrp_shade(position[idx], normal[idx], view[idx], alpha[idx], f0[idx, ch],
                                                       proxy.as_rect(ch), light, settings.disk_radius, receiver="sg"))
        level = np.maximum(ref @ LUMINANCE, texel @ LUMINANCE)
        bright = level > 1e-3 * max(float(level.max()), 1e-30)
        left_out = {"pixels": int((~bright).sum()),
                    "texel share": float((texel @ LUMINANCE)[~bright].sum() / max(float((texel @ LUMINANCE).sum()), 1e-30)),
                    "reference share": float((ref @ LUMINANCE)[~bright].sum() / max(float((ref @ LUMINANCE).sum()), 1e-30))}
        idx, texel = idx[bright], texel[bright]
        start = time.perf_counter()
        values = []
        for count, i in enumerate(idx):
            values.append(stage_values(position[i], normal[i], view[i], alpha[i], f0[i], lights.proxies,
                                       description.lights, settings.disk_radius))
            if count % 25 == 0:
                log(f"{name}: {count}/{len(idx)} pixels, {time.perf_counter() - start:.0f} s")
        log(f"{name}: stages at {len(idx)} served pixels, {time.perf_counter() - start:.0f} s")
        v = {key: np.array([value[key] for value in values]) for key in values[0]}
        materials_index = np.asarray(bench.material_index[pick])[idx]
        material_names = list(bench.materials)
    ratio = lambda a, b: np.divide(a, b, out=np.zeros_like(a), where=np.abs(b) > 0)
    energy_exact = v["ref"] * ratio(v["C_quad"], v["C_ref"])
    shape_only = v["asg_exact"] * ratio(v["C_quad"], v["C_ref"])
    variants = {
        "GPU pass": gpu[idx], "reference, receiver NDF as Eq. 8's SGs (the pass before)": v["ref"],
        "reference, C = A E L_y replaced by its quadrature": energy_exact,
        "ASG light x exact GGX receiver (A E L_y as is)": v["asg_exact"],
        "ASG light x exact GGX receiver, exact C (the ASG's shape alone)": shape_only,
        "reference, receiver NDF warped as 003's ASG (two lobes), ASG x ASG in the tangent plane": v["asg_receiver"],
        "texel brute force of the cell (light's shadows, RSM Rs)": texel}
    q = v["quad"] @ LUMINANCE
    mean = max(float(np.mean(q)), 1e-30)
    rows = {}
    for label, image in variants.items():
        lum_image = image @ LUMINANCE
        error = lum_image - q
        rows[label] = {"sum / quad": float(lum_image.sum() / max(q.sum(), 1e-30)),
                       "rel_rmse": float(np.sqrt(np.mean(error ** 2))) / mean,
                       "error2_over_ref": float(np.sum(error ** 2))}
    ref_e2 = max(rows["reference, receiver NDF as Eq. 8's SGs (the pass before)"]["error2_over_ref"], 1e-30)
    for row in rows.values():
        row["error2_over_ref"] /= ref_e2
    # The energy C split: Eqs. 25-27 against the whole plane, A against clipping by the rectangle.
    c_ref, c_quad, c_plane, e_ly = (v[k] @ LUMINANCE for k in ("C_ref", "C_quad", "C_plane", "E_Ly"))
    energy = {"C_ref / C_quad (sum)": float(c_ref.sum() / max(c_quad.sum(), 1e-30)),
              "E L_y / C_plane (sum): disk integral, Eqs. 25-27": float(e_ly.sum() / max(c_plane.sum(), 1e-30)),
              "A (C-weighted) / (C_quad / C_plane): area ratio, Eq. 36": float(c_ref.sum() / max(e_ly.sum(), 1e-30))
              / float(c_quad.sum() / max(c_plane.sum(), 1e-30))}
    for key, (a, b) in {"C_ref / C_quad": (c_ref, c_quad), "E L_y / C_plane": (e_ly, c_plane),
                        "ref / asg_exact (receiver SGs, M, Eq. 11)": (v["ref"] @ LUMINANCE, v["asg_exact"] @ LUMINANCE),
                        "asg_exact C_quad/C_ref / quad (ASG shape)": (shape_only @ LUMINANCE, q)}.items():
        r = np.divide(a, b, out=np.full_like(a, np.nan), where=b > 1e-6 * max(float(b.max()), 1e-30))
        r = r[np.isfinite(r)]
        if r.size:
            energy[f"per pixel {key}: median / 10th / 90th pct"] = [float(np.median(r)), float(np.percentile(r, 10)),
                                                                    float(np.percentile(r, 90))]
    per_material = {}
    for index in np.unique(materials_index):
        here = materials_index == index
        e_ref = (v["ref"] @ LUMINANCE - q)[here]
        per_material[material_names[index]] = {
            "pixels": int(here.sum()), "quad": float(q[here].sum()),
            "ref / quad": float((v["ref"] @ LUMINANCE)[here].sum() / max(q[here].sum(), 1e-30)),
            "GPU / quad": float((gpu[idx] @ LUMINANCE)[here].sum() / max(q[here].sum(), 1e-30)),
            "texel / quad": float((texel @ LUMINANCE)[here].sum() / max(q[here].sum(), 1e-30)),
            "C_ref / C_quad": float(c_ref[here].sum() / max(c_quad[here].sum(), 1e-30)),
            "share_of_ref_error2": float(np.sum(e_ref ** 2)) / ref_e2}
    return {"scene": name, "stride": stride, "served": int(len(idx)), "left_out": left_out, "variants": rows, "energy": energy,
            "materials": per_material,
            "pixels": {key: value.tolist() for key, value in v.items()} | {"gpu": gpu[idx].tolist(),
                                                                          "texel": texel.tolist()},
            "receivers": {key: value[idx].tolist() for key, value in (("position", position), ("normal", normal),
                                                                       ("view", view), ("f0", f0), ("alpha", alpha))}}


def stages_markdown(results, command) -> str:
    lines = ["# MRP-ASG's error by stage, on the pixels it serves", "",
             f"`{command}` (benchmarks/path_partition.py's `stages`: visibility off, 240x180). The truth is "
             "Eq. 3 by quadrature over each lit proxy side for each light (reference.mrp_asg.brute_force_rectangle, "
             "exact GGX at both ends, no shadows); luminance.", ""]
    for r in results:
        lo = r["left_out"]
        lines += [f"## {r['scene']}", "", f"{r['served']} served pixels (every {r['stride']}th both ways) where the cell's "
                  f"texel brute force or MRP-ASG is above 1e-3 of its brightest; {lo['pixels']} served pixels below "
                  f"that left out (their share of the texel brute force {lo['texel share']:.2e}, of MRP-ASG's "
                  f"{lo['reference share']:.2e}).", "",
                  "| variant | sum / quadrature | rel. RMSE | error² / reference's |", "|---|---|---|---|"]
        for key, value in r["variants"].items():
            lines.append(f"| {key} | {value['sum / quad']:.3f} | {value['rel_rmse']:.3f} | {value['error2_over_ref']:.3f} |")
        lines += ["", "The ASG light's energy C = A E L_y:", ""]
        for key, value in r["energy"].items():
            shown = " / ".join(f"{x:.3f}" for x in value) if isinstance(value, list) else f"{value:.3f}"
            lines.append(f"- {key}: {shown}")
        lines += ["", "| material | pixels | quadrature | ref / quad | GPU / quad | texel / quad | C_ref / C_quad | share of ref's error² |",
                  "|---|---|---|---|---|---|---|---|"]
        for key, value in r["materials"].items():
            lines.append(f"| {key} | {value['pixels']} | {value['quad']:.4g} | {value['ref / quad']:.3f} | "
                         f"{value['GPU / quad']:.3f} | {value['texel / quad']:.3f} | {value['C_ref / C_quad']:.3f} | "
                         f"{value['share_of_ref_error2']:.3f} |")
        lines.append("")
    return "\n".join(lines)


def markdown(results, command) -> str:
    lines = ["# Path partition: is any light path counted twice or dropped?", "",
             f"`{command}` (benchmarks/path_partition.py's documentation: visibility off, δ 1e-6, "
             "no VPL filter, 240x180).", ""]
    for r in results:
        lines += [f"## {r['scene']}", "",
                  f"VSGL sets {r['receiver_sets']}, {r['proxies']} proxies, α_c {r['caustic_roughness']}; "
                  f"{r['pixels']} pixels (every {r['stride']}th both ways), {r['served']} served by MRP-ASG"
                  + (f" (receiver-range test agrees with the pass's alpha on {r['served_agrees']:.3f})" if "served_agrees" in r else "")
                  + (f"; {r['vpls']} VPLs, {r['vpls_unmatched']} not matched to a texel" if "vpls" in r else "")
                  + (f"; glossy set: {r['cut_texels']} texels lost Φs, {r['proxy_texels_lit']} lit texels on proxies, "
                     f"{r['cut_not_sharp']} of the cut not sharp" if "cut_texels" in r else "") + ".", "",
                  "Texel identities (max |Δ| / max |whole|):", ""]
        lines += [f"- {key}: {value:.2e}" for key, value in r["residuals"].items()]
        lines += [f"- lit texels on a proxy whose light is outside its lit-by mask: {r['proxy_texels_outside_masks']}"]
        lines += ["", f"Cells summed vs the unrestricted brute force (max |Δ| / max): diffuse "
                      f"{r['cells_sum_residual']['diffuse']:.2e}, specular {r['cells_sum_residual']['specular']:.2e}.", "",
                  "Brute force per cell (luminance summed over the pixels):", "",
                  "| cell | → diffuse | → specular | → specular, served | → specular, unserved |", "|---|---|---|---|---|"]
        for key, value in r["cells"].items():
            lines.append(f"| {key} | {value['diffuse all']:.5g} | {value['specular all']:.5g} | "
                         f"{value['specular served']:.5g} | {value['specular unserved']:.5g} |")
        c = r["composed_inputs"]
        lines += ["", f"The frame's inputs composed as the frame composes them, brute-forced, over the whole: diffuse "
                      f"{c['diffuse / whole']:.6f} (max |Δ| / max {c['diffuse max |Δ| / max']:.1e}), specular "
                      f"{c['specular / whole']:.6f} (max |Δ| / max {c['specular max |Δ| / max']:.1e}).", "",
                  f"The frame's images recomposed from its passes' images (max |Δ| / max): diffuse "
                  f"{r['frame_composition']['diffuse']:.1e}, specular {r['frame_composition']['specular']:.1e}.", "",
                  "| technique vs its cell (brute force) | ours | cell | ours / cell |", "|---|---|---|---|"]
        for key, value in r["techniques"].items():
            shown = "" if value["ratio"] is None else f"{value['ratio']:.3f}"
            lines.append(f"| {key} | {value['ours']:.5g} | {value['cell']:.5g} | {shown} |")
        lines += ["", "The specular layer against the brute force, per pixel (luminance): "
                      + "; ".join(f"{key} {value:.3f}" for key, value in r["specular_error"].items()), ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=list(SCENES))
    parser.add_argument("--stride", type=int, default=6)
    parser.add_argument("--results-dir", type=Path, default=RESULTS_DIR)
    parser.add_argument("--stages", action="store_true", help="MRP-ASG's error by stage (mrp_asg_stages.md)")
    parser.add_argument("--materials", nargs="+", default=None, help="with --stages: these receivers only")
    parser.add_argument("--results-name", default=None, help="file stem of the results (default by mode)")
    args = parser.parse_args(argv)
    from vsgl_addon import register, unregister
    from vsgl_addon.gpu_context import ensure_gpu_context

    paths = {name: path for name, path, _ in suite()}
    register()
    ensure_gpu_context()
    try:
        results = [stages(name, paths[name], args.stride, args.materials) if args.stages
                   else check(name, paths[name], args.stride) for name in args.only]
    finally:
        unregister()
    command = "benchmarks/path_partition.py " + " ".join(sys.argv[1:] if argv is None else argv)
    text = (stages_markdown if args.stages else markdown)(results, command.strip())
    stem = args.results_name or ("mrp_asg_stages" if args.stages else "path_partition")
    args.results_dir.mkdir(parents=True, exist_ok=True)
    (args.results_dir / f"{stem}.md").write_text(text + "\n")
    (args.results_dir / f"{stem}.json").write_text(json.dumps({"command": command.strip(), "results": results},
                                                                     indent=1, default=float) + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
