# SPDX-License-Identifier: GPL-3.0-or-later
"""A commit against this checkout in one run (not a benchmark of its own): the commit's files
extracted from git, child processes of a benchmark alternating between the two checkouts round by
round, and the largest image difference between them. Used by light_build_profile.py,
view_passes_profile.py, first_coarse_image.py and pass_ab.py; ratios within one run are what the
shared machine allows."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Callable

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "benchmarks" / "results"


def scene_path(name: str) -> Path:
    """demo.blend or a validation scene's .blend of this checkout (every variant opens the same file)."""
    return REPO / "demo.blend" if name == "demo" else REPO / "benchmarks" / "scenes" / f"{name}.blend"


def open_scene(repo: Path, name: str):
    """In a child process: the add-on imported from ``repo`` (before any other checkout's), registered
    on a GPU context, the scene opened; (bpy, the scene's saved settings, its first light)."""
    sys.path.insert(0, str(repo))
    import bpy

    from vsgl_addon import register
    from vsgl_addon.gpu_context import ensure_gpu_context
    from vsgl_addon.settings import VSGLSettings

    ensure_gpu_context()
    register()
    bpy.ops.wm.open_mainfile(filepath=str(scene_path(name)), load_ui=False)
    settings = VSGLSettings.from_properties(bpy.context.scene.vsgl)
    light = next(o for o in bpy.context.scene.objects if o.type == "LIGHT")
    return bpy, settings, light


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


#: run_child's ``python`` for a child in Blender 5.2 without its window (``real-blender run -b``;
#: the child reads its arguments after ``--``, see child_arguments): the application the artist runs
#: instead of the bpy module.
REAL_BLENDER = "real-blender"


def child_arguments(argv=None):
    """A child's own command line: ``argv``, or in Blender (``--python SCRIPT -- ARGS``) the ARGS."""
    if argv is not None:
        return argv
    return sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]


def run_child(script: Path, arguments: list[str], python: str, timeout: float, nice: int = 0) -> dict:
    """A child process of `script` whose last line of output that is a JSON object: that object.
    ``python`` REAL_BLENDER runs the script in Blender 5.2 (real-blender run -b)."""
    if python == REAL_BLENDER:
        tool = Path(os.environ.get("REAL_BLENDER") or REPO.parent / "shared" / "tools" / "real-blender")
        launcher = [str(tool), "run", "-b", "--factory-startup", "--python", str(script), "--"]
        environment = {key: value for key, value in os.environ.items() if not key.startswith("BLENDER_")}
    else:
        launcher, environment = [python, str(script)], None
    command = (["nice", "-n", str(nice)] if nice else []) + launcher + list(arguments)
    output = subprocess.run(command, check=True, capture_output=True, text=True, timeout=timeout,
                            env=environment).stdout
    return json.loads(next(line for line in reversed(output.strip().splitlines()) if line.startswith("{")))


def image_difference(old, new, keys) -> dict[str, float]:
    """Per image, the largest absolute difference over the old image's largest value (0: identical)."""
    import numpy as np

    return {key: float(np.max(np.abs(old[key] - new[key])) / max(float(np.max(np.abs(old[key]))), 1e-30))
            for key in keys}


def add_scene_arguments(parser: argparse.ArgumentParser, scenes, repeats: int, repeats_help: str) -> None:
    """The command line of a per-scene benchmark against ``--baseline``, and its child's hidden one."""
    parser.add_argument("--scenes", nargs="*", default=list(scenes))
    parser.add_argument("--repeats", type=int, default=repeats, help=repeats_help)
    parser.add_argument("--rounds", type=int, default=2, help="processes per checkout and scene")
    parser.add_argument("--baseline", default=None, help="a commit to measure in the same run")
    parser.add_argument("--no-write", action="store_true")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--repo", type=Path, default=REPO, help=argparse.SUPPRESS)
    parser.add_argument("--image", type=Path, default=None, help=argparse.SUPPRESS)


def run_as_child(arguments, measure: Callable) -> bool:
    """With ``--child SCENE``: print ``measure(repo, scene, repeats, image path)`` as the child's JSON
    line (run_child reads it) and say so."""
    if arguments.child is None:
        return False
    print(json.dumps(measure(arguments.repo, arguments.child, arguments.repeats, arguments.image)))
    return True


def compare_scenes(script: Path, arguments, medians: Callable, summary: Callable, image_keys: Callable,
                   timeout: float, nice: int = 0, pair_ratios: Callable | None = None,
                   python: str = sys.executable) -> list[dict]:
    """Per scene of ``arguments.scenes``, ``arguments.rounds`` children of ``script`` for this checkout
    and, with ``arguments.baseline``, for that commit's export, alternating (absolute times are noisy on
    this shared machine: the ratios are what it allows). A row per scene: ``medians`` of each
    variant's children; with a baseline ``pair_ratios(before, after)`` (when given) and the
    image_difference of the images ``image_keys(old, new)`` each variant's last child saved.
    Prints the scene, ``summary`` of each variant's medians and the image difference as it goes."""
    import numpy as np

    rows = []
    with tempfile.TemporaryDirectory() as temporary:
        temporary = Path(temporary)
        base = extract_commit(arguments.baseline, temporary / "baseline") if arguments.baseline is not None else None
        for name in arguments.scenes:
            row = {"scene": name}
            # The checkouts alternate round by round (ABBA...), which spreads the machine's varying
            # load over both; each round is a fresh process (its first measurement compiles the shaders).
            variants = [("baseline", base), ("current", REPO)] if base is not None else [("current", REPO)]
            children = alternate(variants, arguments.rounds, lambda label, repo: run_child(
                script, ["--child", name, "--repo", str(repo), "--repeats", str(arguments.repeats),
                         "--image", str(temporary / f"{label}_{name}.npz")],
                python, timeout=timeout, nice=nice))
            for label, _ in variants:
                row[label] = medians(children[label])
            if base is not None:
                if pair_ratios is not None:
                    row["pair_ratios"] = pair_ratios(children["baseline"], children["current"])
                old, new = (np.load(temporary / f"{label}_{name}.npz") for label in ("baseline", "current"))
                row["image_difference"] = image_difference(old, new, image_keys(old, new))
            rows.append(row)
            print(json.dumps({"scene": name, **{label: summary(row[label]) for label, _ in variants},
                              **({"image_difference": row["image_difference"]} if base is not None else {})}),
                  flush=True)
    return rows


def baseline_sentence(baseline: str | None) -> str:
    """What before and after are in a results page (with its leading space), or '' without a baseline."""
    if baseline is None:
        return ""
    return (f" Before: commit {baseline}; after: this checkout; measured in the same run, "
            "process by process in alternation.")


def write_results(stem: str, rows, text: str, folder: Path = RESULTS) -> None:
    """``folder``/STEM.json (the rows) and STEM.md (``text``); benchmarks/results by default."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{stem}.json").write_text(json.dumps(rows, indent=2))
    (folder / f"{stem}.md").write_text(text)
