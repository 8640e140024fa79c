"""Command line of the add-on, run with the bpy module: `python -m vsgl_addon COMMAND`.

Bad arguments or inputs end with one clear line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import tomllib
from pathlib import Path

from .gpu_context import GPUContextError
from .settings import (DELTA_RANGE, INTERLEAVE_CHOICES, KERNELS, PDFS, POSITIONS, QUALITY_MODES, REFLECTOR_MODES,
                       TIME_BUDGET_RANGE)

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


DEMO_BLEND = Path(__file__).resolve().parent.parent / "demo.blend"
DEMO_OUTPUT = Path.cwd() / "out" / "demo.exr"


def _command_demo(arguments) -> int:
    """The main job: render demo.blend with its saved settings, print the figures and where the images are."""
    out = Path(arguments.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    arguments = argparse.Namespace(scene=str(DEMO_BLEND), out=str(out), report=str(out.with_suffix(".json")),
                                   resolution=arguments.resolution, vsgl_count=None, k=None, kernel=None,
                                   rsm_size=None, seed=None, positional_distribution=None, visibility=None,
                                   ism_size=None, ism_points=None, frame=None, glossy_reflectors=None,
                                   disk_radius=None, caustic_roughness=None, reflector_mode=None, caustics=None,
                                   delta=None, vpl_interleave=None, vpl_filter_radius=None, vpl_samples=None,
                                   vpl_visibility=None, pdf=None, time_budget=None,
                                   quality=None)
    print(f"VSGL add-on {addon_version()}: rendering {DEMO_BLEND.name} (one-bounce indirect light from VSGLs)")
    return _command_render(arguments)


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
            rsm_size=arguments.rsm_size, seed=arguments.seed,
            positional_distribution=arguments.positional_distribution,
            visibility=None if arguments.visibility is None else arguments.visibility == "on",
            ism_size=arguments.ism_size, ism_points=arguments.ism_points,
            glossy_reflectors=(None if getattr(arguments, "glossy_reflectors", None) is None
                               else arguments.glossy_reflectors == "on"),
            disk_radius=getattr(arguments, "disk_radius", None),
            caustic_roughness=getattr(arguments, "caustic_roughness", None),
            reflector_mode=getattr(arguments, "reflector_mode", None),
            caustics=None if getattr(arguments, "caustics", None) is None else arguments.caustics == "on",
            delta=getattr(arguments, "delta", None), vpl_interleave=getattr(arguments, "vpl_interleave", None),
            vpl_filter_radius=getattr(arguments, "vpl_filter_radius", None),
            vpl_samples=getattr(arguments, "vpl_samples", None),
            vpl_visibility=(None if getattr(arguments, "vpl_visibility", None) is None
                            else arguments.vpl_visibility == "on"),
            pdf=getattr(arguments, "pdf", None),
            quality_mode=_quality_mode(arguments),
            time_budget_ms=getattr(arguments, "time_budget", None))
    except SettingsError as error:
        raise UsageError(str(error)) from None


def _quality_mode(arguments) -> str | None:
    """The quality mode the flags ask for (None: the scene's): --time-budget is Budget mode."""
    quality, budget = getattr(arguments, "quality", None), getattr(arguments, "time_budget", None)
    if budget is not None and quality is not None:
        raise UsageError(f"--quality {quality} and --time-budget ask for two quality modes: give one")
    return "budget" if budget is not None else quality


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
    from .light_paths import needs_glossy_vpls
    from .pipeline import generate_scene_vsgls
    from .scene import extract_scene

    out = _output_path(arguments.out, ".npz")
    register()
    try:
        scene = _open_blend(Path(arguments.scene))
        settings = _settings(scene, arguments)
        gpu_renderer = ensure_gpu_context()
        started = time.perf_counter()
        description = extract_scene(bpy.context.evaluated_depsgraph_get())
        budget_line = None
        if settings.quality_mode == "budget":
            settings, budget_line = _budget_settings(scene, description, settings, gpu_renderer)
        table = generate_scene_vsgls(description, settings)
        if needs_glossy_vpls(description, settings):
            table.update(_glossy_vpls(description, settings))
        seconds = time.perf_counter() - started
    finally:
        unregister()
    np.savez(out, **table)
    for line in description.warnings:
        print(line, file=sys.stderr)
    print(f"{out}: {len(table['light_index'])} VSGLs from {len(table['rsm_size'])} lights "
          f"({settings.kernel} kernel, N = {settings.vsgl_count}, K = {settings.k:g}, "
          f"RSM {settings.rsm_size}², seed {settings.seed}, {settings.positional_distribution} positions)"
          + (f", {len(table['vpl_roughness'])} glossy VPLs (delta {settings.delta:g})" if "vpl_roughness" in table
             else "") + f" in {seconds:.2f} s")
    if budget_line:
        print(budget_line)
    return 0


def _budget_settings(scene, description, settings, gpu_renderer):
    """The settings Budget mode gives a frame of the scene at its output size (budget.py, this GPU's
    cost model, calibrated first when the user's cache has none), and its one-line summary."""
    from .budget import choose, save_model
    from .budget_render import model_for, scene_key
    from .views import render_size
    from .planner import plan_frame
    from .renderer import FrameRenderer

    if description.camera is None:
        raise UsageError("--time-budget needs the scene's camera (the frame the budget is for)")
    width, height = render_size(scene.render)
    renderer = FrameRenderer()
    try:
        model = model_for(renderer, description, settings, width, height, gpu_renderer,
                          log=lambda line: print(line, file=sys.stderr))
    finally:
        renderer.free()
    if model.warning:
        print(model.warning, file=sys.stderr)
    else:
        save_model(gpu_renderer, model)
    camera = description.camera
    plan = plan_frame(description, settings, None, camera.projection_matrix() @ camera.view_matrix())
    choice = choose(plan, settings, width, height, settings.time_budget_ms, model,
                    int(description.geometry.triangle_count), model.vpl_fraction(scene_key(description)),
                    scene_key(description))
    return choice.settings, choice.line()


def _glossy_vpls(description, settings) -> dict:
    """The glossy VPLs of the scene (passes/vpl_culling.py scene_vpls) as export rows ``vpl_<field>``,
    with the culling parameters they would be rendered with."""
    import numpy as np

    from .passes.rsm import SceneGPU
    from .passes.vpl_culling import scene_vpls

    scene_gpu = SceneGPU(description)
    try:
        vpls = scene_vpls(scene_gpu, settings.rsm_size, settings.caustic_roughness)
    finally:
        scene_gpu.free()
    rows = {f"vpl_{name}": value for name, value in vpls.items()}
    rows.update(delta=np.float64(settings.delta), caustic_roughness=np.float64(settings.caustic_roughness))
    return rows


def _resolution(text):
    try:
        width, height = (int(part) for part in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"not WIDTHxHEIGHT: {text!r}") from None
    if not (1 <= width <= 16384 and 1 <= height <= 16384):
        raise argparse.ArgumentTypeError(f"each side must be in [1, 16384]: {text!r}")
    return width, height


def _save_render(scene, path: Path, multilayer: bool) -> None:
    """Blender's own writer: multilayer EXR (linear, every pass, 32-bit float) or a PNG preview
    (through the scene's colour management, like F12 → Save)."""
    import bpy

    settings = scene.render.image_settings
    saved = (settings.media_type, settings.file_format, settings.color_depth)
    try:
        if multilayer:
            settings.media_type = "MULTI_LAYER_IMAGE"
            settings.color_depth = "32"
            settings.exr_codec = "ZIP"
        else:
            settings.media_type = "IMAGE"
            settings.file_format = "PNG"
            settings.color_mode = "RGBA"
            settings.color_depth = "8"
        bpy.data.images["Render Result"].save_render(str(path), scene=scene)
    finally:
        settings.media_type = saved[0]
        if saved[0] == "IMAGE":
            settings.file_format = saved[1]
        settings.color_depth = saved[2]


def _command_render(arguments) -> int:
    import json

    import bpy

    from . import register, unregister
    from .engine import ENGINE_ID, RENDER_PASSES, last_frame_statistics
    from .gpu_context import ensure_gpu_context
    from .passes import COUNT_LABELS, TIMING_LABELS

    out = _output_path(arguments.out, ".exr")
    report = _output_path(arguments.report, ".json") if arguments.report else None
    register()
    try:
        scene = _open_blend(Path(arguments.scene))
        settings = _settings(scene, arguments)
        if scene.camera is None:
            raise UsageError(f"{arguments.scene}: the scene has no camera")
        renderer = ensure_gpu_context()
        # The loaded file is never saved: these changes last for this run only.
        scene.vsgl.vsgl_count, scene.vsgl.k, scene.vsgl.rsm_size, scene.vsgl.seed = (
            settings.vsgl_count, settings.k, settings.rsm_size, settings.seed)
        scene.vsgl.kernel = KERNELS.named(settings.kernel).identifier
        scene.vsgl.positional_distribution = POSITIONS.named(settings.positional_distribution).identifier
        scene.vsgl.visibility, scene.vsgl.ism_size, scene.vsgl.ism_points = (
            settings.visibility, settings.ism_size, settings.ism_points)
        scene.vsgl.glossy_reflectors, scene.vsgl.disk_radius, scene.vsgl.caustic_roughness = (
            settings.glossy_reflectors, settings.disk_radius, settings.caustic_roughness)
        scene.vsgl.reflector_mode = REFLECTOR_MODES.named(settings.reflector_mode).identifier
        scene.vsgl.caustics, scene.vsgl.vpl_filter_radius, scene.vsgl.vpl_samples, scene.vsgl.vpl_visibility = (
            settings.caustics, settings.vpl_filter_radius, settings.vpl_samples, settings.vpl_visibility)
        scene.vsgl.delta_log10 = math.log10(settings.delta)
        scene.vsgl.vpl_interleave = INTERLEAVE_CHOICES.named(settings.vpl_interleave).identifier
        scene.vsgl.pdf = PDFS.named(settings.pdf).identifier
        scene.vsgl.quality_mode = QUALITY_MODES.named(settings.quality_mode).identifier
        scene.vsgl.time_budget_ms = settings.time_budget_ms
        scene.render.engine = ENGINE_ID
        if arguments.resolution:
            scene.render.resolution_x, scene.render.resolution_y = arguments.resolution
            scene.render.resolution_percentage = 100
        if arguments.frame is not None:
            scene.frame_set(arguments.frame)
        started = time.perf_counter()
        bpy.ops.render.render(scene=scene.name)
        seconds = time.perf_counter() - started
        if not last_frame_statistics:
            raise UsageError(f"{arguments.scene}: the VSGL engine rendered nothing (see the messages above)")
        _save_render(scene, out, multilayer=True)
        preview = out.with_suffix(".png")
        _save_render(scene, preview, multilayer=False)
        statistics = dict(last_frame_statistics)
    finally:
        unregister()
    statistics.update(scene=str(arguments.scene), output=str(out), preview=str(preview),
                      frame=scene.frame_current, render_seconds=seconds, gpu_renderer=renderer,
                      addon_version=addon_version(), blender_version=bpy.app.version_string)
    # What each timing and count is, as the passes declare it (the statistics panel's labels).
    statistics.update(timing_labels={key: TIMING_LABELS.get(key, key) for key in statistics["timings"]},
                      count_labels={key: COUNT_LABELS.get(key, key) for key in statistics["counts"]})
    if report:
        report.write_text(json.dumps(statistics, indent=2, sort_keys=True), encoding="utf-8")
    width, height = statistics["resolution"]
    settings_line = ", ".join(f"{name} {value}" for name, value in statistics["settings"].items())
    print(f"Blender {statistics['blender_version']}, GPU {renderer}")
    print(f"{width}x{height}, frame {statistics['frame']}, {statistics['counts'].get('vsgls', 0)} VSGLs from "
          f"{statistics['counts'].get('lights', 0)} lights ({settings_line}): {seconds:.2f} s in all")
    for name, value in statistics["timings"].items():
        print(f"  {name:>24}: {value * 1000:9.1f} ms")
    budget = (statistics.get("plan") or {}).get("budget")
    if budget:
        print(f"time budget: target {budget['target_ms']:.0f} ms, predicted {budget['predicted_ms']:.0f} ms, "
              f"measured {budget['measured_ms']:.0f} ms (the passes' sum; cost model: {budget['cost_model']})")
    if statistics.get("plan"):
        print("frame plan:")
        for line in statistics["plan"]["summary"]:
            print(f"  {line}")
    print(f"images: {out} (layers {', '.join(('Combined',) + tuple(RENDER_PASSES))}), {preview}")
    if report:
        print(f"report: {report}")
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


def _caustics_flags(parser) -> None:
    """The glossy VPL pass's flags (004), shared by the render and vsgl commands."""
    parser.add_argument("--caustics", choices=("on", "off"),
                        help="caustics of sharp glossy reflectors on matte surfaces from glossy VPLs (004; on by "
                             "default, run only where such a lit reflector exists)")
    parser.add_argument("--delta", type=_float, metavar="D",
                        help=f"acceptance threshold of stochastic light culling (004 Eq. 2), {DELTA_RANGE[0]:g} to "
                             f"{DELTA_RANGE[1]:g} (default 0.001): larger is faster and noisier")
    parser.add_argument("--vpl-interleave", choices=INTERLEAVE_CHOICES.names,
                        help="interleaved sampling N x N (004 §6; auto: by resolution, 8 at 1080p): larger is "
                             "faster and noisier")
    parser.add_argument("--vpl-filter-radius", type=_positive_int, metavar="R",
                        help="cross-bilateral filter radius in pixels, 0 to 16 (0: none; 004 uses 8)")
    parser.add_argument("--vpl-samples", type=_positive_int, metavar="S",
                        help="culling draws averaged per image (noise falls as 1/sqrt(S))")
    parser.add_argument("--vpl-visibility", choices=("on", "off"),
                        help="shadow the VPLs' light with one imperfect shadow map per VPL cluster (on by default)")


def _budget_flag(parser) -> None:
    parser.add_argument("--time-budget", type=_float, metavar="MS",
                        help=f"Budget mode: a target frame time in ms ({TIME_BUDGET_RANGE[0]:g} to "
                             f"{TIME_BUDGET_RANGE[1]:g}); N, RSM size, delta, VPL interleave and resolution come from "
                             "this machine's cost model (calibrated at first use, kept in the user's cache), "
                             "overriding those flags")
    parser.add_argument("--quality", choices=("manual", "auto"),
                        help="manual: every pass whose light path the scene has runs; auto: the frame planner leaves "
                             "out the VPL pass or MRP-ASG where their light is a small share of the bounce for the "
                             "frame time they add (default: the scene's Quality; --time-budget is Budget mode)")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="python -m vsgl_addon", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    demo = commands.add_parser(
        "demo", help="the main job: render demo.blend to out/demo.exr (+ .png, .json) and print the timings")
    demo.add_argument("--out", default=str(DEMO_OUTPUT), metavar="OUT.exr")
    demo.add_argument("--resolution", type=_resolution, metavar="WxH", help="default: the scene's (480x360)")
    demo.set_defaults(run=_command_demo)


    positional_help = ("where each VSGL's lobes sit: per-lobe (default; each lobe's own power centroid) or "
                       "shared (000 app. B.2 as written)")

    vsgl = commands.add_parser(
        "vsgl", help="export the VSGLs of a .blend's scene (one row per VSGL) to a numpy .npz",
        description="Export the VSGLs of SCENE.blend. Parameters default to the scene's own (scene.vsgl); "
                    "flags override them for this run.")
    vsgl.add_argument("scene", metavar="SCENE.blend")
    vsgl.add_argument("--out", required=True, metavar="VSGLS.npz")
    vsgl.add_argument("--vsgl-count", type=_positive_int, metavar="N", help="VSGLs per frame, shared by the lights by bounce power, 1 to 4096")
    vsgl.add_argument("--k", type=_float, metavar="K", help="kernel size factor K, 0.25 to 16 (000 Eq. 3)")
    vsgl.add_argument("--kernel", choices=KERNELS.names)
    vsgl.add_argument("--rsm-size", type=_positive_int, metavar="S", help="RSM side in texels, a power of two")
    vsgl.add_argument("--seed", type=_positive_int, metavar="S")
    vsgl.add_argument("--positional-distribution", choices=POSITIONS.names, help=positional_help)
    vsgl.add_argument("--visibility", choices=("on", "off"), help="VSGL visibility from imperfect shadow maps")
    vsgl.add_argument("--ism-size", type=_positive_int, metavar="S", help="imperfect shadow map side, a power of two")
    vsgl.add_argument("--ism-points", type=_positive_int, metavar="P", help="scene points per shadow map")
    _caustics_flags(vsgl)
    _budget_flag(vsgl)
    vsgl.set_defaults(run=_command_vsgl)

    render = commands.add_parser(
        "render", help="render a .blend's frame with the VSGL engine to a multilayer EXR (+ PNG preview)",
        description="Render SCENE.blend with the VSGL engine: a multilayer EXR with Combined, Direct, Indirect, "
                    "Indirect Diffuse, Indirect Specular, Indirect Glossy Reflectors and Indirect Caustics (linear, Blender's units) "
                    "and a PNG preview beside "
                    "it. Parameters default to the scene's own (scene.vsgl); flags override them for this run.")
    render.add_argument("scene", metavar="SCENE.blend")
    render.add_argument("--out", required=True, metavar="OUT.exr")
    render.add_argument("--resolution", type=_resolution, metavar="WxH")
    render.add_argument("--vsgl-count", type=_positive_int, metavar="N", help="VSGLs per frame, shared by the lights by bounce power, 1 to 4096")
    render.add_argument("--k", type=_float, metavar="K", help="kernel size factor K, 0.25 to 16 (000 Eq. 3)")
    render.add_argument("--kernel", choices=KERNELS.names)
    render.add_argument("--rsm-size", type=_positive_int, metavar="S", help="RSM side in texels, a power of two")
    render.add_argument("--seed", type=_positive_int, metavar="S")
    render.add_argument("--positional-distribution", choices=POSITIONS.names, help=positional_help)
    render.add_argument("--visibility", choices=("on", "off"), help="VSGL visibility from imperfect shadow maps")
    render.add_argument("--ism-size", type=_positive_int, metavar="S", help="imperfect shadow map side, a power of two")
    render.add_argument("--ism-points", type=_positive_int, metavar="P", help="scene points per shadow map")
    render.add_argument("--glossy-reflectors", choices=("on", "off"),
                        help="glossy interreflection from rectangle proxies with MRP-ASG (001; on by default)")
    render.add_argument("--disk-radius", type=_float, metavar="M",
                        help="MRP-ASG sampling-disk radius in metres (001 §3.4): small keeps sharp reflections, "
                             "large gathers all of a rougher reflector's light but blurs it")
    render.add_argument("--caustic-roughness", type=_float, metavar="A",
                        help="GGX alpha below which a planar reflector becomes a rectangle proxy (alpha_c)")
    render.add_argument("--reflector-mode", choices=REFLECTOR_MODES.names,
                        help="asg (001 Eq. 11, default) or sg (the faster Eq. 37)")
    _caustics_flags(render)
    render.add_argument("--pdf", choices=PDFS.names,
                        help="VSGL generation's PDF: view (000 §5: also what the camera sees of it, for suns; "
                             "the default) or light (the bounce power, for every light)")
    _budget_flag(render)
    render.add_argument("--frame", type=int, metavar="F")
    render.add_argument("--report", metavar="REPORT.json", help="write timings, counts and parameters as JSON")
    render.set_defaults(run=_command_render)
    return parser


def main(argv: list[str] | None = None) -> int:
    try:
        arguments = build_parser().parse_args(argv)
        return arguments.run(arguments)
    except (UsageError, GPUContextError) as error:
        print(error, file=sys.stderr)
        return 2
