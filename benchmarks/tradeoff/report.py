# SPDX-License-Identifier: GPL-3.0-or-later
"""The report of a run: the markdown table (printed and written), the JSON of every figure and the
plot of frame time against relative RMSE, in ``benchmarks/results/``."""

from __future__ import annotations

import json
import math
import os
import statistics
import time
from pathlib import Path

from .bench import TABLE_CHUNK
from .demo import REPO, RESULTS_DIR, log


def fmt_time(seconds: float) -> str:
    return f"{seconds * 1e3:.1f}" if seconds < 10 else f"{seconds * 1e3:.0f}"


def verdict(ok: bool) -> str:
    return "**PASS**" if ok else "**FAIL**"


def _our_row(ours, n, rsm_size, positions):
    """Our modified-kernel, K = 1 row at (N, RSM size, positions), the one random VPLs are set against."""
    return next((o for o in ours if o["kernel"] == "modified" and o["k"] == 1.0 and o["rsm"] == rsm_size
                 and o["n"] == n and o["positions"] == positions), None)


def _against_random(ours, random_rows, positions) -> list[float]:
    """Our RMSE / random VPLs' RMSE at each random row's N and RSM size (NaN without our row)."""
    ratios = []
    for r in random_rows:
        mine = _our_row(ours, r["n"], r["rsm"], positions)
        ratios.append(mine["rmse"] / r["rmse"] if mine else float("nan"))
    return ratios


def _kernel_ratios(st) -> dict:
    """Modified / original of the flicker section's figures (motion, flicker proper and the motion
    floor only with the decomposition)."""
    ratios = {"change": st["modified"]["change"] / st["original"]["change"],
              "jitter": st["modified"]["jitter"] / st["original"]["jitter"]}
    if "motion" in st["modified"]:
        ratios.update(proper=st["modified"]["flicker"] / st["original"]["flicker"],
                      motion=st["modified"]["motion"] / st["original"]["motion"],
                      floor=st["modified"]["motion"] / st["original"]["change"])
    return ratios


def _header(results, plan, truth, errors, full_frame, blender_version) -> list[str]:
    quick, renderer_name = results["quick"], results["renderer"]
    total_seconds, fixed = results["run_seconds"], results["fixed_seconds"]
    width, height = results["resolution"]
    repeats = plan.repeats
    lines = []
    load = os.getloadavg()[0]
    mode = "QUICK subset" if quick else "full run"
    lines.append(f"# Speed/accuracy of VSGL indirect light on demo.blend ({mode})\n")
    lines.append(f"`benchmarks/speed_accuracy.py{' --quick' if quick else ''}`, {time.strftime('%Y-%m-%d %H:%M')}, "
                 f"GPU `{renderer_name}`, {os.cpu_count()} CPUs (load average {load:.1f}), Blender "
                 f"{blender_version}; images {width}x{height}; run time {total_seconds / 60:.1f} min. "
                 f"Times are wall-clock, GPU finished; shading = median of {repeats}.\n")
    lines.append(f"**Ground truth**: `{truth['path'].relative_to(REPO)}`: Cycles, max bounces 1, "
                 f"{int(truth['samples_per_seed'])} samples × seeds {list(truth['seeds'])} "
                 f"({', '.join(f'{t:.0f}' for t in truth['seconds_per_seed'])} s), pixel filter 0.01 px; "
                 f"mean indirect {errors.mean:.5f} W/(m² sr) over {int(errors.mask.sum())} covered pixels; "
                 f"its own noise RMSE {float(truth['noise_rmse']):.2e} = {100 * float(truth['noise_relative']):.2f} % "
                 f"of the mean.\n")
    lines.append(f"Fixed passes of a frame (scene upload, G-buffer, direct light, read-back; from a FrameRenderer "
                 f"frame with the demo's settings, whole frame {full_frame * 1e3:.0f} ms): {fixed * 1e3:.1f} ms. "
                 f"frame = fixed + RSM/VSGL generation + shading.\n")
    return lines


def _ours_section(results, plan, demo_settings) -> list[str]:
    ours, regions, position_cost = results["ours"], results["regions"], results["position_cost"]
    shared_rsm = plan.shared_rsm
    lines = []
    lines.append("## Ours (VSGLs), against Cycles\n")
    lines.append("RMSE and rel RMSE are noise-corrected (the truth's own noise removed, see the module doc); "
                 "'measured' is the plain relative RMSE against the truth image. Diffuse / specular: against "
                 f"DiffInd·DiffCol / GlossInd·GlossCol (specular is {100 * ours[0]['share_specular']:.0f} % of "
                 "the truth's mean). Cycles time: the time Cycles needs for the same noise-corrected RMSE "
                 "(> : not reached at its largest sample count).\n")
    lines.append("Positions: where each VSGL's lobes sit, per-lobe (the add-on's default) or shared (000 app. B.2 "
                 "as written); see `vsgl_addon/reference/vsgl.py` POSITIONAL_DISTRIBUTIONS.\n")
    lines.append("| kernel | N | K | RSM | positions | RSM+VSGL gen (ms) | shading (ms) | frame (ms) | RMSE | rel RMSE | "
                 "rel RMSE measured | rel RMSE diffuse | rel RMSE specular | mean / Cycles | "
                 "Cycles time to same RMSE (ms) | Cycles time / our frame |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in ours:
        q = r["cycles_qualifier"]
        k_text = "—" if r["kernel"] == "two-vsgl" else f"{r['k']:g}"
        lines.append(f"| {r['kernel']} | {r['n']} | {k_text} | {r['rsm']}² | {r['positions']} | "
                     f"{fmt_time(r['generation'])} | {fmt_time(r['shading'])} | {fmt_time(r['frame'])} | "
                     f"{r['rmse']:.5f} | {r['rel']:.3f} | {r['rel_measured']:.3f} | {r['rel_diffuse']:.3f} | "
                     f"{r['rel_specular']:.3f} | {r['mean_ratio']:.3f} | {q}{fmt_time(r['cycles_time'])} | "
                     f"{q}{r['cycles_time'] / r['frame']:.2f} |")
    lines.append(f"\n**Where the error is** (demo settings: {demo_settings.kernel}, N = {demo_settings.vsgl_count}, "
                 f"K = {demo_settings.k:g}, RSM {demo_settings.rsm_size}²), per material of the covered pixels: "
                 "share of the squared error (noise-corrected), relative RMSE and mean / Cycles on those pixels, "
                 "and the material's share of the truth's indirect light.\n")
    lines.append("| positions | material | pixels | share of squared error | rel RMSE | mean / Cycles | share of light |")
    lines.append("|---|---|---|---|---|---|---|")
    for positions, table in regions.items():
        for name, region in table.items():
            lines.append(f"| {positions} | {name} | {region['pixels']} | {100 * region['error_share']:.1f} % | "
                         f"{region['rel']:.3f} | {region['mean_ratio']:.3f} | {100 * region['light_share']:.1f} % |")
    pc = position_cost
    lines.append(f"\n**What per-lobe positions cost**: one table (modified, N = {pc['n']}, RSM {shared_rsm}², shared "
                 f"positions) shaded {len(pc['once'])} times each way, alternating: position terms once per VSGL "
                 f"(shared) {fmt_time(statistics.median(pc['once']))} ms, once per lobe (per-lobe) "
                 f"{fmt_time(statistics.median(pc['twice']))} ms (medians): ×{pc['ratio']:.3f}.\n")
    return lines


def _baselines_section(results, plan, default_positions) -> list[str]:
    ours, brute, random_rows = results["ours"], results["brute"], results["random"]
    cycles_rows, eevee = results["cycles"], results["eevee"]
    random_rsm, random_seeds = plan.random_rsm, plan.random_seeds
    lines = []
    lines.append("\n## Baselines\n")
    lines.append("**Brute force**: every lit RSM texel a VPL (its own VSGL), the same shading pass "
                 f"(tables of {TABLE_CHUNK} blended).\n")
    lines.append("| RSM | VPLs | RSM render (ms) | shading (ms) | frame (ms) | RMSE | rel RMSE | rel RMSE measured | "
                 "rel RMSE diffuse | rel RMSE specular | mean / Cycles |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|")
    for b in brute:
        lines.append(f"| {b['rsm']}² | {b['vpls']} | {fmt_time(b['rsm_time'])} | {fmt_time(b['shading'])} | "
                     f"{fmt_time(b['frame'])} | {b['rmse']:.5f} | {b['rel']:.3f} | {b['rel_measured']:.3f} | "
                     f"{b['rel_diffuse']:.3f} | "
                     f"{b['rel_specular']:.3f} | {b['mean_ratio']:.3f} |")
    lines.append(f"\n**Random VPLs** at equal shading time (same count, same shader): N texels of the {random_rsm}² RSM "
                 "drawn with replacement from VSGL generation's PDF (luminance of Φ(Rd+Rs)), each scaled by 1/(N p); "
                 f"mean over {len(random_seeds)} seed(s) [min–max]. Against ours: modified kernel, K = 1, "
                 f"RSM {random_rsm}², seed 0, {default_positions} positions (shared, the paper's, as context).\n")
    lines.append("| N | random shading (ms) | VSGL shading (ms) | random rel RMSE | VSGL rel RMSE | VSGL / random RMSE | "
                 "shared positions: VSGL / random RMSE | random mean / Cycles |")
    lines.append("|---|---|---|---|---|---|---|---|")
    ratios = _against_random(ours, random_rows, default_positions)
    shared_ratios = _against_random(ours, random_rows, "shared")
    for r, ratio, shared_ratio in zip(random_rows, ratios, shared_ratios):
        mine = _our_row(ours, r["n"], r["rsm"], default_positions)
        lines.append(f"| {r['n']} | {fmt_time(r['shading'])} | {fmt_time(mine['shading'])} | {r['rel']:.3f} "
                     f"[{r['rel_min']:.3f}–{r['rel_max']:.3f}] | {mine['rel']:.3f} | {ratio:.2f} | "
                     f"{shared_ratio:.2f} | {r['mean_ratio']:.3f} |")
    lines.append("\n**Cycles** at increasing samples (seed 100; render wall time incl. scene sync and EXR write):\n")
    lines.append("| samples | time (ms) | RMSE | rel RMSE | rel RMSE measured | mean / truth |")
    lines.append("|---|---|---|---|---|---|")
    for r in cycles_rows:
        lines.append(f"| {r['samples']} | {fmt_time(r['seconds'])} | {r['rmse']:.5f} | {r['rel']:.3f} | "
                     f"{r['rel_measured']:.3f} | {r['mean_ratio']:.3f} |")
    lines.append(f"\n**EEVEE** ({eevee['samples']} samples as saved; ray tracing as saved: "
                 f"{'on' if eevee['default_raytracing'] else 'off'}, fast GI {'on' if eevee['default_fast_gi'] else 'off'}). "
                 "Indirect = Combined − Combined with every indirect source off (ray tracing and fast GI off; "
                 "the world is black and there are no light probes).\n")
    timed = "second render (ms)" if eevee["renders"] > 1 else "timed render = the first (ms, --quick)"
    lines.append(f"| EEVEE | first render (s) | {timed} | RMSE | rel RMSE | mean / Cycles |")
    lines.append("|---|---|---|---|---|---|")
    lines.append(f"| as saved (defaults) | {eevee['first_seconds']:.1f} | {fmt_time(eevee['seconds'])} | "
                 f"{eevee['default']['rmse']:.5f} | {eevee['default']['rel']:.3f} | {eevee['default']['mean_ratio']:.3f} |")
    if "raytraced" in eevee:
        lines.append(f"| ray tracing + fast GI on | {eevee['rt_first_seconds']:.1f} | {fmt_time(eevee['rt_seconds'])} | "
                     f"{eevee['raytraced']['rmse']:.5f} | {eevee['raytraced']['rel']:.3f} | "
                     f"{eevee['raytraced']['mean_ratio']:.3f} |")
    return lines


def _stability_section(results) -> list[str]:
    st, sweeps = results["flicker"], results["change_sweeps"]
    ratios = _kernel_ratios(st)
    lines = []
    lines.append(f"\n## Temporal stability\n\n{st['frames']} frames, spot turning 1°/frame about world Z, N = {st['n']}, "
                 f"K = {st['k']:g}, RSM {st['rsm']}², seed 0, {st['size'][0]}x{st['size'][1]}. Change = mean "
                 "|I(t) − I(t−1)| over covered pixels and RGB (the target's measure: includes the light's real motion); "
                 "jitter = mean |I(t+1) − 2 I(t) + I(t−1)| (second difference: a change smooth in time cancels, "
                 "jumps remain). Context rows: 2-VSGL, and brute force = every texel of a "
                 f"{st['brute_rsm']}² RSM as a VPL.\n")
    decomposed = "motion" in st["modified"]
    if decomposed:
        lines.append(f"Decomposition (context, not the verdict's measure): each frame of the two kernel modes is also "
                     f"rendered with lattice seeds 1..{st['seeds']}; their mean Ī(t) estimates the mode's expected "
                     "image over the random lattice rotation (its converged image, its blur included). Motion = mean "
                     "|Ī(t) − Ī(t−1)| (the real change of the lighting as that mode sees it); flicker proper = mean "
                     "|e(t) − e(t−1)| with e = I − Ī, the seed-0 image's deviation from its seed average. Ī keeps a "
                     f"residual sampling error of 1/√{st['seeds']} of one seed's; seed 0 is not in Ī, so e has "
                     f"{st['error_variance_factor']:.4f}× the variance of I's own error (flicker proper reads high by "
                     f"about √ of that, {math.sqrt(st['error_variance_factor']):.3f}×, the same for both modes: it "
                     f"cancels in their ratio; not rescaled). Decomposition time: {st['seed_average_seconds']:.0f} s "
                     f"of the section's {st['seconds']:.0f} s.\n")
        lines.append("| | mean change | change / mean indirect | jitter | jitter / mean indirect | motion | "
                     "motion / mean indirect | flicker proper | flicker proper / mean indirect |")
        lines.append("|---|---|---|---|---|---|---|---|---|")
    else:
        lines.append("| | mean change | change / mean indirect | jitter | jitter / mean indirect |")
        lines.append("|---|---|---|---|---|")
    for name in ("modified", "original", "two-vsgl", "brute"):
        if name in st:
            row = (f"| {name} | {st[name]['change']:.3e} | {100 * st[name]['relative']:.2f} % | "
                   f"{st[name]['jitter']:.3e} | {100 * st[name]['jitter_relative']:.2f} % |")
            if decomposed:
                row += (f" {st[name]['motion']:.3e} | {100 * st[name]['motion_relative']:.2f} % | "
                        f"{st[name]['flicker']:.3e} | {100 * st[name]['flicker_relative']:.2f} % |"
                        if "motion" in st[name] else " — | — | — | — |")
            lines.append(row)
    lines.append(f"\nModified / original: change {ratios['change']:.2f}, jitter {ratios['jitter']:.2f}.\n")
    if decomposed:
        lines.append(f"Flicker proper (deviation from the seed-averaged image), modified / original: "
                     f"{ratios['proper']:.2f} (motion {ratios['motion']:.2f}; S = {st['seeds']} seeds).\n")
        floor = ratios["floor"]
        lines.append(f"Motion floor: the modified kernel's motion alone is {floor:.2f}× the original kernel's whole "
                     "change. The seed-0 image is Ī + e with e of zero mean over the lattice rotation, so by Jensen's "
                     "inequality its expected change per pixel is at least |Ī(t) − Ī(t−1)|: on this turn the modified "
                     f"kernel's change ratio cannot be expected below {floor:.2f} however little it flickers (it would "
                     "take less flicker from the original kernel or less real motion to go lower).\n")
        lines.append(f"Mean |I − Ī| per frame (the seed-0 image's deviation from its seed average): modified "
                     f"{st['modified']['deviation']:.3e}, original {st['original']['deviation']:.3e}; the two modes' "
                     f"seed-averaged images differ by {st['expected_gap']:.3e} = "
                     f"{100 * st['expected_gap_relative']:.2f} % of the mean indirect (their different blur).\n")
    lines.append("**The flicker target's measure across N, K and RSM size, and for a turn that does not move the light**, "
                 "same frames, seed 0: *pan* is the turn above (about world Z: the "
                 "lit spot moves, so every image has the lighting's real motion in it); *spin* turns the spot 1°/frame "
                 "about its own cone axis: its cone is round, so the lighting is the same in every frame and every "
                 "change is flicker (the RSM, its PDF and so the kernels rotate under the fixed lattice: the dynamic "
                 "PDF of 000 §4). 2-VSGL has no lattice and no kernels: its change is the RSM's own rasterization of "
                 "the turned light (and, in the pan, the real motion). K > 1 blurs more and flickers less (000 §4).\n")
    lines.append("| turn | N | K | RSM | positions | 2-VSGL change / mean indirect (no sampling) | modified change "
                 "/ mean indirect | original change / mean indirect | modified / original |")
    lines.append("|---|---|---|---|---|---|---|---|---|")
    for sweep in sweeps:
        for row in sweep["rows"]:
            lines.append(f"| {sweep['motion']} | {row['n']} | {row['k']:g} | {row['rsm']}² | {row['positions']} | "
                         f"{100 * row['two-vsgl']['relative']:.2f} % | {100 * row['modified']['relative']:.2f} % | "
                         f"{100 * row['original']['relative']:.2f} % | {row['ratio']:.2f} |")
    lines.append("")
    return lines


def _memory_section(results) -> list[str]:
    mem = results["memory"]
    lines = []
    lines.append(f"## Peak memory\n\nFresh process, FrameRenderer at {mem['size']}² with N = {mem['n']} "
                 f"(RSM {mem['rsm']}²): peak RSS {mem['peak_kb'] / 1024:.0f} MB (VmHWM, the whole process from its "
                 f"start; getrusage's ru_maxrss reads {mem.get('ru_maxrss_kb', 0) / 1024:.0f} MB because after fork + "
                 f"exec it keeps the forking parent's high-water mark); high-water mark before the render "
                 f"{mem['before_kb'] / 1024:.0f} MB (bpy, demo.blend, GPU context); resident "
                 f"{mem['rss_before_kb'] / 1024:.0f} MB before, {mem['rss_after_kb'] / 1024:.0f} MB after the frame; "
                 f"frame {mem['seconds']:.1f} s.\n")
    return lines


def _targets_section(results, plan, demo_settings, verdict_configuration) -> list[str]:
    ours, random_rows, eevee, mem, finite = (results[name] for name in ("ours", "random", "eevee", "memory", "finite"))
    st, sweeps, seed_runs = results["flicker"], results["change_sweeps"], results["change_seeds"]
    default_positions = demo_settings.positional_distribution
    ratios = _against_random(ours, random_rows, default_positions)
    shared_ratios = _against_random(ours, random_rows, "shared")
    kernel_ratios = _kernel_ratios(st)
    jitter_ratio, proper_ratio, motion_floor = (kernel_ratios.get(name) for name in ("jitter", "proper", "floor"))
    extra_seeds = plan.extra_seeds
    lines = []
    demo_row = next((o for o in ours if o["kernel"] == demo_settings.kernel and o["n"] == demo_settings.vsgl_count
                     and o["k"] == demo_settings.k and o["rsm"] == demo_settings.rsm_size
                     and o["positions"] == default_positions), None)
    if demo_row is None:
        demo_row = next(o for o in ours if o["kernel"] == "modified" and o["n"] == 256 and o["k"] == 1.0)
    lines.append("## Targets\n")
    lines.append("| target | figure | verdict |")
    lines.append("|---|---|---|")
    lines.append(f"| mean indirect within 10 % of Cycles | demo settings ({demo_row['kernel']}, N = {demo_row['n']}, "
                 f"K = {demo_row['k']:g}, RSM {demo_row['rsm']}²): mean / Cycles = {demo_row['mean_ratio']:.3f}; "
                 f"all our rows {min(o['mean_ratio'] for o in ours):.3f}–{max(o['mean_ratio'] for o in ours):.3f} | "
                 f"{verdict(abs(demo_row['mean_ratio'] - 1) <= 0.10)} |")
    worst = max(ratios) if ratios else float("nan")
    per_n = ", ".join(f"{r['n']}: {x:.2f}" for r, x in zip(random_rows, ratios))
    per_n_shared = ", ".join(f"{r['n']}: {x:.2f}" for r, x in zip(random_rows, shared_ratios))
    lines.append(f"| VSGL RMSE ≤ 0.6× random VPLs at equal time | VSGL / random RMSE per N "
                 f"({per_n}); worst {worst:.2f} ({default_positions} positions; with the paper's shared "
                 f"positions: {per_n_shared}) | "
                 f"{verdict(bool(ratios) and worst <= 0.6)} |")
    # The flicker target's measure for both readings of "a light turning 1° per frame" at the flicker section's
    # settings: the pan (real motion in every image) and the spin (no real motion: all change is flicker).
    def sweep_text(motion):
        sweep = next(sweep for sweep in sweeps if sweep["motion"] == motion)
        return ", ".join(f"(N {r['n']}, K {r['k']:g}, RSM {r['rsm']}², {r['positions']}): {r['ratio']:.2f}"
                         for r in sweep["rows"] if (r["n"], r["k"], r["rsm"], r["positions"]) != verdict_configuration)

    def seed_ratios(motion):
        """The verdict setting's ratio per lattice seed, seed 0 (the sweep's) first."""
        seed_0 = next(r for sweep in sweeps if sweep["motion"] == motion for r in sweep["rows"]
                      if (r["n"], r["k"], r["rsm"], r["positions"]) == verdict_configuration)
        return [seed_0["ratio"]] + [run["rows"][0]["ratio"] for run in seed_runs[motion]]

    seed_names = f"seeds 0–{len(extra_seeds)}"
    pan_ratios, spin_ratios = seed_ratios("pan"), seed_ratios("spin")
    pan_median, spin_median = statistics.median(pan_ratios), statistics.median(spin_ratios)
    proper_text = (f"; flicker proper (deviation from the {st['seeds']}-seed average) ratio {proper_ratio:.2f}; "
                   f"motion floor {motion_floor:.2f}: no renderer with the "
                   "modified kernel's expected image can be expected below it on this turn"
                   if proper_ratio is not None else "")
    settings_text = f"N = {st['n']}, K = {st['k']:g}, RSM {st['rsm']}²"
    lines.append(f"| modified flicker ≤ 0.7× original: turn about world Z (pan; the lighting's real motion is in "
                 f"the measure) | mean frame-to-frame change ratio at {settings_text}, median over lattice "
                 f"{seed_names}: {pan_median:.2f} ({', '.join(f'{x:.2f}' for x in pan_ratios)}); at seed 0 second-"
                 f"difference jitter ratio {jitter_ratio:.2f}{proper_text}; other settings, seed 0: "
                 f"{sweep_text('pan')} | {verdict(pan_median <= 0.7)} |")
    lines.append(f"| modified flicker ≤ 0.7× original: turn about the cone axis (spin; the lighting does not "
                 f"change, all change is flicker) | mean frame-to-frame change ratio at {settings_text}, median over "
                 f"lattice {seed_names}: {spin_median:.2f} ({', '.join(f'{x:.2f}' for x in spin_ratios)}); other "
                 f"settings, seed 0: {sweep_text('spin')} | {verdict(spin_median <= 0.7)} |")
    faster = demo_row["frame"] < eevee["seconds"]
    lower = demo_row["rmse"] < eevee["default"]["rmse"]
    lines.append(f"| faster than EEVEE with lower indirect RMSE | demo settings frame {fmt_time(demo_row['frame'])} ms vs "
                 f"EEVEE {fmt_time(eevee['seconds'])} ms; RMSE {demo_row['rmse']:.5f} vs {eevee['default']['rmse']:.5f} "
                 f"(EEVEE defaults give no indirect here) | {verdict(faster and lower)} |")
    target_memory = mem["size"] == 1024 and mem["n"] == 4096
    lines.append(f"| peak memory ≤ 2 GB at 1024², N = 4096 | {mem['peak_kb'] / 1024:.0f} MB at {mem['size']}², "
                 f"N = {mem['n']} | {verdict(mem['peak_kb'] <= 2 * 1024 * 1024) if target_memory else 'not run (--quick)'} |")
    bad = [name for name, ok in finite.items() if not ok]
    lines.append(f"| no NaN/Inf in any output | {len(finite)} raw outputs checked (sweep, baselines, extremes, "
                 f"flicker, 1024²): {'none bad' if not bad else 'bad: ' + ', '.join(bad)} | {verdict(not bad)} |")
    return lines


def write_report(results, plan, truth, errors, full_frame, demo_settings, verdict_configuration) -> None:
    """Write ``speed_accuracy{,_quick}.{md,json,png}`` and print the markdown."""
    import bpy

    quick = results["quick"]
    width, height = results["resolution"]
    renderer_name = results["renderer"]
    lines = _header(results, plan, truth, errors, full_frame, bpy.app.version_string)
    lines += _ours_section(results, plan, demo_settings)
    lines += _baselines_section(results, plan, demo_settings.positional_distribution)
    lines += _stability_section(results)
    lines += _memory_section(results)
    lines += _targets_section(results, plan, demo_settings, verdict_configuration)
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    stem = "speed_accuracy_quick" if quick else "speed_accuracy"
    png = RESULTS_DIR / f"{stem}.png"
    lines.append(f"\nPlot: `{png.relative_to(REPO)}`.\n")
    text = "\n".join(lines)
    (RESULTS_DIR / f"{stem}.md").write_text(text + "\n", encoding="utf-8")
    (RESULTS_DIR / f"{stem}.json").write_text(json.dumps(results, indent=1, default=str) + "\n", encoding="utf-8")
    plot(png, results["ours"], results["brute"], results["random"], results["cycles"], results["eevee"],
         f"demo.blend {width}x{height}, indirect vs Cycles (1 bounce); {renderer_name.split(' (')[0]}, "
         f"{os.cpu_count()} CPUs" + (" — QUICK" if quick else ""))
    print(text)
    log(f"done in {results['run_seconds'] / 60:.1f} min: {RESULTS_DIR.relative_to(REPO)}/{stem}.md, {png.name}")


def plot(path: Path, ours, brute, random_rows, cycles_rows, eevee, title):
    """Frame time against noise-corrected relative RMSE, log-log. Our lines at the middle RSM size
    (one per kernel and K, the default per-lobe positions); the other RSM sizes as faint markers;
    the paper's shared positions (K = 1) as dash-dot lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(11, 7), dpi=110)
    shared = [r for r in ours if r.get("positions") == "shared"]
    ours = [r for r in ours if r.get("positions") != "shared"]
    sizes = sorted({r["rsm"] for r in ours if r["kernel"] != "two-vsgl"})
    main_size = 128 if 128 in sizes else sizes[0]
    styles = {("modified", 1.0): ("tab:blue", "-", "o"), ("original", 1.0): ("tab:orange", "-", "s"),
              ("modified", 4.0): ("tab:blue", ":", "o"), ("original", 4.0): ("tab:orange", ":", "s")}
    for (kernel, k), (color, line, marker) in styles.items():
        rows = sorted((r for r in ours if r["kernel"] == kernel and r["k"] == k and r["rsm"] == main_size),
                      key=lambda r: r["n"])
        if not rows:
            continue
        ax.plot([r["rel"] for r in rows], [r["frame"] for r in rows], line, marker=marker, color=color, ms=6,
                label=f"VSGL {kernel}, K={k:g}, RSM {main_size}²")
        if k == 1.0 and kernel == "modified":
            for r in rows:
                ax.annotate(f"N={r['n']}", (r["rel"], r["frame"]), textcoords="offset points", xytext=(-46, -3),
                            fontsize=8, color=color)
        others = [r for r in ours if r["kernel"] == kernel and r["k"] == k and r["rsm"] != main_size]
        if others:
            ax.plot([r["rel"] for r in others], [r["frame"] for r in others], marker, color=color, alpha=0.3, ms=4,
                    mfc="none", label=None)
    for kernel, color, marker in (("modified", "tab:blue", "o"), ("original", "tab:orange", "s")):
        rows = sorted((r for r in shared if r["kernel"] == kernel), key=lambda r: r["n"])
        if rows:
            ax.plot([r["rel"] for r in rows], [r["frame"] for r in rows], "-.", marker=marker, color=color, ms=5,
                    alpha=0.6, mfc="white",
                    label=f"VSGL {kernel}, K=1, RSM {rows[0]['rsm']}², shared positions (000 app. B.2)")
    if len(sizes) > 1:
        ax.plot([], [], "o", color="grey", alpha=0.4, mfc="none",
                label=f"VSGL, RSM {', '.join(f'{x}²' for x in sizes if x != main_size)} (faint)")
    two = [r for r in ours if r["kernel"] == "two-vsgl"]
    if two:
        ax.plot([r["rel"] for r in two], [r["frame"] for r in two], "D", color="tab:purple", label="2-VSGL (003)")
    if brute:
        ax.plot([b["rel"] for b in brute], [b["frame"] for b in brute], "P-", color="black", ms=8,
                label="brute force: every RSM texel a VPL")
        for b in brute:
            ax.annotate(f"RSM {b['rsm']}²", (b["rel"], b["frame"]), textcoords="offset points", xytext=(-58, -3),
                        fontsize=8)
    if random_rows:
        ax.plot([r["rel"] for r in random_rows], [r["frame"] for r in random_rows], "x--", color="tab:red", ms=8,
                label=f"random VPLs (same PDF, RSM {random_rows[0]['rsm']}²)")
        for r in random_rows:
            ax.annotate(f"N={r['n']}", (r["rel"], r["frame"]), textcoords="offset points", xytext=(7, 0),
                        fontsize=8, color="tab:red")
    if cycles_rows:
        ax.plot([r["rel"] for r in cycles_rows], [r["seconds"] for r in cycles_rows], "^-", color="tab:green",
                label="Cycles (1 bounce), samples ×2")
        for r in cycles_rows:
            ax.annotate(f"{r['samples']} spp", (r["rel"], r["seconds"]), textcoords="offset points", xytext=(4, 5),
                        fontsize=7, color="tab:green")
    if eevee:
        ax.plot([eevee["default"]["rel"]], [eevee["seconds"]], "*", color="tab:brown", ms=14,
                label="EEVEE as saved (no indirect here)")
        if "raytraced" in eevee:
            ax.plot([eevee["raytraced"]["rel"]], [eevee["rt_seconds"]], "*", color="tab:olive", ms=14,
                    label="EEVEE, ray tracing + fast GI on")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("indirect relative RMSE against Cycles' 1-bounce truth (noise-corrected RMSE / mean)")
    ax.set_ylabel("frame time (s)   [VSGL: fixed passes + RSM/VSGLs + shading]")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
