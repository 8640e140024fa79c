# SPDX-License-Identifier: GPL-3.0-or-later
"""A commit against this checkout in one run (not a benchmark of its own): the commit's files
extracted from git, child processes of a benchmark alternating between the two checkouts round by
round, and the largest image difference between them. Used by light_build_profile.py,
view_passes_profile.py and pass_ab.py; ratios within one run are what the shared machine allows."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Callable

REPO = Path(__file__).resolve().parents[1]


def extract_commit(commit: str, destination: Path, *paths: str) -> Path:
    """`commit`'s tree (or only `paths` of it) written under `destination`, which is returned."""
    destination.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(REPO), "archive", commit, *paths],
                             check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(destination)], input=archive, check=True)
    return destination


def alternate(variants: list[tuple[str, Path]], rounds: int, run: Callable[[str, Path], dict]) -> dict[str, list]:
    """`run(label, repo)` for every variant, `rounds` times, in the order AB BA AB ... so that the
    machine's varying load falls on both; the results per label, in round order."""
    results: dict[str, list] = {label: [] for label, _ in variants}
    for round_index in range(rounds):
        for label, repo in (variants if round_index % 2 == 0 else variants[::-1]):
            results[label].append(run(label, repo))
    return results


def run_child(script: Path, arguments: list[str], python: str, timeout: float, nice: int = 0) -> dict:
    """A child process of `script` whose last line of output is a JSON object: that object."""
    command = (["nice", "-n", str(nice)] if nice else []) + [python, str(script), *arguments]
    output = subprocess.run(command, check=True, capture_output=True, text=True, timeout=timeout).stdout
    return json.loads(output.strip().splitlines()[-1])


def image_difference(old, new, keys) -> dict[str, float]:
    """Per image, the largest absolute difference over the old image's largest value (0: identical)."""
    import numpy as np

    return {key: float(np.max(np.abs(old[key] - new[key])) / max(float(np.max(np.abs(old[key]))), 1e-30))
            for key in keys}
