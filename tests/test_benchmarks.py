# SPDX-License-Identifier: GPL-3.0-or-later
"""The README's benchmarks still run (smoke tests: small subsets; the figures are the benchmarks' job)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _run(*arguments, timeout):
    return subprocess.run([sys.executable, *map(str, arguments)], cwd=REPO, capture_output=True, text=True,
                          timeout=timeout)


def test_vsgl_generation_benchmark_prints_its_table():
    result = _run("benchmarks/vsgl_generation.py", "--repeats", 1, "--counts", 64, "--sizes", 64, timeout=300)
    assert result.returncode == 0, result.stderr
    assert "| RSM | N |" in result.stdout and "overhead" in result.stdout


def test_vsgl_shading_cost_benchmark_prints_its_table_and_ratios():
    result = _run("benchmarks/vsgl_shading_cost.py", "--repeats", 1, timeout=300)
    assert result.returncode == 0, result.stderr
    assert "| 256² | 1024 |" in result.stdout and "4× the VSGLs" in result.stdout


def test_pass_ab_runs_vsgl_shadings_four_variants_against_heads_glsl():
    result = _run("benchmarks/pass_ab.py", "--pass", "vsgl_shading", "--old", "HEAD", "--scenes", "demo", "--size", 32,
                  "--repeats", 1, "--vsgl-count", 64, timeout=300)
    assert result.returncode == 0, result.stderr
    rows = [line for line in result.stdout.splitlines() if line.startswith("| demo |")]
    assert [row.split(" | ")[1] for row in rows] == [f"visibility {v}, {p}" for v in ("off", "on")
                                                     for p in ("per-lobe", "shared")]
    assert all(row.endswith("| True |") for row in rows), result.stdout  # finite
    glsl_clean = subprocess.run(["git", "diff", "--quiet", "HEAD", "--", "glsl"], cwd=REPO).returncode == 0
    if glsl_clean:  # the same GLSL on both sides
        assert all(row.endswith("| True | True |") for row in rows), result.stdout


def test_speed_accuracy_benchmark_quick_run_writes_table_plot_and_targets():
    # The quick run writes into the repository (benchmarks/results/*_quick.*, gitignored): remove
    # what an earlier run left there first, so that only this run's files can pass the checks.
    results = REPO / "benchmarks" / "results"
    for name in ("speed_accuracy_quick.md", "speed_accuracy_quick.json", "speed_accuracy_quick.png"):
        (results / name).unlink(missing_ok=True)
    result = _run("benchmarks/speed_accuracy.py", "--quick", timeout=900)
    assert result.returncode == 0, result.stderr
    table = (results / "speed_accuracy_quick.md").read_text()
    assert "Targets" in table and ("PASS" in table or "FAIL" in table)
    assert "Flicker proper (deviation from the seed-averaged image), modified / original:" in table
    assert "turn about the cone axis (spin" in table and "Motion floor:" in table
    assert "| spin | 256 | 1 | 128² | per-lobe |" in table
    figures = json.loads((results / "speed_accuracy_quick.json").read_text())
    stability = figures["flicker"]
    assert stability["seeds"] == 4
    for mode in ("modified", "original"):
        assert {"motion", "motion_relative", "flicker", "flicker_relative"} <= set(stability[mode])
    sweeps = {sweep["motion"]: sweep for sweep in figures["change_sweeps"]}
    assert set(sweeps) == {"pan", "spin"}
    # The sweep's pan at N = 256 renders the verdict's frames again (seed 0): the same figure, up to
    # llvmpipe's float32 (measured 5e-5 relative).
    pan_256 = next(row for row in sweeps["pan"]["rows"]
                   if (row["n"], row["k"], row["rsm"], row["positions"]) == (256, 1, 128, "per-lobe"))
    for mode in ("modified", "original"):
        assert abs(pan_256[mode]["change"] - stability[mode]["change"]) <= 1e-3 * stability[mode]["change"]
    assert (results / "speed_accuracy_quick.png").stat().st_size > 10_000


def test_validation_suite_quick_run_writes_its_table():
    # Two scenes against their committed truths (nothing is rendered by Cycles); the quick files are
    # gitignored, removed first so that only this run's can pass.
    results = REPO / "benchmarks" / "results"
    for name in ("validation_suite_quick.md", "validation_suite_quick.json"):
        (results / name).unlink(missing_ok=True)
    result = _run("benchmarks/validation_suite.py", "--quick", timeout=120)
    assert result.returncode == 0, result.stderr
    table = (results / "validation_suite_quick.md").read_text()
    assert "| scene | mean ours / Cycles | rel RMSE | rel RMSE plain | robust rel RMSE |" in table
    rows = json.loads((results / "validation_suite_quick.json").read_text())["scenes"]
    assert [row["scene"] for row in rows] == ["occluder", "cornell_box"]
    for row in rows:
        assert row["finite"] and 0.0 < row["mean_ratio"] < 10.0
        assert f"| {row['scene']} | {row['mean_ratio']:.3f} |" in table


def test_tradeoff_suite_quick_run_writes_table_plot_and_targets():
    # One scene against its committed truth, the cost model calibrated into a fresh temporary cache
    # (never the user's); the quick files are gitignored, removed first so only this run's can pass.
    results = REPO / "benchmarks" / "results"
    for name in ("tradeoff_suite_quick.md", "tradeoff_suite_quick.json", "tradeoff_suite_quick.png"):
        (results / name).unlink(missing_ok=True)
    result = _run("benchmarks/tradeoff_suite.py", "--quick", timeout=120)
    assert result.returncode == 0, result.stderr
    table = (results / "tradeoff_suite_quick.md").read_text()
    assert "| configuration | N | RSM | δ | interleave | scale | frame (ms) | rel RMSE |" in table
    assert "## Targets" in table and "- **occluder**: Auto " in table
    figures = json.loads((results / "tradeoff_suite_quick.json").read_text())
    (scene,) = figures["scenes"]
    assert scene["scene"] == "occluder" and {row["label"] for row in scene["manual"]} >= {"VSGL only", "+ visibility"}
    for row in [scene["auto"], *scene["manual"], *scene["budget"]]:
        assert row["finite"] and row["rel"] > 0.0 and row["seconds"] > 0.0
    (budget,) = scene["budget"]
    assert budget["target_ms"] > 0.0 and budget["predicted_ms"] > 0.0
    # Cycles' error falls as 1/sqrt(samples) from its truth's noise.
    rows = scene["cycles"]["rows"]
    assert rows[0]["rel"] / rows[1]["rel"] == pytest.approx(2.0)
    assert (results / "tradeoff_suite_quick.png").stat().st_size > 10_000


def test_budget_error_terms_fit_recovers_the_slopes_it_was_made_with():
    """benchmarks/budget_error_terms.py's fit on made-up scenes (no rendering): each scene's error is
    its base error times 1 + the term weights times the feature moves, so every slope comes back,
    the RSM's also under its scene's kind, and the medians in budget.py's units."""
    sys.path.insert(0, str(REPO / "benchmarks"))
    try:
        import budget_error_terms as T
    finally:
        sys.path.remove(str(REPO / "benchmarks"))
    from vsgl_addon.budget import ERROR_WEIGHTS

    def scene(name, base, weights, vpl_pass, orthographic):
        at_base = T.features(T.BASE, vpl_pass)
        rows = []
        grids = (T.GRID, T.VPL_GRID) if vpl_pass else (T.GRID,)
        for point in [dict(T.BASE)] + [dict(T.BASE, **{k: v}) for grid in grids
                                       for k, values in grid.items() for v in values]:
            moved = [a - b for a, b in zip(T.features(point, vpl_pass), at_base)]
            rows.append({**point, "rel": base * (1.0 + sum(w * m for w, m in zip(weights, moved)))})
        return {"scene": name, "vpl_pass": vpl_pass, "orthographic": orthographic, "rows": rows}

    results = [scene("local", 0.2, (8.0, 0.5, 0.0, 0.1), False, False),
               scene("sun", 0.4, (6.0, 40.0, 0.0, 0.2), False, True),
               scene("caustics", 0.1, (10.0, 12.0, 0.02, 1.0), True, False)]
    slopes = {r["scene"]: T.slopes(r) for r in results}
    assert slopes["local"]["rsm"] == slopes["local"]["rsm_local"] == pytest.approx(0.5)
    assert "rsm_orthographic" not in slopes["local"]
    assert slopes["sun"]["rsm_orthographic"] == pytest.approx(40.0)
    assert slopes["caustics"]["rsm_vpls"] == pytest.approx(12.0) and slopes["caustics"]["vpls"] == pytest.approx(0.02)
    fitted = T.fit(results)
    assert fitted["vsgls"]["median"] == pytest.approx(8.0) and fitted["rsm"]["median"] == pytest.approx(12.0)
    assert fitted["vsgls"]["weight"] == pytest.approx(ERROR_WEIGHTS["vsgls"])
    assert fitted["scale"]["weight"] == pytest.approx(0.2 * ERROR_WEIGHTS["vsgls"] / 8.0)
    text = T.markdown(results, fitted, "budget_error_terms.py", 1.0)
    assert "| rsm_orthographic | sun 40 | 40 |" in text


def test_cost_model_fit_recovers_the_model_its_frames_were_timed_with():
    """benchmarks/cost_model_fit.py's fit and table on made-up frames (no rendering): frames timed
    with known coefficients give a refitted model that predicts them (ratio 1.00) and a table with
    the VPL pass's interleave rows."""
    sys.path.insert(0, str(REPO / "benchmarks"))
    try:
        import cost_model_fit as T
    finally:
        sys.path.remove(str(REPO / "benchmarks"))
    import numpy as np

    from vsgl_addon import budget as B

    rng = np.random.default_rng(2)
    truth = {step: [2.0 * v + 1e-3 for v in values] for step, values in B.FALLBACK_COEFFICIENTS.items()}
    samples = []
    for _ in range(40):
        features = {step: rng.uniform(0.1, 5.0, len(names)).tolist() for step, names in B.STEP_FEATURES.items()}
        samples.append({"features": features,
                        "timings": {step: float(np.dot(truth[step], f)) for step, f in features.items()}})
    sweep = [{"interleave": n, "vpl_pass_ms": 100.0 / int(n), "vpls": 10, "features": [1.0, 4.0 / int(n) ** 2, 2.0]}
             for n in T.INTERLEAVES]
    results = [{"scene": "made_up", "vpl_pass": True, "samples": samples, "sweep": sweep}]
    refitted = B.fit(samples)
    assert np.median(T.ratios(refitted, samples)) == pytest.approx(1.0, abs=0.01)
    assert np.median(T.ratios(dict(B.FALLBACK_COEFFICIENTS), samples)) < 0.7
    text = T.markdown(results, dict(B.FALLBACK_COEFFICIENTS), refitted, "cost_model_fit.py", 1.0)
    assert "| made_up | 10 | 8 | 12 | 0.12 |" in text and '"vpl_culling": (' in text


@pytest.mark.parametrize("application", ["bpy", "real-blender"])
def test_resolve_weights_benchmark_times_each_piece_and_finds_kept_weights_bit_identical(application):
    extra = ["--real-blender"] if application == "real-blender" else []
    result = _run("benchmarks/resolve_weights.py", "--scenes", "demo", "--rounds", 1, "--repeats", 1, "--no-write",
                  *extra, timeout=600)
    assert result.returncode == 0, result.stderr
    row = json.loads(result.stdout.strip().splitlines()[-1])
    assert row["scene"] == "demo"
    assert set(row["current"]) >= {"one_pass", "weights", "with_kept_weights", "identical"}
    assert row["current"]["identical"] is True


def test_budget_coarse_prediction_benchmark_reports_the_switchs_coarse_image():
    result = _run("benchmarks/budget_coarse_prediction.py", "--scenes", "demo", "--rounds", 1, "--repeats", 1,
                  "--no-write", timeout=600)
    assert result.returncode == 0, result.stderr
    row = json.loads(result.stdout.strip().splitlines()[-1])
    current = row["current"]
    assert row["scene"] == "demo" and current["steps"] == 1 and len(current["sizes"]) == 1
    # The cost model's prediction is of the view render it sized, in the same units as the measurement.
    assert 0.0 < current["predicted"] < 1000.0 and 0.0 < current["view"] <= current["step"]
