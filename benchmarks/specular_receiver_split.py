# SPDX-License-Identifier: GPL-3.0-or-later
"""Where the VSGLs' specular-receiver light from diffuse reflectors goes (not a test), per material.

    .venv/bin/python benchmarks/specular_receiver_split.py [--only NAME ...] [--stride S]
        [--materials M ...] [--results-dir DIR]

On every S-th pixel (both ways) of the suite's 240x180 camera G-buffer, of the named materials
(default: the demo's gold sphere), the receivers' specular term (their exact GGX, or 003's ASG) of
the light the reflectors' *diffuse* flux Φ·Rd throws, float64, no visibility, in one chain:

1. exact: every RSM texel (every view of every light, the GPU's read back) a Lambertian VPL
   Φ Rd/π ⟨ω, n⟩ onto the receiver's exact GGX lobe (reference/vsgl_shading.brute_force_shading);
2. SG lobes: the VPLs' lobes replaced by 000 Eq. 6's SG (hemisphere-normalized, what the VSGLs
   carry): the lobe fit alone;
3. SG lobes, ASG receiver: each texel its own VSGL (reference/vsgl_shading.per_texel_vsgls, the
   N = M limit: a point light), shaded by the reference (003's ASG receiver lobe, SG × ASG
   convolution): the receiver-lobe approximation;
4. VSGLs, Eq. 12: the GPU's VSGL table (N = the scene's; and --counts) shaded by the reference,
   the diffuse lobes' specular term in specular mode "product" (000 Eq. 12's SG): clustering
   into Gaussians (000 app. B) and the product;
5. VSGLs, separable: the same VSGLs in specular mode "separable" (the positional lobe convolved
   with the receiver's ASG, the emission taken at −ξµ).

Then (unless --no-frame) the frame's own VSGL sets (renderer.SceneLights: the diffuse receivers'
and, with MRP-ASG, the glossy receivers' without the proxies' specular flux) by the reference in
both modes and by the GPU, and the rendered frame's indirect specular without and with MRP-ASG's
part, visibility on and off.

Each as a ratio to step 1 on those pixels (luminance), with its relative RMSE per pixel against
step 1, and per receiver-roughness bin (``ALPHA_BINS``) for steps 3-5. Also Cycles' indirect
glossy (GlossInd·GlossCol) on them, for scale. Writes ``specular_receiver_split.md`` in the
results directory (``specular_receiver_split_all.md`` with ``--materials all``: every covered pixel).
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
from energy_budget import rsm_vpls  # noqa: E402
from tradeoff.bench import Bench  # noqa: E402
from tradeoff.demo import log  # noqa: E402

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
# Receiver GGX α bins of the per-roughness comparison.
ALPHA_BINS = ((0.0, 0.15), (0.15, 0.4), (0.4, 2.0))
STEPS = ("exact", "sg_lobes", "sg_lobes_asg", "vsgl_product", "vsgl_separable")


def split(name, path, stride, materials, counts, frame_sets=True):
    from vsgl_addon.reference.vsgl import MOMENT_CHANNELS, texel_moments, vsgl_parameters
    from vsgl_addon.reference.vsgl_shading import VPLs, brute_force_shading, shade

    width, height = RESOLUTION
    settings, truth, description = scene_with_truth(name, path, width, height)
    bench = Bench(description, width, height)
    light = {}
    try:
        pick, position, normal, view, rd, f0, alpha = sampled_pixels(bench, truth, stride,
                                                                      None if "all" in materials else materials)
        log(f"{name}: {int(pick.sum())} pixels of {materials}, GGX alpha {alpha.min():.3f}-{alpha.max():.3f}")
        v = rsm_vpls(bench.scene_gpu, settings.rsm_size)
        vpls = VPLs(v["position"], v["normal"], v["flux"], v["rd"], np.zeros_like(v["rs"]), v["alpha"], v["incoming"])
        start = time.perf_counter()
        light["exact"] = brute_force_shading(vpls, position, normal, view, rd, f0, alpha, "ggx")[1]
        light["sg_lobes"] = brute_force_shading(vpls, position, normal, view, rd, f0, alpha, "sg")[1]
        # reference/vsgl_shading.per_texel_vsgls on the flat texel list (RSM.coerce wants a square image).
        flat = vpls.rsm()
        image = type(flat)(**{k: getattr(flat, k)[None] for k in flat.__dataclass_fields__})
        table = vsgl_parameters(texel_moments(image).reshape(-1, MOMENT_CHANNELS))
        _, _, terms = shade(table, position, normal, view, rd, f0, alpha, diffuse_mode="separable", per_term=True)
        light["sg_lobes_asg"] = terms[:, :, 0, 1].sum(axis=1)
        log(f"{name}: {len(v['flux'])} VPLs, brute force {time.perf_counter() - start:.0f} s")
        # The scene's own N always, since the GPU and frame columns are taken at it.
        for count in dict.fromkeys([*counts, settings.vsgl_count]):
            vsgls, _ = bench.vsgls(settings.overridden(vsgl_count=count, visibility=False))
            try:
                for mode in ("product", "separable"):
                    total = np.zeros_like(position)
                    for _, _, generation in vsgls.generations:
                        table = {k: np.asarray(x, np.float64) for k, x in generation.read_table().items()}
                        _, _, terms = shade(table, position, normal, view, rd, f0, alpha, diffuse_mode="separable",
                                            specular_mode=mode, per_term=True)
                        total += terms[:, :, 0, 1].sum(axis=1)
                    light[f"vsgl_{mode}" + ("" if count == settings.vsgl_count else f"_{count}")] = total
            finally:
                vsgls.free()
        # The frame's own VSGL sets (renderer.SceneLights: the diffuse receivers' set, and with MRP-ASG
        # the glossy receivers' set without the proxies' specular flux), by the reference and by the GPU.
        from tradeoff.bench import upload
        from vsgl_addon.renderer import FrameRenderer, SceneLights

        if not frame_sets:
            return _figures(name, materials, pick, alpha, settings, light, truth)

        camera = description.camera
        lights = SceneLights.build(description, settings.overridden(visibility=False),
                                   view=(camera.view_matrix(), camera.projection_matrix()))
        try:
            for set_name in ("vsgls", "glossy_vsgls"):
                table_set = getattr(lights, set_name)
                if table_set is None:
                    continue
                tables = [{k: np.asarray(x, np.float64) for k, x in t.items()} for t in table_set.table_arrays()]
                for mode in ("product", "separable"):
                    ours = np.zeros_like(position)
                    both = np.zeros_like(position)
                    for table in tables:
                        _, _, terms = shade(table, position, normal, view, rd, f0, alpha, diffuse_mode="separable",
                                            specular_mode=mode, per_term=True)
                        ours += terms[:, :, 0, 1].sum(axis=1)
                        both += terms[:, :, :, 1].sum(axis=(1, 2))
                    light[f"frame_{set_name}_{mode}"] = ours
                    light[f"frame_{set_name}_{mode}_both_lobes"] = both
                diffuse_only = [dict(t, specular_amplitude=np.zeros_like(t["specular_amplitude"])) for t in tables]
                gpu_tables = [part for t in diffuse_only for part in upload(t)]
                light[f"frame_{set_name}_gpu"] = bench.shade(gpu_tables)[1][pick].astype(np.float64)
                light[f"frame_{set_name}_gpu_both_lobes"] = bench.shade(table_set.tables())[1][pick].astype(np.float64)
        finally:
            lights.free()
        # The frame as rendered (FrameRenderer, the scene's settings, visibility on and off): its
        # VSGLs' part of the indirect specular (without MRP-ASG's) and MRP-ASG's.
        for visibility in (True, False):
            renderer = FrameRenderer()
            try:
                frame = renderer.render(description, settings.overridden(visibility=visibility), width, height)
            finally:
                renderer.free()
            suffix = "on" if visibility else "off"
            mrp = frame.indirect_glossy_reflectors
            mrp = np.zeros_like(frame.indirect_specular) if mrp is None else mrp
            light[f"render_vsgl_{suffix}"] = (frame.indirect_specular - mrp)[pick].astype(np.float64)
            light[f"render_mrp_{suffix}"] = mrp[pick].astype(np.float64)
    finally:
        bench.free()
    return _figures(name, materials, pick, alpha, settings, light, truth)


def _figures(name, materials, pick, alpha, settings, light, truth):
    cycles = np.asarray(truth["glossy"], np.float64)[pick]
    exact = light["exact"] @ LUMINANCE
    rows = {}
    for key, value in light.items():
        lum = value @ LUMINANCE
        rows[key] = {"ratio": float(lum.sum() / exact.sum()),
                     "rel_rmse": float(np.sqrt(np.mean((lum - exact) ** 2)) / np.mean(exact)),
                     "mean_rgb": [float(x) for x in value.mean(axis=0)]}
    figures = {"scene": name, "materials": list(materials), "pixels": int(pick.sum()),
               "alpha": [float(alpha.min()), float(alpha.max())], "vsgl_count": settings.vsgl_count, "rows": rows}
    figures["cycles_glossy_mean_rgb"] = [float(x) for x in cycles.mean(axis=0)]
    # Per receiver roughness: where each specular mode is the closer to the brute force.
    bins = {}
    for low, high in ALPHA_BINS:
        here = (alpha >= low) & (alpha < high) & (exact > 0.0)
        if here.sum() < 8:
            continue
        bins[f"{low}-{high}"] = {"pixels": int(here.sum()), **{
            key: {"ratio": float((light[key] @ LUMINANCE)[here].sum() / exact[here].sum()),
                  "rel_rmse": float(np.sqrt(np.mean(((light[key] @ LUMINANCE)[here] - exact[here]) ** 2))
                                    / np.mean(exact[here]))}
            for key in ("sg_lobes_asg", "vsgl_product", "vsgl_separable")}}
    figures["alpha_bins"] = bins
    log(f"{name}: " + ", ".join(f"{k} {r['ratio']:.3f} (rel. RMSE {r['rel_rmse']:.3f})" for k, r in rows.items()))
    return figures


DESCRIPTIONS = {
    "exact": "Lambertian VPLs (Φ Rd), exact GGX receiver",
    "sg_lobes": "000 Eq. 6 SG lobes, exact GGX receiver",
    "sg_lobes_asg": "000 Eq. 6 SG lobes, 003 ASG receiver (a VSGL per texel)",
    "vsgl_product": "VSGLs, 000 Eq. 12 product (specular mode \"product\")",
    "vsgl_separable": "VSGLs, separable (specular mode \"separable\")",
}
for _set, _what in (("vsgls", "the frame's diffuse-receiver VSGLs"), ("glossy_vsgls", "the frame's glossy-receiver VSGLs (no proxy specular flux)")):
    for _mode in ("product", "separable"):
        DESCRIPTIONS[f"frame_{_set}_{_mode}"] = f"{_what}, reference, {_mode}, diffuse lobes"
        DESCRIPTIONS[f"frame_{_set}_{_mode}_both_lobes"] = f"{_what}, reference, {_mode}, both lobes"
    DESCRIPTIONS[f"frame_{_set}_gpu"] = f"{_what}, GPU, diffuse lobes"
    DESCRIPTIONS[f"frame_{_set}_gpu_both_lobes"] = f"{_what}, GPU, both lobes"
for _vis in ("on", "off"):
    DESCRIPTIONS[f"render_vsgl_{_vis}"] = f"the rendered frame's indirect specular without MRP-ASG's, visibility {_vis}"
    DESCRIPTIONS[f"render_mrp_{_vis}"] = f"the rendered frame's MRP-ASG part (not from diffuse flux; for scale), visibility {_vis}"


def markdown(all_figures, command):
    lines = ["# The specular receivers' light from diffuse reflectors, split by approximation",
             "", f"`{command}` (float64, no visibility; benchmarks/specular_receiver_split.py's documentation).", "",
             "| scene, material | pixels | GGX α | step | luminance / exact | rel. RMSE per pixel vs exact | mean RGB |",
             "|---|---|---|---|---|---|---|"]
    for f in all_figures:
        for key, r in f["rows"].items():
            label = DESCRIPTIONS.get(key, DESCRIPTIONS.get(key.rsplit("_", 1)[0], key))
            if key not in DESCRIPTIONS:
                label += f", N = {key.rsplit('_', 1)[1]}"
            elif key.startswith("vsgl"):
                label += f", N = {f['vsgl_count']}"
            lines.append(f"| {f['scene']}, {', '.join(f['materials'])} | {f['pixels']} | {f['alpha'][0]:.3f}–{f['alpha'][1]:.3f} | "
                         f"{label} | {r['ratio']:.3f} | {r['rel_rmse']:.3f} | "
                         + " ".join(f"{x:.5f}" for x in r["mean_rgb"]) + " |")
        lines.append(f"| {f['scene']}, {', '.join(f['materials'])} | {f['pixels']} | | Cycles GlossInd·GlossCol (all sources) | | | "
                     + " ".join(f"{x:.5f}" for x in f["cycles_glossy_mean_rgb"]) + " |")
    lines += ["", "Per receiver roughness (luminance / exact, rel. RMSE per pixel vs exact):", "",
              "| scene, material | GGX α | pixels | SG lobes, ASG receiver | VSGLs, Eq. 12 product | VSGLs, separable |",
              "|---|---|---|---|---|---|"]
    for f in all_figures:
        for span, b in f.get("alpha_bins", {}).items():
            cells = " | ".join(f"{b[k]['ratio']:.3f}, {b[k]['rel_rmse']:.3f}"
                               for k in ("sg_lobes_asg", "vsgl_product", "vsgl_separable"))
            lines.append(f"| {f['scene']}, {', '.join(f['materials'])} | {span} | {b['pixels']} | {cells} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", default=["demo"])
    parser.add_argument("--stride", type=int, default=4)
    parser.add_argument("--materials", nargs="+", default=["Glossy gold"])
    parser.add_argument("--counts", type=int, nargs="+", default=[256])
    parser.add_argument("--no-frame", action="store_true",
                        help="only steps 1-5 (not the frame's own VSGL sets and renders)")
    parser.add_argument("--results-dir", type=Path, default=REPO / "benchmarks" / "results")
    args = parser.parse_args(argv)
    from vsgl_addon import register

    register()
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    figures = [split(name, path, args.stride, args.materials, args.counts, not args.no_frame)
               for name, path, _ in suite() if name in args.only]
    command = "benchmarks/specular_receiver_split.py " + " ".join(sys.argv[1:] if argv is None else argv)
    args.results_dir.mkdir(parents=True, exist_ok=True)
    suffix = "_all" if "all" in args.materials else ""
    (args.results_dir / f"specular_receiver_split{suffix}.md").write_text(markdown(figures, command.strip()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
