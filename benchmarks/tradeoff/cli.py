# SPDX-License-Identifier: GPL-3.0-or-later
"""The benchmark's command line, what a run (full or --quick) measures, and the order of its sections."""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass

from . import __doc__ as BENCHMARK_DOC
from .baselines import brute_and_random, cycles_sweep, cycles_time_to, eevee_runs
from .bench import Bench
from .demo import extract, open_demo
from .flicker import change_sweep, flicker
from .memory import measure_memory, memory_child
from .metrics import Errors
from .ours import extremes, fixed_passes, measure_ours, position_cost
from .report import write_report
from .truth import load_reference


@dataclass(frozen=True)
class Plan:
    """What one run measures: the full run or the --quick subset (see the package doc)."""

    quick: bool
    width: int
    height: int
    repeats: int

    @classmethod
    def from_args(cls, args) -> Plan:
        width, height = (int(v) for v in args.resolution.lower().split("x"))
        return cls(args.quick, width, height, args.repeats or (1 if args.quick else 3))

    @property
    def counts(self):
        return [64, 256] if self.quick else [64, 256, 1024, 4096]

    @property
    def ks(self):
        return [1.0] if self.quick else [1.0, 4.0]

    @property
    def rsm_sizes(self):
        return [64] if self.quick else [64, 128, 256]

    @property
    def shared_rsm(self):
        """RSM size of the shared-positions rows and of the position-cost table."""
        return 64 if self.quick else 128

    def configurations(self, default_positions) -> list[tuple]:
        """(kernel, N, K, RSM size, positions) of our sweep, in the table's order."""
        configurations = [("two-vsgl", 2, 1.0, s, default_positions) for s in self.rsm_sizes]
        configurations += [(kernel, n, k, s, default_positions) for s in self.rsm_sizes for k in self.ks
                           for kernel in ("modified", "original") for n in self.counts]
        configurations += [(kernel, n, 1.0, self.shared_rsm, "shared") for kernel in ("modified", "original")
                           for n in self.counts]
        return configurations

    @property
    def cost_n(self):
        return 256 if self.quick else 1024

    @property
    def cost_runs(self):
        return 3 if self.quick else 7

    @property
    def random_seeds(self):
        return [0] if self.quick else [0, 1, 2]

    @property
    def random_rsm(self):
        return 64 if self.quick else 128

    @property
    def extreme_rsm(self):
        return 64 if self.quick else 256

    @property
    def max_cycles_samples(self):
        return 16 if self.quick else 2048

    @property
    def flicker_frames(self):
        return 8 if self.quick else 30

    @property
    def flicker_seeds(self):
        return 4 if self.quick else 16

    @property
    def sweep_configurations(self) -> list[tuple]:
        """(N, K, RSM size, positions) of the change sweeps."""
        if self.quick:
            return [(64, 1.0, 128, "per-lobe"), (256, 1.0, 128, "per-lobe")]
        return [(64, 1.0, 128, "per-lobe"), (256, 1.0, 128, "per-lobe"), (1024, 1.0, 128, "per-lobe"),
                (256, 4.0, 128, "per-lobe"), (256, 1.0, 64, "per-lobe"), (256, 1.0, 256, "per-lobe"),
                (256, 1.0, 128, "shared")]

    @property
    def extra_seeds(self):
        """Lattice seeds besides 0 of the flicker verdict's setting."""
        return range(1, 3) if self.quick else range(1, 5)

    @property
    def memory(self):
        """(image side, N, RSM size) of the peak-memory frame."""
        return (1024, 256, 128) if self.quick else (1024, 4096, 256)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=BENCHMARK_DOC.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a small subset (smoke test, under ~2 min)")
    parser.add_argument("--regenerate-reference", action="store_true", help="render the Cycles truth again")
    parser.add_argument("--resolution", default="240x180", help="image size of every render (default 240x180)")
    parser.add_argument("--reference-samples", type=int, default=4096, help="Cycles samples per seed of the truth")
    parser.add_argument("--reference-only", action="store_true", help="make the cached truth if needed, then stop")
    parser.add_argument("--repeats", type=int, default=None, help="shading runs per figure (median)")
    parser.add_argument("--memory-child", nargs="+", type=int, help=argparse.SUPPRESS)
    return parser.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.memory_child:
        return memory_child(*args.memory_child)

    started = time.perf_counter()
    plan = Plan.from_args(args)
    width, height, quick = plan.width, plan.height, plan.quick
    scene = open_demo()
    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.passes.vsgl_shading import compile_shaders
    from vsgl_addon.settings import VSGLSettings

    renderer_name = ensure_gpu_context()
    description = extract()
    truth = load_reference(scene, width, height, args.reference_samples, args.regenerate_reference)
    if args.reference_only:
        return 0

    fixed, full_frame, demo_settings = fixed_passes(scene, description, width, height)
    bench = Bench(description, width, height)
    compile_shaders()
    errors = Errors(truth, bench.coverage)

    ours, regions, finite = measure_ours(bench, errors, plan.configurations(demo_settings.positional_distribution),
                                         plan.repeats, fixed, demo_settings)
    cost = position_cost(bench, plan.cost_n, plan.shared_rsm, plan.cost_runs)
    brute, random_rows, baseline_finite = brute_and_random(bench, errors, plan.rsm_sizes, plan.random_rsm,
                                                           plan.counts, plan.random_seeds, plan.repeats, fixed)
    finite.update(baseline_finite)
    finite.update(extremes(bench, plan.extreme_rsm))
    bench.free()

    cycles_rows = cycles_sweep(scene, width, height, errors, plan.max_cycles_samples)
    for row in ours:
        row["cycles_time"], row["cycles_qualifier"] = cycles_time_to(cycles_rows, row["rmse"])
    eevee = eevee_runs(scene, width, height, errors, with_raytracing=not quick, renders=1 if quick else 2)

    # Temporal stability at half the image size.
    fw, fh = width // 2, height // 2
    stability = flicker(scene, plan.flicker_frames, fw, fh, with_brute=not quick, seeds=plan.flicker_seeds)
    finite["flicker frames"] = stability["finite"]
    sweeps = [change_sweep(scene, plan.flicker_frames, fw, fh, motion, plan.sweep_configurations)
              for motion in ("pan", "spin")]
    # The verdict's setting with other lattice seeds: a seed is an arbitrary rotation of the lattice
    # (and the original kernel's spikes come and go with it), so the verdict takes the median seed.
    verdict_configuration = (stability["n"], stability["k"], stability["rsm"], VSGLSettings.positional_distribution)
    seed_runs = {motion: [change_sweep(scene, plan.flicker_frames, fw, fh, motion, [verdict_configuration], seed=seed)
                          for seed in plan.extra_seeds] for motion in ("pan", "spin")}
    for run in [*sweeps, *(run for runs in seed_runs.values() for run in runs)]:
        finite[f"{run['motion']} sweep frames, seed {run['seed']}"] = run["finite"]

    mem = measure_memory(*plan.memory)
    finite["1024² render"] = mem["finite"]
    results = {"ours": ours, "regions": regions, "position_cost": cost, "brute": brute, "random": random_rows,
               "cycles": cycles_rows, "eevee": eevee, "flicker": stability, "change_sweeps": sweeps,
               "change_seeds": seed_runs, "memory": mem, "fixed_seconds": fixed, "finite": finite,
               "resolution": [width, height], "renderer": renderer_name, "quick": quick,
               "run_seconds": time.perf_counter() - started}
    write_report(results, plan, truth, errors, full_frame, demo_settings, verdict_configuration)
    return 0
