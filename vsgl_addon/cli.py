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


BLEND_MAGICS = (b"BLENDER", b"\x28\xb5\x2f\xfd", b"\x1f\x8b")  # plain, zstd- and gzip-compressed


def _open_blend(path: Path):
    """Open `path` in the bpy module with the add-on registered (so `scene.vsgl` is read) and
    return its scene; every failure is a UsageError naming the file."""
    import bpy

    if not path.is_file():
        raise UsageError(f"{path}: no such file")
    with path.open("rb") as file:
        head = file.read(7)
    if not head.startswith(BLEND_MAGICS):
        raise UsageError(f"{path}: not a .blend file")
    try:
        bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False)
    except RuntimeError as error:
        reason = str(error).strip().splitlines()[0] if str(error).strip() else "unknown error"
        reason = reason.removeprefix("Error: ")
        raise UsageError(f"{path}: Blender could not open it ({reason})") from None
    return bpy.context.scene


def _settings(scene, arguments):
    from .settings import SettingsError, VSGLSettings

    try:
        return VSGLSettings.from_properties(scene.vsgl).overridden(
            vsgl_count=arguments.vsgl_count, k=arguments.k, kernel=arguments.kernel,
            rsm_size=arguments.rsm_size, seed=arguments.seed)
    except SettingsError as error:
        raise UsageError(str(error)) from None


def _output_path(text: str, suffix: str) -> Path:
    path = Path(text)
    if path.suffix.lower() != suffix:
        raise UsageError(f"{path}: the output must be a {suffix} file")
    if not path.parent.is_dir():
        raise UsageError(f"{path.parent}: no such folder for the output")
    return path


def _command_vsgl(arguments) -> int:
    import bpy
    import numpy as np

    from . import register, unregister
    from .gpu_context import ensure_gpu_context
    from .pipeline import generate_scene_vsgls
    from .scene import extract_scene

    out = _output_path(arguments.out, ".npz")
    register()
    try:
        scene = _open_blend(Path(arguments.scene))
        settings = _settings(scene, arguments)
        ensure_gpu_context()
        started = time.perf_counter()
        description = extract_scene(bpy.context.evaluated_depsgraph_get())
        table = generate_scene_vsgls(description, settings)
        seconds = time.perf_counter() - started
    finally:
        unregister()
    np.savez(out, **table)
    for line in description.warnings:
        print(line, file=sys.stderr)
    print(f"{out}: {len(table['light_index'])} VSGLs from {len(table['rsm_size'])} lights "
          f"({settings.kernel} kernel, N = {settings.vsgl_count}, K = {settings.k:g}, "
          f"RSM {settings.rsm_size}², seed {settings.seed}) in {seconds:.2f} s")
    return 0


def _positive_int(text):
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None


def _float(text):
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="python -m vsgl_addon", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    demo = commands.add_parser(
        "demo", help="the main job: version, GPU renderer and the measured accuracy of the SG/ASG/GGX math")
    demo.set_defaults(run=_command_demo)

    from .settings import KERNEL_MODES

    vsgl = commands.add_parser(
        "vsgl", help="export the VSGLs of a .blend's scene (one row per VSGL) to a numpy .npz",
        description="Export the VSGLs of SCENE.blend. Parameters default to the scene's own (scene.vsgl); "
                    "flags override them for this run.")
    vsgl.add_argument("scene", metavar="SCENE.blend")
    vsgl.add_argument("--out", required=True, metavar="VSGLS.npz")
    vsgl.add_argument("--vsgl-count", type=_positive_int, metavar="N", help="VSGLs per light, 1 to 4096")
    vsgl.add_argument("--k", type=_float, metavar="K", help="kernel size factor K, 0.25 to 16 (000 Eq. 3)")
    vsgl.add_argument("--kernel", choices=KERNEL_MODES)
    vsgl.add_argument("--rsm-size", type=_positive_int, metavar="S", help="RSM side in texels, a power of two")
    vsgl.add_argument("--seed", type=_positive_int, metavar="S")
    vsgl.set_defaults(run=_command_vsgl)
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        arguments = build_parser().parse_args(argv)
        return arguments.run(arguments)
    except (UsageError, GPUContextError) as error:
        print(error, file=sys.stderr)
        return 2
