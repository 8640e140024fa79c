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
    args = parser.parse_args(argv)
    from vsgl_addon import register, unregister
    from vsgl_addon.gpu_context import ensure_gpu_context

    paths = {name: path for name, path, _ in suite()}
    register()
    ensure_gpu_context()
    try:
        results = [check(name, paths[name], args.stride) for name in args.only]
    finally:
        unregister()
    command = "benchmarks/path_partition.py " + " ".join(sys.argv[1:] if argv is None else argv)
    text = markdown(results, command.strip())
    args.results_dir.mkdir(parents=True, exist_ok=True)
    (args.results_dir / "path_partition.md").write_text(text + "\n")
    (args.results_dir / "path_partition.json").write_text(json.dumps({"command": command.strip(), "results": results},
                                                                     indent=1, default=float) + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
