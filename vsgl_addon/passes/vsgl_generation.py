# SPDX-License-Identifier: GPL-3.0-or-later
"""VSGL generation on the GPU: the twin of ``vsgl_addon/reference/vsgl.py`` (formulas.md §5).

000 = Tokuyoshi, "Modified filtered importance sampling for virtual spherical Gaussian lights"
(CVM 2016); 003 = the Square Enix SG talk (simplified 2-VSGL mode).

Four shader stages (``glsl/vsgl_generation/``), compiled once per process and cached:

1. ``texel_moments.frag.glsl``: one fragment per RSM texel writes level 0 of the six **planes**
   (six render targets): the 20 per-texel VPL moment channels of 000 app. B.3 (planes 0-4, the
   reference's channel order: lobes, then each lobe's position moments) and the PDF weight
   (plane 5; by default lum(Φ (Rd + Rs)), or a custom PDF image).
2. ``mip_reduce_level1.frag.glsl``: level 1 of every plane, one draw over their stacked regions
   of the **mip atlas** (one per RSM view, not one per plane), each texel the mean of its 2x2
   children (the reference's ``build_mip_chain``, same order of additions).
   Stages 1-2 are fragment passes because render targets are the fast write path everywhere; on
   llvmpipe compute image stores were ~6x slower (512² atlas: 19 ms instead of 125 ms).
2b. ``mip_reduce.comp.glsl``: levels 2..top, one compute dispatch per level, all five planes at
   once (image load/store in the atlas: reading and writing one texture in a draw would be a
   feedback loop; these levels hold 1/12 of the texels).
3. ``vsgl_kernels.comp.glsl``: one invocation per VSGL: Fibonacci lattice point in exact fixed
   point, hierarchical warp through the PDF plane, kernel level (modified: 000 Eq. 3 by bisection,
   12 iterations; original: Eq. 1), cluster totals (Eq. 5 / Eq. 4) from float32 trilinear lookups
   with exact weights (texel loads, no hardware filtering), VSGL parameters with the reference's
   clamps (``glsl/lib/vsgl_parameters.glsl``), each lobe's position per the positional
   distribution (``reference.vsgl.POSITIONAL_DISTRIBUTIONS``). The 2-VSGL mode reads the atlas's
   top level (the parallel sum comes with the mip chain). With ``plane_split`` a kernel whose
   diffuse normals disagree bins its filter's diffuse moments by the normal class of the texels
   ``reference.vsgl.PLANE_SPLIT_DEPTH`` levels under its taps and writes its extra planes' VSGLs
   into its slots after the N kernels' columns (``reference.vsgl.split_planes``).

Python textures have no mip levels (shared/reference/blender-gpu.md). Level 0 of each plane is its
own S x S texture; levels >= 1 of all planes share one RGBA32F texture, the mip atlas
(``MipAtlasLayout``; ``glsl/lib/mip_atlas.glsl``): with H = S / 2, plane p holds rows
[p H, (p + 1) H), level 1 at (0, p H) and level l >= 2 at (H, p H + H - 2H / 2^(l-1)); its size is
(H + H/2) x 6 H. Six samplers and one image binding serve the later stages; lookups use texel
loads with float32 weights computed in the shader (no hardware filtering, whose weights have
8 bits).

The PDF plane is not normalized: the density p = M · probability is the plane's value divided by
its top-level mean (the same number, rounded differently); an all-zero PDF is uniform, as in the
reference.

Output table (``vsgl_table``, RGBA32F, N columns, column i = VSGL i; its rows and their
channels declared once in :data:`vsgl_addon.layouts.VSGL_TABLE`), kept on the GPU for shading and
read back by :meth:`VSGLGeneration.read_table` into the reference's dict of arrays: the shared
Gaussian (mean, variance: 000 app. B.2), each lobe's amplitude, axis, sharpness and position (the
positions shading places each lobe at), the power, the kernel's centre and level, the level-0 texel
the warp chose (``kernel_texel``, row and column), and once per table ``rsm_total_power``.

RSM input: an :class:`~vsgl_addon.reference.vsgl.RSM` (or mapping) of numpy arrays, uploaded with
:func:`upload_rsm`, or :class:`RSMTextures` already on the GPU (RGBA32F, S x S, the attachments of
:data:`vsgl_addon.layouts.RSM`): the position y, normal n, Φ Rd, Φ Rs, and the specular lobe's
axis ξs and sharpness λs of every texel.

Needs a GPU context (``vsgl_addon.gpu_context.ensure_gpu_context``), main thread.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..layouts import RSM, VSGL_TABLE
from ..reference import vsgl as reference
from ..shaders import ShaderInterface
from .contract import LIGHT_PASSES, GPUPass, ShaderSpec
from .gpu_util import fullscreen_triangle_batch, read_texture, set_uniform, texture_from_array

KERNEL_MODES = reference.KERNEL_MODES  # ("modified", "original", "two-vsgl")
_KERNEL_MODE_INDEX = {"modified": 0, "original": 1, "two-vsgl": 2}
POSITIONAL_DISTRIBUTIONS = reference.POSITIONAL_DISTRIBUTIONS  # ("per-lobe", "shared")
_POSITIONAL_INDEX = {"per-lobe": 0, "shared": 1}

#: Planes of the mip atlas: 5 x 4 moment channels (reference ``MOMENT_CHANNELS``) + the PDF.
ATLAS_PLANES = 6
MOMENT_PLANES = 5
PDF_PLANE = 5
#: Largest VSGL count: the table is one texture row wide (and the lattice's fixed point is exact
#: up to 2^15).
MAX_VSGL_COUNT = 16384
#: Largest RSM side: at 2048 the six level-0 textures and the atlas take ~520 MB of RGBA32F
#: (the atlas, 6 S/2 rows, would fit a 16384-row texture up to S = 4096).
MAX_RSM_SIZE = 2048

_REDUCE_GROUP = (8, 8, 1)
_KERNEL_GROUP = (64, 1, 1)

_LEVEL0_SAMPLERS = [("FLOAT_2D", f"level0_plane{plane}") for plane in range(ATLAS_PLANES)]


def _texel_moments_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("INT", "rsm_size"), ("INT", "use_custom_pdf"), ("INT", "compute_jumps")],
        samplers=[("FLOAT_2D", f"rsm_{name}") for name in RSM.slot_names] + [("FLOAT_2D", "pdf_image")],
        vertex_inputs=[("VEC2", "position")],
        varyings=[("VEC2", "uv")],
        fragment_outputs=[("VEC4", f"level0_out{plane}") for plane in range(ATLAS_PLANES)],
    )


def _mip_reduce_level1_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("INT", "plane_side")],
        samplers=_LEVEL0_SAMPLERS,
        vertex_inputs=[("VEC2", "position")],
        varyings=[("VEC2", "uv")],
        fragment_outputs=[("VEC4", "level1_out")],
    )


def _mip_reduce_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("INT", "rsm_size"), ("INT", "level")],
        samplers=_LEVEL0_SAMPLERS,  # declared for glsl/lib/mip_atlas.glsl, unused
        images=[_ATLAS_IMAGE],
        local_group_size=_REDUCE_GROUP,
    )


def _vsgl_kernels_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("INT", "rsm_size"), ("INT", "vsgl_count"), ("INT", "kernel_mode"),
                        ("INT", "positional_distribution"), ("FLOAT", "kernel_k"),
                        ("IVEC2", "lattice_rotation_fixed"), ("INT", "split_at_jumps"), ("INT", "plane_split")],
        samplers=_LEVEL0_SAMPLERS,
        images=[_ATLAS_IMAGE, ("RGBA32F", "FLOAT_2D", "vsgl_table")],
        local_group_size=_KERNEL_GROUP,
    )


_ATLAS_IMAGE = ("RGBA32F", "FLOAT_2D", "mip_atlas")
_FULLSCREEN = "fullscreen_triangle.vert.glsl"


def run(rsm, vsgl_count, k=1.0, kernel="modified", seed=0, pdf=None, rotation=None,
        positional_distribution="per-lobe", generation: "VSGLGeneration | None" = None) -> "VSGLGeneration":
    """The pass's entry: a :class:`VSGLGeneration` (new, or `generation` reused) holding the table of
    `rsm` on the GPU (see :meth:`VSGLGeneration.run`); free it with ``free()``."""
    generation = VSGLGeneration() if generation is None else generation
    generation.run(rsm, vsgl_count, k, kernel, seed, pdf, rotation, positional_distribution)
    return generation


PASS = GPUPass(
    name="vsgl_generation",
    label="VSGL Generation",
    step=LIGHT_PASSES,
    shaders={
        "texel_moments": ShaderSpec(_texel_moments_interface,
                                    {"vertex": _FULLSCREEN, "fragment": "vsgl_generation/texel_moments.frag.glsl"},
                                    defines=lambda: {"JUMP_TEXELS": float(reference.JUMP_TEXELS)},
                                    code=lambda: {"fragment": RSM.glsl("samplers_load")}),
        "mip_reduce_level1": ShaderSpec(_mip_reduce_level1_interface,
                                        {"vertex": _FULLSCREEN,
                                         "fragment": "vsgl_generation/mip_reduce_level1.frag.glsl"}),
        "mip_reduce": ShaderSpec(_mip_reduce_interface, {"compute": "vsgl_generation/mip_reduce.comp.glsl"}),
        "vsgl_kernels": ShaderSpec(_vsgl_kernels_interface,
                                   {"compute": "vsgl_generation/vsgl_kernels.comp.glsl"},
                                   defines=lambda: {"STRADDLE_SHARE": float(reference.STRADDLE_SHARE),
                                                    "NORMAL_AGREEMENT": float(reference.NORMAL_AGREEMENT),
                                                    "SNAP_TO_TEXEL": int(bool(reference.SNAP_TO_TEXEL)),
                                                    "MAX_DESCENT": int(reference.MAX_DESCENT),
                                                    "PLANE_SPLIT_DEPTH": int(reference.PLANE_SPLIT_DEPTH),
                                                    "PLANE_SPLIT_SHARE": float(reference.PLANE_SPLIT_SHARE),
                                                    "PLANE_SPLIT_EXTRA": int(reference.PLANE_SPLIT_EXTRA)},
                                   code=lambda: {"compute": VSGL_TABLE.glsl("image_store")}),
    },
    reads=(RSM.name,),
    writes=(VSGL_TABLE.name,),
    run=run,
)


def shader(name: str):
    """The compiled stage `name` (texel_moments, mip_reduce_level1, mip_reduce, vsgl_kernels),
    compiled on first use and cached for the process."""
    return PASS.shader(name)


def _fullscreen_triangle():
    """The batch of one triangle covering the viewport (glsl/fullscreen_triangle.vert.glsl)."""
    return PASS.resource("fullscreen_triangle", lambda: fullscreen_triangle_batch(shader("texel_moments")))


compile_shaders = PASS.compile_shaders
free_shaders = PASS.free_shaders


def _groups(count: int, group: int) -> int:
    return max(1, -(-int(count) // group))


# --- Textures --------------------------------------------------------------------------------
# RGBA32F uploads and read-backs come from .gpu_util.


@dataclass
class RSMTextures:
    """An RSM on the GPU: RGBA32F textures of side ``size`` (a power of two), one per attachment of
    :data:`vsgl_addon.layouts.RSM` (which declares their channels). Background texels (no flux) may
    hold anything.
    """

    size: int
    position: object
    normal: object
    flux_diffuse: object
    flux_specular: object
    specular_axis: object


def upload_rsm(rsm) -> RSMTextures:
    """Validate an RSM (as the reference does) and upload it as :class:`RSMTextures`."""
    rsm = reference.RSM.coerce(rsm)
    if rsm.size > MAX_RSM_SIZE:
        raise ValueError(f"RSM side {rsm.size} exceeds {MAX_RSM_SIZE}")
    lit_s = reference.luminance(rsm.flux_specular) > 0.0
    sharpness = np.where(lit_s, rsm.specular_sharpness, 0.0)
    if np.any(np.isnan(sharpness)) or np.any(sharpness < 0.0):
        raise ValueError("specular_sharpness of lit texels must be >= 0 (inf allowed)")
    lit = reference.luminance(rsm.flux_diffuse + rsm.flux_specular) > 0.0
    if not np.all(np.isfinite(rsm.position[lit])):
        raise ValueError("position of lit texels must be finite")
    fields = {"position": rsm.position, "specular_sharpness": sharpness, "normal": rsm.normal,
              "flux_diffuse": rsm.flux_diffuse, "flux_specular": rsm.flux_specular,
              "specular_axis": rsm.specular_axis}
    with np.errstate(over="ignore", invalid="ignore"):
        texels = RSM.pack_slots(fields, (rsm.size, rsm.size))
    return RSMTextures(size=rsm.size, **{name: texture_from_array(texels[name]) for name in RSM.slot_names})


def upload_pdf(pdf, size: int):
    """A custom PDF image (H, W), finite and non-negative (normalized on the GPU), as a texture."""
    pdf = np.asarray(pdf, dtype=np.float64)
    if pdf.shape != (size, size):
        raise ValueError(f"pdf must have shape {(size, size)}, got {pdf.shape}")
    if not np.all(np.isfinite(pdf)) or np.any(pdf < 0.0):
        raise ValueError("a PDF image must be finite and non-negative")
    data = np.zeros((size, size, 4), dtype=np.float32)
    data[..., 0] = pdf
    return texture_from_array(data)


# --- Mip atlas ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class MipAtlasLayout:
    """Where level l >= 1 of plane p of an RSM of side ``size`` lies in the atlas
    (glsl/lib/mip_atlas.glsl); level 0 of each plane is a texture of its own."""

    size: int
    planes: int = ATLAS_PLANES

    @property
    def top_level(self) -> int:
        return self.size.bit_length() - 1

    @property
    def width(self) -> int:
        half = self.size // 2
        return max(1, half + half // 2)

    @property
    def height(self) -> int:
        return max(1, self.planes * (self.size // 2))

    def origin(self, level: int, plane: int) -> tuple[int, int]:
        """(x, y) of texel (0, 0) of level `level` >= 1."""
        if level < 1:
            raise ValueError("level 0 is not in the atlas")
        half = self.size // 2
        y = plane * half
        if level == 1:
            return 0, y
        return half, y + half - ((2 * half) >> (level - 1))

    def level(self, atlas: np.ndarray, level: int, plane: int) -> np.ndarray:
        """Level `level` >= 1 of plane `plane`, (side, side, 4), from a read-back atlas."""
        x, y = self.origin(level, plane)
        side = self.size >> level
        return atlas[y:y + side, x:x + side]


def rotation_fixed_point(rotation) -> tuple[int, int]:
    """A lattice shift in [0, 1)^2 as 32-bit fixed point (int32 bit patterns for push constants)."""
    rotation = np.asarray(rotation, dtype=np.float64).reshape(2)
    rotation = rotation - np.floor(rotation)
    fixed = [int(np.floor(value * 2.0**32)) % 2**32 for value in rotation]
    return tuple(value - 2**32 if value >= 2**31 else value for value in fixed)


# --- The pass ----------------------------------------------------------------------------------


def _check_arguments(vsgl_count, k, kernel, positional_distribution="per-lobe") -> tuple[int, float]:
    """(row count, K) after validation; 'two-vsgl' always has 2 rows."""
    if kernel not in _KERNEL_MODE_INDEX:
        raise ValueError(f"kernel must be one of {KERNEL_MODES}, got {kernel!r}")
    if positional_distribution not in _POSITIONAL_INDEX:
        raise ValueError(f"positional_distribution must be one of {POSITIONAL_DISTRIBUTIONS}, "
                         f"got {positional_distribution!r}")
    count = 2 if kernel == "two-vsgl" else int(vsgl_count)
    if not 1 <= count <= MAX_VSGL_COUNT:
        raise ValueError(f"vsgl_count must be in [1, {MAX_VSGL_COUNT}], got {count}")
    k = float(k)
    if not (np.isfinite(k) and k > 0.0):
        raise ValueError(f"k must be finite and positive, got {k}")
    return count, k


class VSGLGeneration:
    """VSGL generation, keeping its GPU textures (mip atlas, output table) between frames.

    Per frame: :meth:`build_mip_atlas` (stages 1, 2, 2b), then :meth:`generate` (stage 3); the table
    stays on the GPU (:attr:`table`) and :meth:`read_table` reads it back. Textures are reallocated
    only when the RSM side or the VSGL count changes. :meth:`free` drops them.
    """

    def __init__(self):
        self.level0: list | None = None  # level 0 of each plane, S x S textures
        self._framebuffer = None
        self._atlas_framebuffer = None
        self.atlas = None  # levels >= 1 of every plane
        self.layout: MipAtlasLayout | None = None
        self.table = None
        self.table_width = 0
        self.vsgl_count = 0  # the table's columns: the kernels', then their plane-split slots
        self.kernel_count = 0
        self.plane_split = False  # of the current table
        self.positional_distribution = "per-lobe"  # of the current table

    def free(self) -> None:
        """Release the textures (Blender frees a GPUTexture with its last reference)."""
        self._framebuffer = None
        self._atlas_framebuffer = None
        self.level0 = None
        self.atlas = None
        self.layout = None
        self.table = None
        self.table_width = 0
        self.vsgl_count = 0
        self.kernel_count = 0

    def build_mip_atlas(self, rsm_textures: RSMTextures, pdf_texture=None, jumps=None) -> None:
        """Stages 1, 2 and 2b: level 0 from the RSM, then the mip levels of every plane. ``jumps``:
        plane 5's power on texels beside a depth discontinuity (what :meth:`generate`'s
        ``split_at_jumps`` reads; four neighbour loads per texel), or zero; None reads
        reference.SPLIT_AT_JUMPS."""
        import gpu

        size = int(rsm_textures.size)
        if size < 1 or size & (size - 1) or size > MAX_RSM_SIZE:
            raise ValueError(f"RSM side must be a power of two <= {MAX_RSM_SIZE}, got {size}")
        layout = MipAtlasLayout(size)
        if self.layout != layout:
            self._framebuffer = None
            self.level0 = [gpu.types.GPUTexture((size, size), format="RGBA32F")
                           for _ in range(ATLAS_PLANES)]
            self._framebuffer = gpu.types.GPUFrameBuffer(color_slots=self.level0)
            self.atlas = gpu.types.GPUTexture((layout.width, layout.height), format="RGBA32F")
            self._atlas_framebuffer = gpu.types.GPUFrameBuffer(color_slots=[self.atlas])
            self.layout = layout

        moments = shader("texel_moments")
        batch = _fullscreen_triangle()
        saved = (gpu.state.blend_get(), gpu.state.depth_test_get(), gpu.state.depth_mask_get(),
                 tuple(gpu.state.viewport_get()))
        try:
            with self._framebuffer.bind():
                gpu.state.viewport_set(0, 0, size, size)
                gpu.state.blend_set("NONE")
                gpu.state.depth_test_set("NONE")
                gpu.state.depth_mask_set(False)
                moments.bind()
                set_uniform(moments.uniform_int, "rsm_size", size)
                set_uniform(moments.uniform_int, "use_custom_pdf", 0 if pdf_texture is None else 1)
                jumps = reference.SPLIT_AT_JUMPS if jumps is None else jumps
                set_uniform(moments.uniform_int, "compute_jumps", int(bool(jumps)))
                for name in RSM.slot_names:
                    moments.uniform_sampler(f"rsm_{name}", getattr(rsm_textures, name))
                set_uniform(moments.uniform_sampler, "pdf_image",
                            pdf_texture if pdf_texture is not None else rsm_textures.flux_diffuse)
                batch.draw(moments)
            if layout.top_level >= 1:
                # Level 1 of every plane: one draw over the atlas's level-1 column (planes stacked).
                first = shader("mip_reduce_level1")
                side = size >> 1
                with self._atlas_framebuffer.bind():
                    first.bind()
                    gpu.state.viewport_set(0, 0, side, side * ATLAS_PLANES)
                    set_uniform(first.uniform_int, "plane_side", side)
                    for plane, texture in enumerate(self.level0):
                        first.uniform_sampler(f"level0_plane{plane}", texture)
                    batch.draw(first)
        finally:
            gpu.state.blend_set(saved[0])
            gpu.state.depth_test_set(saved[1])
            gpu.state.depth_mask_set(saved[2])
            gpu.state.viewport_set(*saved[3])

        if layout.top_level < 1:
            return
        reduce = shader("mip_reduce")
        reduce.bind()
        set_uniform(reduce.uniform_int, "rsm_size", size)
        reduce.image("mip_atlas", self.atlas)
        for level in range(2, layout.top_level + 1):
            side = size >> level
            set_uniform(reduce.uniform_int, "level", level)
            gpu.compute.dispatch(reduce, _groups(side, _REDUCE_GROUP[0]), _groups(side, _REDUCE_GROUP[1]),
                                 ATLAS_PLANES)

    def _bind_levels(self, program) -> None:
        """Bind the mip chains for reading (level-0 textures as samplers, the atlas as an image)."""
        for plane, texture in enumerate(self.level0):
            set_uniform(program.uniform_sampler, f"level0_plane{plane}", texture)
        program.image("mip_atlas", self.atlas)

    def generate(self, vsgl_count: int, k: float = 1.0, kernel: str = "modified",
                 rotation=(0.0, 0.0), positional_distribution: str = "per-lobe", split_at_jumps=None,
                 plane_split=None):
        """Stage 3 on the current mip atlas; returns the table texture (see the module doc).
        ``split_at_jumps``: the kernels descend off depth discontinuities (reference
        ``kernel_level_unstraddled``); None reads reference.SPLIT_AT_JUMPS. ``plane_split``:
        clusters over several planes add a VSGL per plane (reference ``split_planes``; None reads
        reference.PLANE_SPLIT): the table then has reference.PLANE_SPLIT_EXTRA slots per kernel
        after the kernels' columns, zero where unused (:meth:`read_table` drops those)."""
        import gpu

        if self.atlas is None:
            raise RuntimeError("build_mip_atlas() first")
        count, k = _check_arguments(vsgl_count, k, kernel, positional_distribution)
        split_planes = reference.plane_split_applies(
            reference.PLANE_SPLIT if plane_split is None else plane_split, kernel, count)
        width = count * (1 + reference.PLANE_SPLIT_EXTRA) if split_planes else count
        if self.table is None or self.table_width != width:
            self.table = gpu.types.GPUTexture((width, len(VSGL_TABLE.slots)), format="RGBA32F")
            self.table_width = width
        self.vsgl_count = width
        self.kernel_count = count
        self.plane_split = split_planes
        self.positional_distribution = positional_distribution
        kernels = shader("vsgl_kernels")
        kernels.bind()
        set_uniform(kernels.uniform_int, "rsm_size", self.layout.size)
        set_uniform(kernels.uniform_int, "vsgl_count", count)
        set_uniform(kernels.uniform_int, "kernel_mode", _KERNEL_MODE_INDEX[kernel])
        set_uniform(kernels.uniform_int, "positional_distribution",
                    _POSITIONAL_INDEX[positional_distribution])
        set_uniform(kernels.uniform_float, "kernel_k", k)
        set_uniform(kernels.uniform_int, "lattice_rotation_fixed", rotation_fixed_point(rotation))
        # reference.SPLIT_AT_JUMPS read at each generation, as the reference reads it per call.
        split = reference.SPLIT_AT_JUMPS if split_at_jumps is None else split_at_jumps
        set_uniform(kernels.uniform_int, "split_at_jumps", int(bool(split)))
        set_uniform(kernels.uniform_int, "plane_split", int(split_planes))
        self._bind_levels(kernels)
        kernels.image("vsgl_table", self.table)
        gpu.compute.dispatch(kernels, _groups(count, _KERNEL_GROUP[0]), 1, 1)
        return self.table

    def read_table(self) -> dict:
        """The table as the reference's dict of float64 arrays (reading back finishes the GPU),
        without the unused plane-split slots (reference ``compact_plane_split``)."""
        count = self.vsgl_count
        table = read_texture(self.table, self.table_width, len(VSGL_TABLE.slots)).astype(np.float64)
        table = VSGL_TABLE.unpack(table, count)
        return reference.compact_plane_split(table, self.kernel_count) if self.plane_split else table

    def read_mip_chains(self) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """The mip chains as the reference's ``RSMMipmaps`` holds them (float32 values):
        ``moments`` (levels of (side, side, 20)) and ``pdf`` (levels of (side, side), the density:
        the PDF plane divided by its top-level mean; 1 everywhere for an all-zero PDF)."""
        layout = self.layout
        size = layout.size
        atlas = read_texture(self.atlas, layout.width, layout.height)
        planes = [[read_texture(texture, size, size) for texture in self.level0]]
        for level in range(1, layout.top_level + 1):
            planes.append([layout.level(atlas, level, plane) for plane in range(ATLAS_PLANES)])
        moments = [np.concatenate(level[:MOMENT_PLANES], axis=-1) for level in planes]
        pdf = [level[PDF_PLANE][..., 0].astype(np.float64) for level in planes]
        top = pdf[-1][0, 0]
        pdf = [p / top if top > 0.0 else np.ones_like(p) for p in pdf]
        return moments, pdf

    def run(self, rsm, vsgl_count, k=1.0, kernel="modified", seed=0, pdf=None, rotation=None,
            positional_distribution="per-lobe"):
        """Upload (if numpy), build the atlas and generate; returns the table texture."""
        _check_arguments(vsgl_count, k, kernel, positional_distribution)
        textures = rsm if isinstance(rsm, RSMTextures) else upload_rsm(rsm)
        pdf_texture = None
        if pdf is not None and kernel != "two-vsgl":
            pdf_texture = pdf if not isinstance(pdf, np.ndarray) else upload_pdf(pdf, textures.size)
        self.build_mip_atlas(textures, pdf_texture)
        return self.generate(vsgl_count, k, kernel, reference.lattice_rotation(seed, rotation),
                             positional_distribution)


def generate_vsgls_gpu(rsm, vsgl_count, k=1.0, kernel="modified", seed=0, pdf=None, rotation=None,
                       generation: VSGLGeneration | None = None,
                       positional_distribution="per-lobe") -> dict:
    """GPU twin of ``reference.vsgl.generate_vsgls`` (same arguments, same dict of arrays).

    rsm         an RSM / mapping of numpy arrays, or :class:`RSMTextures` already on the GPU.
    vsgl_count  N in [1, 16384] (ignored by 'two-vsgl', which returns 2 rows).
    k           K > 0 (000 Eq. 1 and Eq. 3).
    kernel      'modified' (default), 'original' or 'two-vsgl'.
    seed, rotation  the lattice's Cranley-Patterson shift, as in the reference.
    pdf         optional (H, W) numpy PDF image or a GPU texture (R channel).
    positional_distribution  "per-lobe" (default) or "shared" (000 app. B.2 as written).
    generation  a :class:`VSGLGeneration` to reuse (its textures stay allocated); by default a
                temporary one whose textures are released before returning.
    """
    own = generation is None
    generation = VSGLGeneration() if own else generation
    try:
        generation.run(rsm, vsgl_count, k, kernel, seed, pdf, rotation, positional_distribution)
        return generation.read_table()
    finally:
        if own:
            generation.free()
