"""Ground truth from Blender's own renderers, as float32 numpy passes.

    passes = render_cycles(scene, samples=64, max_bounces=1)
    passes["DiffDir"] * passes["DiffCol"]      # diffuse direct radiance, W/(m² sr), (H, W, 3)
    passes["GlossDir"] * passes["GlossCol"]    # glossy direct radiance

Renders ``scene`` (default: the context scene) with Cycles on the CPU into a temporary multilayer
OpenEXR (32-bit float, no compression), reads the file back with a small EXR reader (the bpy
wheel ships no OpenImageIO) and returns a dict of ``(H, W, 3)`` float32 arrays, row 0 at the TOP of
the image (as the file stores it; flip with ``[::-1]`` for the GPU passes' bottom-up rows):

* ``Combined`` (RGB, alpha dropped), ``DiffDir``, ``DiffInd``, ``DiffCol``, ``GlossDir``,
  ``GlossInd``, ``GlossCol`` (Blender's pass names in the EXR), plus ``Alpha`` (H, W).

One-bounce ground truth: ``max_bounces=1`` then indirect = DiffInd·DiffCol + GlossInd·GlossCol.
Denoising is off, the seed fixed, the light tree and adaptive sampling off (noise then falls as
1/sqrt(samples) everywhere), clamping off, filter width 1.5 px as Blender's default unless set.
Fast defaults for tests (64x48 from the scene's camera settings, 64 samples).

:func:`render_eevee` renders Combined only (EEVEE has no Cycles-style direct/colour split in the
same names); it is here for the benchmark's time/quality comparisons.
"""

from __future__ import annotations

import os
import struct
import tempfile
import time
from pathlib import Path

import numpy as np

PASSES = ("DiffDir", "DiffInd", "DiffCol", "GlossDir", "GlossInd", "GlossCol")
# Blender 5 names the layers in the EXR by their UI names; older versions by the short ones.
_SHORT_NAMES = {"Diffuse Direct": "DiffDir", "Diffuse Indirect": "DiffInd", "Diffuse Color": "DiffCol",
                "Glossy Direct": "GlossDir", "Glossy Indirect": "GlossInd", "Glossy Color": "GlossCol"}


# --- A minimal OpenEXR reader (scanline, NONE compression, HALF/FLOAT channels) -----------------


def _read_header(data: bytes, pos: int) -> tuple[dict, int]:
    header = {}
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        pos = end + 1
        end = data.index(b"\0", pos)
        kind = data[pos:end].decode()
        pos = end + 1
        (size,) = struct.unpack_from("<i", data, pos)
        pos += 4
        header[name] = (kind, data[pos:pos + size])
        pos += size
    return header, pos + 1


def read_exr(path) -> dict[str, np.ndarray]:
    """Channels of an uncompressed scanline EXR as float32 (H, W) arrays, keyed by full channel name
    (``ViewLayer.DiffDir.R``); row 0 = the top of the image. Single-part files and multi-part files
    (Blender 5 writes a multilayer EXR as one part per layer) of scanline parts."""
    data = Path(path).read_bytes()
    if data[:4] != b"\x76\x2f\x31\x01":
        raise ValueError(f"{path}: not an OpenEXR file")
    if data[5] & 0x0A:  # version flags: tiled (bit 9), deep (bit 11)
        raise ValueError(f"{path}: only scanline EXR files are supported")
    multipart = bool(data[5] & 0x10)
    pos = 8
    headers = []
    while True:
        header, pos = _read_header(data, pos)
        headers.append(header)
        if not multipart or data[pos] == 0:
            break
    if multipart:
        pos += 1
    parts = []
    for header in headers:
        if header["compression"][1][0] != 0:
            raise ValueError(f"{path}: compressed EXR (write it with exr_codec='NONE')")
        channels = []
        raw = header["channels"][1]
        p = 0
        while raw[p] != 0:
            end = raw.index(b"\0", p)
            name = raw[p:end].decode()
            (pixel_type,) = struct.unpack_from("<i", raw, end + 1)
            channels.append((name, pixel_type))
            p = end + 1 + 16
        xmin, ymin, xmax, ymax = struct.unpack_from("<iiii", header["dataWindow"][1])
        height = ymax - ymin + 1
        offsets = np.frombuffer(data, "<u8", height, pos)
        pos += 8 * height
        parts.append((channels, xmin, ymin, xmax - xmin + 1, height, offsets))
    dtypes = {1: np.dtype("<f2"), 2: np.dtype("<f4"), 0: np.dtype("<u4")}
    out = {}
    for channels, xmin, ymin, width, height, offsets in parts:
        layer = {name: np.zeros((height, width), np.float32) for name, _ in channels}
        for offset in offsets:
            q = int(offset) + (4 if multipart else 0)
            y, _size = struct.unpack_from("<ii", data, q)
            q += 8
            for name, pixel_type in channels:
                dtype = dtypes[pixel_type]
                layer[name][y - ymin] = np.frombuffer(data, dtype, width, q).astype(np.float32)
                q += width * dtype.itemsize
        out.update(layer)
    return out


def _layer_passes(channels: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``ViewLayer.DiffDir.R/G/B`` -> ``DiffDir`` (H, W, 3); Combined alpha -> ``Alpha``."""
    grouped: dict[str, dict[str, np.ndarray]] = {}
    for name, values in channels.items():
        parts = name.split(".")
        if len(parts) < 2:
            continue
        grouped.setdefault(parts[-2], {})[parts[-1]] = values
    passes = {}
    for name, components in grouped.items():
        name = _SHORT_NAMES.get(name, name)
        if all(c in components for c in "RGB"):
            passes[name] = np.stack([components[c] for c in "RGB"], axis=-1)
        elif "X" in components or "V" in components:
            passes[name] = next(iter(components.values()))
        if name == "Combined" and "A" in components:
            passes["Alpha"] = components["A"]
    return passes


# --- Cycles -------------------------------------------------------------------------------------


def configure_cycles(scene, *, samples: int = 64, max_bounces: int = 1, seed: int = 0,
                     resolution: tuple[int, int] | None = None, filter_width: float | None = None,
                     threads: int = 0) -> None:
    """Set ``scene`` up for a reproducible, noise-measurable Cycles render (see the module doc)."""
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = int(samples)
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.seed = int(seed)
    cycles.use_animated_seed = False
    cycles.max_bounces = int(max_bounces)
    for name in ("diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces",
                 "transparent_max_bounces"):
        setattr(cycles, name, int(max_bounces))
    cycles.sample_clamp_direct = 0.0
    cycles.sample_clamp_indirect = 0.0
    cycles.caustics_reflective = True
    cycles.caustics_refractive = True
    cycles.blur_glossy = 0.0
    if hasattr(cycles, "use_light_tree"):
        cycles.use_light_tree = False
    if filter_width is not None:
        cycles.filter_width = float(filter_width)
    if resolution is not None:
        scene.render.resolution_x, scene.render.resolution_y = resolution
        scene.render.resolution_percentage = 100
    scene.render.threads_mode = "FIXED" if threads else "AUTO"
    if threads:
        scene.render.threads = int(threads)
    scene.render.film_transparent = True
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    view_layer = scene.view_layers[0]
    view_layer.use_pass_combined = True
    view_layer.use_pass_diffuse_direct = True
    view_layer.use_pass_diffuse_indirect = True
    view_layer.use_pass_diffuse_color = True
    view_layer.use_pass_glossy_direct = True
    view_layer.use_pass_glossy_indirect = True
    view_layer.use_pass_glossy_color = True
    # Linear data out: the EXR holds scene-linear values whatever the view transform.
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0


def _render_to_exr(scene) -> tuple[dict[str, np.ndarray], float]:
    import bpy

    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):  # Blender 5: choose the multilayer EXR media type first
        settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    settings.exr_codec = "NONE"
    with tempfile.TemporaryDirectory(prefix="vsgl_truth_") as folder:
        path = os.path.join(folder, "truth.exr")
        scene.render.filepath = path
        start = time.perf_counter()
        with bpy.context.temp_override(scene=scene):
            bpy.ops.render.render(write_still=True, scene=scene.name)
        seconds = time.perf_counter() - start
        channels = read_exr(path)
    return _layer_passes(channels), seconds


def render_cycles(scene=None, *, samples: int = 64, max_bounces: int = 1, seed: int = 0,
                  resolution: tuple[int, int] | None = None, filter_width: float | None = None,
                  threads: int = 0) -> dict[str, np.ndarray]:
    """Render with Cycles and return the passes (see the module doc); ``passes["seconds"]`` is the
    wall time of the render call (a float in the dict)."""
    import bpy

    scene = scene or bpy.context.scene
    configure_cycles(scene, samples=samples, max_bounces=max_bounces, seed=seed, resolution=resolution,
                     filter_width=filter_width, threads=threads)
    passes, seconds = _render_to_exr(scene)
    passes["seconds"] = seconds
    return passes


def direct_radiance(passes) -> tuple[np.ndarray, np.ndarray]:
    """(diffuse direct, glossy direct) radiance: DiffDir·DiffCol and GlossDir·GlossCol."""
    return passes["DiffDir"] * passes["DiffCol"], passes["GlossDir"] * passes["GlossCol"]


def indirect_radiance(passes) -> np.ndarray:
    """One-bounce indirect radiance: DiffInd·DiffCol + GlossInd·GlossCol."""
    return passes["DiffInd"] * passes["DiffCol"] + passes["GlossInd"] * passes["GlossCol"]


# --- EEVEE --------------------------------------------------------------------------------------


def render_eevee(scene=None, *, samples: int = 16, resolution: tuple[int, int] | None = None
                 ) -> dict[str, np.ndarray]:
    """Render with EEVEE (Blender 4.2+ "BLENDER_EEVEE_NEXT", 5.x "BLENDER_EEVEE"): Combined only,
    plus ``seconds``."""
    import bpy

    scene = scene or bpy.context.scene
    engines = {item.identifier for item in
               bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items}
    scene.render.engine = "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in engines else "BLENDER_EEVEE"
    scene.eevee.taa_render_samples = int(samples)
    if resolution is not None:
        scene.render.resolution_x, scene.render.resolution_y = resolution
        scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    scene.view_layers[0].use_pass_combined = True
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    passes, seconds = _render_to_exr(scene)
    passes["seconds"] = seconds
    return passes
