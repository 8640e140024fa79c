"""Command line of the add-on, run with the bpy module: `python -m vsgl_addon COMMAND`.

Bad arguments or inputs end with one clear line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path

from .gpu_context import GPUContextError

MANIFEST = Path(__file__).resolve().parent.parent / "blender_manifest.toml"


class UsageError(Exception):
    """A problem with the user's input, reported as one line and exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        raise UsageError(f"{self.prog}: {message}")


def addon_version() -> str:
    try:
        return tomllib.loads(MANIFEST.read_text(encoding="utf-8"))["version"]
    except (OSError, KeyError, tomllib.TOMLDecodeError) as error:
        raise UsageError(f"cannot read the add-on version from {MANIFEST}: {error}") from None


def _command_demo(arguments) -> int:
    import bpy

    from .gpu_context import ensure_gpu_context
    from .reference import accuracy

    started = time.perf_counter()
    renderer = ensure_gpu_context()
    context_seconds = time.perf_counter() - started
    print(f"VSGL add-on {addon_version()} on Blender {bpy.app.version_string}")
    print(f"GPU renderer: {renderer} (context in {context_seconds:.2f} s)")
    print()
    started = time.perf_counter()
    rows = accuracy.measure()
    print(accuracy.to_markdown(rows, header=False))
    print(f"{len(rows)} math checks against numerical quadrature in {time.perf_counter() - started:.1f} s "
          "(how each is measured: docs/accuracy.md)")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="python -m vsgl_addon", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    demo = commands.add_parser(
        "demo", help="the main job: version, GPU renderer and the measured accuracy of the SG/ASG/GGX math")
    demo.set_defaults(run=_command_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        arguments = build_parser().parse_args(argv)
        return arguments.run(arguments)
    except (UsageError, GPUContextError) as error:
        print(error, file=sys.stderr)
        return 2
