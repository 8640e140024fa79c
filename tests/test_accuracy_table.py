# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/accuracy.md is current: every figure recomputed by vsgl_addon.reference.measurements.measure()
matches the committed one (numbers compared with a tolerance, not text).

Regenerate with: python -m vsgl_addon.reference.accuracy --write docs/accuracy.md
"""

from __future__ import annotations

import pathlib

import pytest

from vsgl_addon.reference import accuracy, measurements

DOC = pathlib.Path(__file__).resolve().parents[1] / "docs" / "accuracy.md"
# The table prints 4 significant digits; platform differences in exp/log are far below that.
RTOL = 2e-3
REGENERATE = "python -m vsgl_addon.reference.accuracy --write docs/accuracy.md"


@pytest.fixture(scope="module")
def rows():
    return measurements.measure()


@pytest.fixture(scope="module")
def committed():
    return accuracy.parse_markdown(DOC.read_text(encoding="utf-8"))


def _key(row):
    return (row.name, row.parameters, row.metric)


def test_same_rows(rows, committed):
    keys = [_key(r) for r in rows]
    assert len(set(keys)) == len(keys), "row keys must be unique"
    missing = [k for k in keys if k not in committed]
    stale = [k for k in committed if k not in set(keys)]
    assert (
        not missing and not stale
    ), f"docs/accuracy.md rows differ ({REGENERATE}): missing {missing}, stale {stale}"


def test_figures_current(rows, committed):
    wrong = []
    for row in rows:
        value, exact = committed[_key(row)]
        assert exact == row.exact
        if row.exact:
            # Noise of a closed form against the quadrature: only the bound is reproducible.
            if not (row.value <= measurements.EXACT_BOUND and value <= measurements.EXACT_BOUND):
                wrong.append((_key(row), value, row.value))
        elif abs(value - row.value) > RTOL * abs(row.value):
            wrong.append((_key(row), value, row.value))
    assert not wrong, f"stale figures in docs/accuracy.md ({REGENERATE}): {wrong}"


def test_markdown_round_trip(rows):
    parsed = accuracy.parse_markdown(accuracy.to_markdown(rows))
    assert len(parsed) == len(rows)
    for row in rows:
        value, exact = parsed[_key(row)]
        assert exact == row.exact
        assert value == pytest.approx(row.value, rel=1e-3 if not row.exact else 0.1, abs=0.0)


def test_nu_evidence_in_the_table(committed):
    """Which nu is right is settled in the committed table: nu = lam/2 accurate, nu = lam not."""
    table = {k: v for k, (v, _) in committed.items()}
    kappa = [v for (name, _, metric), v in table.items() if name == "SG×ASG convolution, ν = κλ"]
    assert kappa == [pytest.approx(0.5, abs=0.011)]
    half = [
        v
        for (name, params, metric), v in table.items()
        if "ν = λ/2" in name
        and "p = z" in params
        and metric == "max relative error"
        and "[50, 1e4]" in params
    ]
    full = [
        v
        for (name, params, metric), v in table.items()
        if "ν = λ (" in name and "p = z" in params and metric == "max relative error"
    ]
    assert half and full
    assert max(half) < 0.01 < 0.4 < min(full)
