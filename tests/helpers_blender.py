# SPDX-License-Identifier: GPL-3.0-or-later
"""Running the Blender 5.2 application (../shared/tools/real-blender) from tests.

real-blender runs ``blender ARGS`` in a chroot where only its current folder, /work/shared and
/tmp are visible, at their own paths. So every call runs with cwd = the repository, and every
scratch file or folder a call reads or writes must live under /tmp (use :func:`scratch_dir`).
Only ``BLENDER_*`` variables reach Blender.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Iterator, Mapping

import pytest

REPO = Path(__file__).resolve().parents[1]
# The same default (and override) as tools/setup-env.
REAL_BLENDER = Path(os.environ.get("REAL_BLENDER") or REPO.parent / "shared" / "tools" / "real-blender")
CHROOT_VISIBLE_TMP = Path("/tmp")


def run_blender(
    *args: str,
    blender_env: Mapping[str, str] | None = None,
    timeout: float = 120.0,
) -> subprocess.CompletedProcess[str]:
    """Run ``blender ARGS`` (no window; add ``-b`` for a full Blender) and return the finished process.

    ``blender_env`` holds the ``BLENDER_*`` variables to pass (e.g. BLENDER_USER_RESOURCES); any
    BLENDER_* of the calling environment is dropped so a developer's own profile never leaks in.
    Without a BLENDER_USER_RESOURCES of the caller, the call gets an empty profile of its own:
    otherwise it would use the one kept in real-blender's root, which outlives every run.
    """
    with contextlib.ExitStack() as stack:
        env = blender_environment(blender_env)
        if "BLENDER_USER_RESOURCES" not in env:
            env["BLENDER_USER_RESOURCES"] = str(stack.enter_context(scratch_dir("vsgl-profile-")))
        return subprocess.run(
            [str(REAL_BLENDER), "run", *args],
            cwd=REPO,
            env=env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )


def blender_environment(blender_env: Mapping[str, str] | None = None) -> dict[str, str]:
    """This process's environment without its BLENDER_* variables, plus ``blender_env`` (BLENDER_*
    only: real-blender passes nothing else): the environment of a real-blender call."""
    if not os.access(REAL_BLENDER, os.X_OK):
        pytest.fail(f"{REAL_BLENDER} not found or not executable (tools/setup-env sets it up)")
    env = {k: v for k, v in os.environ.items() if not k.startswith("BLENDER_")}
    for key, value in (blender_env or {}).items():
        assert key.startswith("BLENDER_"), f"real-blender passes only BLENDER_* variables, not {key}"
        env[key] = value
    return env


def describe(proc: subprocess.CompletedProcess[str]) -> str:
    """The command, exit code and output of a finished process, for assertion messages."""
    return (
        f"$ {' '.join(map(str, proc.args))}\nexit code {proc.returncode}\n"
        f"--- stdout ---\n{proc.stdout}\n--- stderr ---\n{proc.stderr}"
    )


@contextlib.contextmanager
def scratch_dir(prefix: str) -> Iterator[Path]:
    """A fresh folder under /tmp (which real-blender's chroot sees at the same path), removed afterwards."""
    path = Path(tempfile.mkdtemp(prefix=prefix, dir=CHROOT_VISIBLE_TMP))
    try:
        yield path
    finally:
        shutil.rmtree(path, ignore_errors=True)


@contextlib.contextmanager
def installed_extension(prefix: str) -> Iterator[tuple[Path, dict[str, str]]]:
    """(folder, BLENDER_* environment): a scratch folder under /tmp and a clean Blender user profile
    in it with the extension built from this checkout installed and enabled."""
    with scratch_dir(prefix) as folder:
        build = run_blender("--command", "extension", "build", "--source-dir", str(REPO),
                            "--output-dir", str(folder))
        assert build.returncode == 0, describe(build)
        environment = {"BLENDER_USER_RESOURCES": str(folder / "user")}
        install = run_blender("--command", "extension", "install-file", "-r", "user_default", "-e",
                              str(next(folder.glob("*.zip"))), blender_env=environment)
        assert install.returncode == 0, describe(install)
        yield folder, environment
