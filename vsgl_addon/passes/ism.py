# SPDX-License-Identifier: GPL-3.0-or-later
"""Imperfect shadow maps (ISMs) on the GPU: one octahedral depth map per origin (a VSGL lobe's
position; 000 §5, Ritschel et al. 2008), all in one atlas. The twin of
:mod:`vsgl_addon.reference.ism` (projection, splat, pull-push; why octahedral is said there).

Four compute stages (``glsl/ism/``), after a fifth that makes the splat's table of a VSGL table
on the GPU (``ism_origins.comp.glsl``, :func:`vsgl_map_origins`: each map's origin, point set and
minimum distance from the table texture, so the maps of GPU-made VSGLs read nothing back):

1. ``ism_splat.comp.glsl``: one invocation per (point, map). Map m splats point set
   ``set_index[m]`` of :func:`vsgl_addon.scene_points.scene_point_sets` (an RGBA32F texture, one
   row per set) with ``imageAtomicMin`` on the distance's float bits into its tile of an R32UI atlas
   (shared/reference/blender-gpu.md: about 7× faster than drawing points on llvmpipe).
2. ``ism_close.comp.glsl``: gaps between nearer texels on both sides closed (holes in near
   occluders, through which the points behind them show; silhouettes stay), into a second atlas.
3. ``ism_pull.comp.glsl``: the pyramid of the atlas, one dispatch per level (RG32F: mean depth of
   the valid children, valid); tiles are aligned power-of-two squares, so each level is every
   tile's own pyramid.
4. ``ism_push.comp.glsl``: holes take their parent's depth, coarsest level first, down to level 0.

The result, :class:`ISMAtlas`, holds the filled level 0 as R32F: the depth, or
:data:`UNKNOWN_DEPTH` where no point of the map's set landed (a map no point reached is all
unknown). Needs a GPU context, main thread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..layouts import VSGL_TABLE
from ..reference import ism as _reference_ism
from ..reference.ism import EMPTY, GAP_MARGIN, GAP_REACH, SPLAT_SHARE
from ..shaders import ShaderInterface
from .contract import GPUPass, ShaderSpec, Step, run_stages
from .gpu_util import read_texture, texture_from_array

#: Largest atlas side (llvmpipe's and most GPUs' texture limit), and the sides an ISM may have.
MAX_ATLAS_SIDE = 16384
ISM_SIZE_RANGE = (1, 256)
#: Points of one set are one texture row.
MAX_POINTS_PER_SET = 16384
_GROUP = (64, 1, 1)
_LEVEL_GROUP = (8, 8, 1)
#: (point, map) pairs splatted per dispatch, each a stage of build_ism_atlas_stages (64 maps of 4096
#: points): the viewport runs a light build's stages within its step budget, and one set's splat in
#: one dispatch took up to 129 ms in Blender's window (benchmarks/results/latency_preview.md).
SPLATS_PER_STAGE = 1 << 18
#: Atlas texels the gap closing writes per dispatch, a stage each (128 maps of 64²; the closing of
#: 512 maps took 117-145 ms in one dispatch, windowless).
CLOSED_TEXELS_PER_STAGE = 1 << 19


def _splat_interface() -> ShaderInterface:
    return ShaderInterface(
        # (points per set, map count, map side, tiles per atlas row)
        push_constants=[("IVEC4", "ism_params"), ("FLOAT", "ism_point_area"), ("FLOAT", "ism_plane_depth"),
                        ("INT", "ism_max_radius"), ("INT", "ism_first_map")],
        # Inputs read as images, not samplers: on llvmpipe an imageLoad costs a fraction of a
        # texelFetch (benchmarks/light_build_profile.py), the same texels either way.
        images=[("R32UI", "UINT_2D", "ism_atlas"), ("RGBA32F", "FLOAT_2D", "scene_points"),
                ("RGBA32F", "FLOAT_2D", "scene_point_normals"), ("RGBA32F", "FLOAT_2D", "ism_origins")],
        local_group_size=_GROUP,
    )


def _origins_interface() -> ShaderInterface:
    return ShaderInterface(
        # (VSGL count, maps per VSGL, first map, point sets)
        push_constants=[("IVEC4", "ism_origin_params"), ("FLOAT", "ism_own_reflector_sigmas")],
        samplers=[("FLOAT_2D", "vsgl_table")],
        images=[("RGBA32F", "FLOAT_2D", "ism_origins")],
        local_group_size=_GROUP,
    )


def _close_interface() -> ShaderInterface:
    return ShaderInterface(push_constants=[("INT", "ism_size"), ("INT", "ism_continued"), ("INT", "ism_first_row")],
                           images=[("R32UI", "UINT_2D", "ism_splatted"), ("R32UI", "UINT_2D", "ism_closed")],
                           local_group_size=_LEVEL_GROUP)


def _pull_interface() -> ShaderInterface:
    return ShaderInterface(push_constants=[("INT", "ism_first_level")],
                           images=[("R32UI", "UINT_2D", "ism_atlas"), ("RG32F", "FLOAT_2D", "ism_fine"),
                                   ("RG32F", "FLOAT_2D", "ism_coarse")],
                           local_group_size=_LEVEL_GROUP)


def _push_interface(final: bool = False) -> ShaderInterface:
    return ShaderInterface(push_constants=[("INT", "ism_first_level")],
                           images=[("R32UI", "UINT_2D", "ism_atlas"), ("RG32F", "FLOAT_2D", "ism_own"),
                                   ("RG32F", "FLOAT_2D", "ism_parent"),
                                   ("R32F" if final else "RG32F", "FLOAT_2D", "ism_filled")],
                           local_group_size=_LEVEL_GROUP)


#: Depth of a texel no point reached in the filled atlas (R32F): the lookups' test ``distance <=
#: depth + bias`` then passes without a second channel, so a lookup reads one float per texel (a
#: quarter of an RGBA32F atlas's memory, one textureGather for the bilinear filter).
UNKNOWN_DEPTH = 1e30


def atlas_layout(map_count: int, size: int) -> tuple[int, int]:
    """(tiles per row, rows of tiles) of an atlas of ``map_count`` maps of ``size``²: square-ish."""
    columns, rows = atlas_layout_unchecked(map_count)
    if max(columns, rows) * size > MAX_ATLAS_SIDE:
        raise ValueError(f"{map_count} ISMs of {size}² do not fit a {MAX_ATLAS_SIDE}² atlas")
    return columns, rows


def fitting_size(map_count: int, size: int) -> int:
    """``size``, or the largest power of two below it at which ``map_count`` maps fit one atlas (many
    VSGLs at a large map side would not: 8192 maps of 256² need a 23296² atlas)."""
    while size > 1 and max(atlas_layout_unchecked(map_count)) * size > MAX_ATLAS_SIDE:
        size //= 2
    return size


def atlas_layout_unchecked(map_count: int) -> tuple[int, int]:
    columns = max(1, math.ceil(math.sqrt(map_count)))
    return columns, max(1, math.ceil(map_count / columns))


@dataclass
class ISMAtlas:
    """The filled maps on the GPU: ``texture`` R32F (depth, UNKNOWN_DEPTH where nothing landed), map
    m in tile (m mod columns, m div columns)."""

    texture: object
    size: int
    count: int
    columns: int
    rows: int
    seconds: dict = field(default_factory=dict)
    #: The maps keep their surfaces' depth (oriented splats, continued gap sides; reference.ism
    #: SPLAT_PLANE_DEPTH, SURFACE_SPLAT_MAX_RADIUS, GAP_EXTRAPOLATE).
    surfaces: bool = False
    #: Their lookups take the surface normal offset (reference.ism SURFACE_NORMAL_OFFSET; the
    #: reference vsgl_visibility ``surfaces``), else the slope-scaled depth bias.
    normal_offset: bool = False

    def read(self) -> np.ndarray:
        """(count, size, size) float64 depths [map, row, column]; EMPTY where the map has nothing."""
        s = self.size
        array = read_texture(self.texture, self.columns * s, self.rows * s, channels=1).astype(np.float64)
        tiles = array.reshape(self.rows, s, self.columns, s).transpose(0, 2, 1, 3).reshape(-1, s, s)
        tiles = tiles[:self.count]
        return np.where(tiles < 0.5 * UNKNOWN_DEPTH, tiles, EMPTY)

    def free(self) -> None:
        self.texture = None


def _groups(count: int, size: int) -> int:
    return max(1, -(-count // size))


def _finish_stage(texture, clock: float, seconds: dict, name: str) -> float:
    """Wait for the GPU (``texture`` read back) and add the time since ``clock`` to ``seconds[name]``."""
    import time

    texture.read()
    now = time.perf_counter()
    seconds[name] = seconds.get(name, 0.0) + now - clock
    return now


def upload_points(points) -> tuple:
    """The (positions, normals) RGBA32F textures of a :class:`~vsgl_addon.scene_points.ScenePoints`
    (one row per set), for :func:`build_ism_atlas`'s ``point_textures``."""
    ones = np.ones((*points.positions.shape[:2], 1), np.float32)
    return (texture_from_array(np.concatenate([points.positions, ones], axis=-1)),
            texture_from_array(np.concatenate([points.normals, ones], axis=-1)))


@dataclass
class MapOrigins:
    """The splat's table on the GPU: an RGBA32F texture of ``count`` columns (row 0: origin xyz,
    point set; row 1: minimum distance; row 2: the half-space, zero: every point kept), as
    :func:`build_ism_atlas` makes from numpy arrays; made on the GPU by :func:`vsgl_map_origins` from
    a VSGL table and by passes/vpl_culling.py cluster_view from the VPLs' RSM views (its row 1's y:
    1 where the block has a VPL)."""

    texture: object
    count: int


def set_shadow_origin_sigmas(sigmas: float) -> None:
    """Centre the maps (and every lookup in them) ``sigmas`` σ_v off each lobe's mean along its axis
    (reference.ism.shadow_origin): sets reference.ism.SHADOW_ORIGIN_SIGMAS, the float64 twin, which
    every shader requiring glsl/lib/ism.glsl is compiled with (its define ISM_ORIGIN_SIGMAS:
    the map origins here, the VSGL shading's and the VPL clusters' lookups; passes/contract.py
    compiles them again when it changed)."""
    from ..reference import ism as reference_ism

    sigmas = float(sigmas)
    if not math.isfinite(sigmas) or sigmas < 0.0:
        raise ValueError(f"shadow origin offset must be finite and >= 0 sigma_v, got {sigmas}")
    reference_ism.SHADOW_ORIGIN_SIGMAS = sigmas


def set_lookup_bias(normal_offset: float, depth_texels: float | None = None, back_offset: float | None = None,
                    spread: float | None = None) -> None:
    """Every lookup's bias (reference.ism.lookup_offsets): the receiver offset along its normal,
    ``normal_offset`` filter footprints (0: the slope-scaled depth bias alone), the depth bias left
    with it, ``depth_texels`` texel footprints, and the offset away from the origin of receivers
    facing away from it, ``back_offset`` filter footprints (0: none), and the cap of the bilinear
    lookup's bias by its texels' depth spread, ``spread`` times it (0: none); None keeps a value.
    Sets reference.ism.NORMAL_OFFSET, NORMAL_OFFSET_DEPTH, BACK_OFFSET and SPREAD_BIAS, which every
    shader requiring glsl/lib/ism.glsl is compiled with (its defines ISM_NORMAL_OFFSET,
    ISM_NORMAL_OFFSET_DEPTH, ISM_BACK_OFFSET and ISM_SPREAD; passes/contract.py compiles them again
    when they changed)."""
    from ..reference import ism as reference_ism

    values = [float(normal_offset),
              reference_ism.NORMAL_OFFSET_DEPTH if depth_texels is None else float(depth_texels),
              reference_ism.BACK_OFFSET if back_offset is None else float(back_offset),
              reference_ism.SPREAD_BIAS if spread is None else float(spread)]
    for name, value in zip(("normal offset", "depth bias", "back offset", "spread"), values):
        if not math.isfinite(value) or value < 0.0:
            raise ValueError(f"lookup {name} must be finite and >= 0, got {value}")
    (reference_ism.NORMAL_OFFSET, reference_ism.NORMAL_OFFSET_DEPTH, reference_ism.BACK_OFFSET,
     reference_ism.SPREAD_BIAS) = values


def vsgl_map_origins(table_texture, vsgl_count: int, maps_per_vsgl: int, first_map: int, point_sets: int,
                     own_reflector_sigmas: float) -> MapOrigins:
    """The splat's table of the maps of a VSGL table texture (layouts.VSGL_TABLE, ``vsgl_count``
    columns), made on the GPU: the twin of reference.ism.vsgl_map_origins (same arguments)."""
    import gpu

    if maps_per_vsgl not in (1, 2):
        raise ValueError(f"maps per VSGL must be 1 or 2, got {maps_per_vsgl}")
    count = int(vsgl_count) * maps_per_vsgl
    texture = gpu.types.GPUTexture((max(count, 1), 3), format="RGBA32F")
    if count:
        shader = PASS.shader("origins")
        shader.bind()
        shader.uniform_int("ism_origin_params", (int(vsgl_count), maps_per_vsgl, int(first_map), int(point_sets)))
        shader.uniform_float("ism_own_reflector_sigmas", float(own_reflector_sigmas))
        shader.uniform_sampler("vsgl_table", table_texture)
        shader.image("ism_origins", texture)
        gpu.compute.dispatch(shader, _groups(count, _GROUP[0]), 1, 1)
    return MapOrigins(texture, count)


def build_ism_atlas(points, origins, set_index, size: int = 64, min_distance=0.0, point_area: float = 0.0,
                    timed: bool = False, point_textures=None, planes=None, surfaces: bool = False,
                    normal_offset=None) -> ISMAtlas:
    """:func:`build_ism_atlas_stages` at once."""
    return run_stages(build_ism_atlas_stages(points, origins, set_index, size, min_distance, point_area, timed,
                                             point_textures, planes, surfaces, normal_offset))


def build_ism_atlas_stages(points, origins, set_index, size: int = 64, min_distance=0.0, point_area: float = 0.0,
                           timed: bool = False, point_textures=None, planes=None, surfaces: bool = False,
                           normal_offset=None):
    """A generator that yields after each chunk of SPLATS_PER_STAGE splats and of CLOSED_TEXELS_PER_STAGE
    closed texels (llvmpipe runs a dispatch
    before it returns, so each part's work is done by then) and returns the ISMAtlas: the viewport
    spreads a light build over steps of its time budget. The ISMs of ``origins`` (M, 3) (or a :class:`MapOrigins`, which holds the sets and minimum
    distances too: ``set_index``, ``min_distance`` and ``planes`` are then unused), map m splatting set ``set_index[m]`` of ``points`` (a
    :class:`vsgl_addon.scene_points.ScenePoints`), each ``size``² (a power of two), leaving out the
    points nearer than ``min_distance`` (a scalar, or one per map) and, with ``planes`` (M, 4), the
    points outside map m's half-space (reference keeps_point; none: every point). ``point_area`` > 0 (the surface
    each point stands for) sizes every splat to the solid angle it covers (reference splat_radius);
    0 splats single texels. ``point_textures``: :func:`upload_points` of ``points``, when several
    atlases splat the same sets (uploaded here otherwise). ``timed``: the GPU is waited for after each stage, and the atlas's
    ``seconds`` holds the splat's and the pull-push's time (costs a few read-backs; benchmarks).
    ``surfaces``: oriented splats (reference splat ``plane_depth`` = SPLAT_PLANE_DEPTH, radius capped
    at SURFACE_SPLAT_MAX_RADIUS instead of SPLAT_MAX_RADIUS) and gap
    sides continued as planes (close_gaps ``continued`` = GAP_EXTRAPOLATE); the atlas says so.
    ``normal_offset``: its lookups take the surface normal offset (vsgl_shading; None: ``surfaces``)."""
    import time

    import gpu

    seconds = {}
    clock = time.perf_counter()

    size = int(size)
    if not ISM_SIZE_RANGE[0] <= size <= ISM_SIZE_RANGE[1] or size & (size - 1):
        raise ValueError(f"ISM size must be a power of two in {ISM_SIZE_RANGE}, got {size}")
    if isinstance(origins, MapOrigins):
        count, origin_texture = origins.count, origins.texture
    else:
        origins = np.asarray(origins, np.float64).reshape(-1, 3)
        count, origin_texture = len(origins), None
    if points.points_per_set > MAX_POINTS_PER_SET:
        raise ValueError(f"at most {MAX_POINTS_PER_SET} points per set, got {points.points_per_set}")
    columns, rows = atlas_layout(count, size)
    width, height = columns * size, rows * size
    point_texture, normal_texture = point_textures if point_textures is not None else upload_points(points)
    if origin_texture is None:
        table = np.zeros((3, max(count, 1), 4), np.float32)
        table[0, :count, :3] = origins
        table[0, :count, 3] = np.asarray(set_index).reshape(-1)[:count]
        table[1, :count, 0] = np.broadcast_to(np.asarray(min_distance, np.float64), (count,))
        if planes is not None:
            table[2, :count] = np.asarray(planes, np.float64).reshape(count, 4)
        origin_texture = texture_from_array(table)
    atlas = gpu.types.GPUTexture((width, height), format="R32UI")
    atlas.clear(format="UINT", value=(-1,))  # every texel empty: 0xFFFFFFFF
    if count:
        splat = PASS.shader("splat")

        def bind_splat(first: int) -> None:
            # Again for every chunk: between stages other passes and Blender's drawing rebind the units.
            splat.bind()
            splat.uniform_int("ism_params", (points.points_per_set, count, size, columns))
            splat.uniform_float("ism_point_area", float(point_area))
            splat.uniform_float("ism_plane_depth", float(_reference_ism.SPLAT_PLANE_DEPTH) if surfaces else 0.0)
            splat.uniform_int("ism_max_radius", int(_reference_ism.SURFACE_SPLAT_MAX_RADIUS if surfaces
                                                    else _reference_ism.SPLAT_MAX_RADIUS))
            splat.uniform_int("ism_first_map", first)
            splat.image("scene_points", point_texture)
            splat.image("scene_point_normals", normal_texture)
            splat.image("ism_origins", origin_texture)
            splat.image("ism_atlas", atlas)

        # In chunks of maps, a stage each: the atomic minimum makes the atlas independent of the order.
        chunk = max(1, SPLATS_PER_STAGE // max(points.points_per_set, 1))
        for first in range(0, count, chunk):
            if first:
                yield
            bind_splat(first)
            gpu.compute.dispatch(splat, _groups(points.points_per_set, _GROUP[0]), min(chunk, count - first), 1)
            if timed:
                clock = _finish_stage(atlas, clock, seconds, "splat")
    yield
    # Gaps in near occluders closed (reference close_gaps), into a second atlas that pull-push reads,
    # in bands of atlas rows (whole work groups), a stage each; every texel reads the splatted atlas only.
    closed = gpu.types.GPUTexture((width, height), format="R32UI")
    close = PASS.shader("close")
    band = max(_LEVEL_GROUP[1], CLOSED_TEXELS_PER_STAGE // max(width, 1) // _LEVEL_GROUP[1] * _LEVEL_GROUP[1])
    for first_row in range(0, height, band):
        if first_row:
            yield
        close.bind()
        close.uniform_int("ism_size", size)
        close.uniform_int("ism_continued", 1 if surfaces and _reference_ism.GAP_EXTRAPOLATE else 0)
        close.uniform_int("ism_first_row", first_row)
        close.image("ism_splatted", atlas)
        close.image("ism_closed", closed)
        gpu.compute.dispatch(close, _groups(width, _LEVEL_GROUP[0]),
                             _groups(min(band, height - first_row), _LEVEL_GROUP[1]), 1)
        if timed:
            clock = _finish_stage(closed, clock, seconds, "close")
    atlas = closed
    yield
    # Pull: level l of every tile from level l - 1 (level 0 is the splatted atlas itself).
    levels = int(math.log2(size))
    pulled = []
    pull = PASS.shader("pull")
    for level in range(1, levels + 1):
        coarse = gpu.types.GPUTexture((width >> level, height >> level), format="RG32F")
        pull.bind()
        pull.uniform_int("ism_first_level", 1 if level == 1 else 0)
        pull.image("ism_fine", pulled[-1] if pulled else PASS.resource("unread", lambda: _unknown(1, 1)))
        pull.image("ism_atlas", atlas)
        pull.image("ism_coarse", coarse)
        gpu.compute.dispatch(pull, _groups(width >> level, _LEVEL_GROUP[0]), _groups(height >> level, _LEVEL_GROUP[1]), 1)
        pulled.append(coarse)
    # Push: from the top level down; level 0 reads the atlas. A 1² map has no pyramid: its parent is
    # a texture of unknowns of the atlas's own size.
    filled = pulled[-1] if pulled else _unknown(width, height)
    push = PASS.shader("push")
    for level in range(levels - 1, -1, -1):
        if level == 0:
            push = PASS.shader("push_final")
        target = gpu.types.GPUTexture((width >> level, height >> level), format="RG32F" if level else "R32F")
        push.bind()
        push.uniform_int("ism_first_level", 1 if level == 0 else 0)
        push.image("ism_own", pulled[level - 1] if level > 0 else filled)
        push.image("ism_parent", filled)
        push.image("ism_atlas", atlas)
        push.image("ism_filled", target)
        gpu.compute.dispatch(push, _groups(width >> level, _LEVEL_GROUP[0]), _groups(height >> level, _LEVEL_GROUP[1]), 1)
        filled = target
    if levels == 0:
        push = PASS.shader("push_final")
        target = gpu.types.GPUTexture((width, height), format="R32F")
        push.bind()
        push.uniform_int("ism_first_level", 1)
        push.image("ism_own", filled)
        push.image("ism_parent", filled)
        push.image("ism_atlas", atlas)
        push.image("ism_filled", target)
        gpu.compute.dispatch(push, _groups(width, _LEVEL_GROUP[0]), _groups(height, _LEVEL_GROUP[1]), 1)
        filled = target
    if timed:
        _finish_stage(filled, clock, seconds, "pull_push")
    return ISMAtlas(filled, size, count, columns, rows, seconds, surfaces=bool(surfaces),
                    normal_offset=bool(surfaces if normal_offset is None else normal_offset))


def _unknown(width: int, height: int):
    """An RG32F texture of unknowns (g = 0): the parent of a level with none above it."""
    import gpu

    texture = gpu.types.GPUTexture((width, height), format="RG32F")
    texture.clear(format="FLOAT", value=(0.0, 0.0))
    return texture


PASS = GPUPass(
    name="ism",
    label="Imperfect Shadow Maps",
    step=Step("ism", "Imperfect Shadow Maps"),
    shaders={"origins": ShaderSpec(_origins_interface, {"compute": "ism/ism_origins.comp.glsl"},
                                   code=lambda: {"compute": VSGL_TABLE.glsl("sampler_load")}),
             "splat": ShaderSpec(_splat_interface, {"compute": "ism/ism_splat.comp.glsl"},
                                 defines=lambda: {"ISM_SPLAT_SHARE": repr(float(SPLAT_SHARE))}),
             "close": ShaderSpec(_close_interface, {"compute": "ism/ism_close.comp.glsl"},
                                 defines=lambda: {"ISM_GAP_REACH": GAP_REACH, "ISM_GAP_MARGIN": repr(float(GAP_MARGIN))}),
             "pull": ShaderSpec(_pull_interface, {"compute": "ism/ism_pull.comp.glsl"}),
             "push": ShaderSpec(_push_interface, {"compute": "ism/ism_push.comp.glsl"},
                                defines=lambda: {"ISM_PUSH_FINAL": 0}),
             "push_final": ShaderSpec(lambda: _push_interface(True), {"compute": "ism/ism_push.comp.glsl"},
                                      defines=lambda: {"ISM_PUSH_FINAL": 1, "ISM_UNKNOWN_DEPTH": repr(UNKNOWN_DEPTH)})},
    reads=("scene", "vsgl_table"),  # the scene's surface points, the VSGLs' lobe positions
    writes=("ism_atlas",),
    run=build_ism_atlas,
)
