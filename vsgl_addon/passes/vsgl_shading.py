# SPDX-License-Identifier: GPL-3.0-or-later
"""VSGL shading on the GPU: indirect diffuse and specular radiance of every camera pixel from the
VSGLs of every light (000 app. C; formulas.md §6). Twin of ``vsgl_addon/reference/vsgl_shading.py``
(whose module documentation defines the formulas, C(ξin) included).

    shading = VSGLShading()
    diffuse_tex, specular_tex = shading.run(gbuffer, camera, [VSGLTable.from_generation(gen), ...])
    diffuse, specular = shading.read()     # (h, w, 4) float32, row 0 = bottom
    shading.free()

**Input G-buffer** (:class:`ShadingGBuffer`, RGBA32F textures of one size, row 0 = bottom; the
``position`` and ``normal`` attachments of :data:`vsgl_addon.layouts.GBUFFER` and the textures of
:data:`vsgl_addon.layouts.SHADING_INPUTS`, where the channels are declared):

=======================  ===================================  =================================
texture                  .rgb                                 .a
=======================  ===================================  =================================
``position``             world position                       coverage (> 0: geometry)
``normal``               world shading normal (renormalized)  GGX α, or the perceptual roughness
                                                              (α = r²) if ``roughness_is_perceptual``
``diffuse_reflectance``  Rd (RGB)                             —
``specular_f0``          F0 (RGB, Schlick)                    —
=======================  ===================================  =================================

The ``position`` and ``normal`` textures of :mod:`vsgl_addon.passes.gbuffer` fit as they are
(``roughness_is_perceptual=True``); Rd and F0 are the material model's.

**Camera**: (x, y, z) or (x, y, z, 1) = camera position (perspective: view = normalize(camera −
position)), (x, y, z, 0) = unit direction towards the camera (orthographic), as
``GBuffer.camera_vector``.

**VSGLs**: one or more :class:`VSGLTable` (the RGBA32F table texture of
:class:`~vsgl_addon.passes.vsgl_generation.VSGLGeneration` and its count, read directly on the GPU;
:func:`upload_vsgl_table` makes one from a numpy dict). Tables are drawn one after the other and
added by blending (float32 adds).

**Outputs**: two RGBA32F textures of the G-buffer's size, ``indirect_diffuse`` (Rd × Σ) and
``indirect_specular`` (F0 × Σs + Σf), alpha = coverage; background pixels 0. Radiance in the units
of the VSGL amplitudes (Blender's W/(m² sr) when the RSM carries Blender's light units).

``diffuse_mode``: "separable" (the radiant intensity at the mean's direction times the positional
lobe, cosine pulled out: 000 Eqs. 10-11 and app. C; the modified and original kernels'), "cosine"
(Eq. 12's SG, cosine pulled out, 000 app. C), "sg-convolution" (003's 2-VSGL mode) or
"clamped-cosine" (Eq. 12's SG times the clamped cosine, Tokuyoshi et al. 2024;
``reference.vsgl_shading.diffuse_mode_for_kernel``; the specular is Eq. 12's in every mode). An
entry called without a mode shades as the renderer does for the default kernel
(``reference.vsgl_shading.DEFAULT_DIFFUSE_MODE``). One shader per mode, compiled once per process.
:class:`VSGLShading` keeps its output textures between frames (reallocated when the size changes);
:meth:`VSGLShading.free` drops them.

Cost: linear in pixels × VSGLs (two lobes each). Needs a GPU context, main thread.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..layouts import GBUFFER, SHADING_INPUTS, VSGL_TABLE
from ..reference.vsgl_shading import DEFAULT_DIFFUSE_MODE, DIFFUSE_MODES
from ..shaders import ShaderInterface
from .contract import GPUPass, ShaderSpec, Step
from .gpu_util import fullscreen_triangle_batch, read_texture, set_uniform, texture_from_array
from .vsgl_generation import MAX_VSGL_COUNT

_MODE_INDEX = {"cosine": 0, "sg-convolution": 1, "clamped-cosine": 2, "separable": 3}


#: Largest radius in texels of the visibility filter (its cost grows with (2r + 1)²).
ISM_MAX_RADIUS = 1


def _interface(visibility: bool = False) -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("VEC4", "camera"), ("INT", "vsgl_count"), ("INT", "accumulate"),
                        ("INT", "roughness_is_perceptual")]
        + ([("IVEC4", "ism_params")] if visibility else []),
        # What is read texel by texel is bound as images: on llvmpipe an imageLoad costs a fraction
        # of a texelFetch (benchmarks/results/view_passes_profile.md), the same texels either way.
        # The ISM atlas stays a sampler: its lookup is one textureGather of four texels.
        images=[("RGBA32F", "FLOAT_2D", "gbuffer_position"), ("RGBA32F", "FLOAT_2D", "gbuffer_normal")]
        + [("RGBA32F", "FLOAT_2D", f"shading_inputs_{name}") for name in SHADING_INPUTS.slot_names]
        + [("RGBA32F", "FLOAT_2D", "vsgl_table")],
        samplers=[("FLOAT_2D", "ism_atlas")] if visibility else [],
        vertex_inputs=[("VEC2", "position")],
        varyings=[("VEC2", "uv")],
        fragment_outputs=[("VEC4", "indirect_diffuse"), ("VEC4", "indirect_specular")],
    )


#: Maps per VSGL an ISM atlas can bring (VSGLTable.maps_per_vsgl), each a shader variant.
MAPS_PER_VSGL_CHOICES = (1, 2)


def _shader_spec(diffuse_mode: str, visibility: bool = False, maps_per_vsgl: int = 1,
                 shared_positions: bool = False) -> ShaderSpec:
    # The map count and the table's positional distribution are compiled in: the loop then neither
    # branches on them nor divides map indices (llvmpipe runs both sides of a branch, uniform or not).
    return ShaderSpec(lambda: _interface(visibility), {"vertex": "fullscreen_triangle.vert.glsl",
                                                       "fragment": "vsgl_shading/vsgl_shading.frag.glsl"},
                      defines=lambda: {"VSGL_DIFFUSE_MODE": _MODE_INDEX[diffuse_mode],
                                       "VSGL_VISIBILITY": int(visibility), "VSGL_ISM_MAX_RADIUS": ISM_MAX_RADIUS,
                                       "VSGL_ISM_MAPS": maps_per_vsgl,
                                       "VSGL_SHARED_POSITIONS": int(shared_positions)},
                      code=lambda: {"fragment": GBUFFER.glsl() + SHADING_INPUTS.glsl("images_load")
                                                + VSGL_TABLE.glsl("image_load")})


def run(gbuffer: "ShadingGBuffer", camera, tables, diffuse_mode: str = DEFAULT_DIFFUSE_MODE,
        shading: "VSGLShading | None" = None) -> "VSGLShading":
    """The pass's entry: a :class:`VSGLShading` (new, or `shading` reused) holding the indirect
    images of `gbuffer` (see :meth:`VSGLShading.run`); free it with ``free()``."""
    shading = VSGLShading() if shading is None else shading
    shading.run(gbuffer, camera, tables, diffuse_mode)
    return shading


def _key(diffuse_mode: str, visibility: bool = False, maps_per_vsgl: int = 1, shared_positions: bool = False) -> str:
    return (diffuse_mode + ("+visibility" if visibility else "")
            + (f"+{maps_per_vsgl}maps" if visibility and maps_per_vsgl != 1 else "")
            + ("+shared" if shared_positions else ""))


#: Every variant: diffuse mode × (no visibility, or visibility with each map count) × positional
#: distribution, 4 × 3 × 2 = 24 shaders.
_VARIANTS = tuple((mode, visibility, maps, shared) for mode in _MODE_INDEX
                  for visibility, maps in ((False, 1),) + tuple((True, m) for m in MAPS_PER_VSGL_CHOICES)
                  for shared in (False, True))


#: Shading inputs and VSGL shading are timed together, as the frame always ran them.
SHADING_STEP = Step("vsgl_shading", "VSGL Shading")

PASS = GPUPass(
    name="vsgl_shading",
    label="VSGL Shading",
    step=SHADING_STEP,
    shaders={_key(*variant): _shader_spec(*variant) for variant in _VARIANTS},
    reads=(GBUFFER.name, SHADING_INPUTS.name, VSGL_TABLE.name, "ism_atlas"),
    writes=("indirect",),
    run=run,
)


def shader(diffuse_mode: str = DEFAULT_DIFFUSE_MODE, visibility: bool = False, maps_per_vsgl: int = 1,
           shared_positions: bool = False):
    """The shading shader for `diffuse_mode` (with VSGL visibility from imperfect shadow maps when
    `visibility`, ``maps_per_vsgl`` of them per VSGL; for tables whose lobes share their positions when
    `shared_positions`), compiled on first use and cached for the process."""
    if diffuse_mode not in _MODE_INDEX:
        raise ValueError(f"diffuse_mode must be one of {DIFFUSE_MODES}, got {diffuse_mode!r}")
    if visibility and maps_per_vsgl not in MAPS_PER_VSGL_CHOICES:
        raise ValueError(f"maps per VSGL must be one of {MAPS_PER_VSGL_CHOICES}, got {maps_per_vsgl}")
    return PASS.shader(_key(diffuse_mode, visibility, maps_per_vsgl if visibility else 1, bool(shared_positions)))


compile_shaders = PASS.compile_shaders
free_shaders = PASS.free_shaders


def _fullscreen_triangle():
    return PASS.resource("fullscreen_triangle", lambda: fullscreen_triangle_batch(shader("cosine")))


@dataclass
class ShadingGBuffer:
    """The camera G-buffer shading reads (see the module documentation)."""

    position: object
    normal: object
    diffuse_reflectance: object
    specular_f0: object
    width: int
    height: int
    roughness_is_perceptual: bool = False

    def free(self) -> None:
        """Drop the references to the textures (Blender frees each with its last reference; the
        camera G-buffer keeps its own)."""
        self.position = self.normal = self.diffuse_reflectance = self.specular_f0 = None


def upload_gbuffer(position, coverage, normal, roughness, diffuse_reflectance, specular_f0,
                   roughness_is_perceptual=False) -> ShadingGBuffer:
    """A :class:`ShadingGBuffer` from numpy arrays (h, w, 3) and (h, w) (row 0 = bottom).
    Its textures are freed with the object (Blender frees a GPUTexture with its last reference)."""
    position = np.asarray(position)
    height, width = position.shape[:2]
    gbuffer = GBUFFER.pack_slots({"position": position, "coverage": coverage, "normal": normal,
                                  "roughness": roughness}, (height, width))
    inputs = SHADING_INPUTS.pack_slots({"diffuse_reflectance": diffuse_reflectance, "specular_f0": specular_f0},
                                       (height, width))
    return ShadingGBuffer(
        position=texture_from_array(gbuffer["position"]), normal=texture_from_array(gbuffer["normal"]),
        diffuse_reflectance=texture_from_array(inputs["diffuse_reflectance"]),
        specular_f0=texture_from_array(inputs["specular_f0"]), width=width, height=height,
        roughness_is_perceptual=roughness_is_perceptual)


@dataclass
class VSGLTable:
    """A VSGL table texture (RGBA32F, at least ``count`` columns, :data:`~vsgl_addon.layouts.VSGL_TABLE`).

    ``shared_positions``: both lobes of every VSGL sit at the same position (the paper's shared
    positional distribution, 000 app. B.2), so shading computes the position terms once per VSGL.
    """

    texture: object
    count: int
    shared_positions: bool = False
    # The imperfect shadow maps of its VSGLs (passes/ism.py ISMAtlas): one per VSGL (at its diffuse lobe's
    # position), or two (map 2i the diffuse lobe's, 2i + 1 the specular's); None: no
    # visibility, every VSGL lights every pixel it faces.
    ism: object = None

    @classmethod
    def from_generation(cls, generation, ism=None) -> "VSGLTable":
        """The current table of a :class:`~vsgl_addon.passes.vsgl_generation.VSGLGeneration`."""
        if generation.table is None:
            raise RuntimeError("the VSGL generation has no table: generate() first")
        return cls(generation.table, int(generation.vsgl_count),
                   generation.positional_distribution == "shared", ism)

    @property
    def maps_per_vsgl(self) -> int:
        """Maps of its ISM atlas per VSGL: 1 (at each VSGL's diffuse lobe position, both lobes) or 2 (one
        per lobe position)."""
        if self.ism is not None and self.count > 0:
            return 2 if self.ism.count >= 2 * self.count else 1
        return 1 if self.shared_positions else 2


def table_array(vsgls) -> np.ndarray:
    """The (rows, N, 4) float32 table of a numpy VSGL dict, packed by the declared layout
    (:data:`vsgl_addon.layouts.VSGL_TABLE`); fields the dict lacks stay 0."""
    count = len(np.asarray(vsgls["diffuse_variance"]).reshape(-1))
    return VSGL_TABLE.pack(vsgls, count)


def upload_vsgl_table(vsgls) -> VSGLTable:
    """A :class:`VSGLTable` from a numpy dict (``reference.vsgl.generate_vsgls`` or ``read_table``)."""
    count = len(np.asarray(vsgls["diffuse_variance"]).reshape(-1))
    if count > MAX_VSGL_COUNT:
        raise ValueError(f"at most {MAX_VSGL_COUNT} VSGLs per table, got {count}")
    shared = (np.array_equal(vsgls["diffuse_mean"], vsgls["specular_mean"])
              and np.array_equal(vsgls["diffuse_variance"], vsgls["specular_variance"]))
    return VSGLTable(texture_from_array(table_array(vsgls)), count, bool(shared))


def camera_uniform(camera) -> tuple[float, float, float, float]:
    camera = np.asarray(camera, dtype=np.float64).reshape(-1)
    if camera.shape == (3,):
        camera = np.append(camera, 1.0)
    if camera.shape != (4,) or not np.all(np.isfinite(camera)):
        raise ValueError("camera must be a finite (x, y, z) position or (x, y, z, w) vector")
    return tuple(float(value) for value in camera)


class VSGLShading:
    """The shading pass, keeping its two output textures (and framebuffer) between frames."""

    def __init__(self):
        self.diffuse = None
        self.specular = None
        self._framebuffer = None
        self._size = None
        self._empty_table = None

    def free(self) -> None:
        self._framebuffer = None
        self.diffuse = None
        self.specular = None
        self._size = None
        self._empty_table = None

    def _targets(self, width: int, height: int) -> None:
        import gpu

        if self._size != (width, height):
            self._framebuffer = None
            self.diffuse = gpu.types.GPUTexture((width, height), format="RGBA32F")
            self.specular = gpu.types.GPUTexture((width, height), format="RGBA32F")
            self._framebuffer = gpu.types.GPUFrameBuffer(color_slots=[self.diffuse, self.specular])
            self._size = (width, height)

    def run(self, gbuffer: ShadingGBuffer, camera, tables, diffuse_mode: str = DEFAULT_DIFFUSE_MODE):
        """Shade every pixel of `gbuffer` with every VSGL of `tables` (a VSGLTable or a list);
        returns the (indirect_diffuse, indirect_specular) textures."""
        import gpu

        if isinstance(tables, VSGLTable):
            tables = [tables]
        tables = [table for table in tables if table.count > 0]
        for table in tables:
            if table.count > MAX_VSGL_COUNT:
                raise ValueError(f"at most {MAX_VSGL_COUNT} VSGLs per table, got {table.count}")
        visibility = any(table.ism is not None for table in tables)
        if visibility and not all(table.ism is not None for table in tables):
            raise ValueError("either every table has imperfect shadow maps or none has")
        batch = _fullscreen_triangle()
        width, height = int(gbuffer.width), int(gbuffer.height)
        self._targets(width, height)
        if not tables:  # still one draw: coverage in alpha, zero radiance
            if self._empty_table is None:
                self._empty_table = texture_from_array(np.zeros((len(VSGL_TABLE.slots), 1, 4), np.float32))
            tables = [VSGLTable(self._empty_table, 0)]
        saved = (gpu.state.blend_get(), gpu.state.depth_test_get(), gpu.state.depth_mask_get(),
                 tuple(gpu.state.viewport_get()))
        try:
            with self._framebuffer.bind():
                gpu.state.viewport_set(0, 0, width, height)
                gpu.state.depth_test_set("NONE")
                gpu.state.depth_mask_set(False)
                program = None
                for index, table in enumerate(tables):
                    # One shader per maps-per-VSGL count and positional distribution; tables of one
                    # variant share the bound one.
                    wanted = shader(diffuse_mode, visibility, table.maps_per_vsgl if visibility else 1,
                                    table.shared_positions)
                    if wanted is not program:
                        program = wanted
                        program.bind()
                        set_uniform(program.uniform_float, "camera", camera_uniform(camera))
                        set_uniform(program.uniform_int, "roughness_is_perceptual",
                                    1 if gbuffer.roughness_is_perceptual else 0)
                        program.image("gbuffer_position", gbuffer.position)
                        program.image("gbuffer_normal", gbuffer.normal)
                        program.image("shading_inputs_diffuse_reflectance", gbuffer.diffuse_reflectance)
                        program.image("shading_inputs_specular_f0", gbuffer.specular_f0)
                    # The first table writes, the others add (ONE, ONE), alpha 0.
                    gpu.state.blend_set("NONE" if index == 0 else "ADDITIVE_PREMULT")
                    set_uniform(program.uniform_int, "accumulate", 0 if index == 0 else 1)
                    set_uniform(program.uniform_int, "vsgl_count", int(table.count))
                    program.image("vsgl_table", table.texture)
                    if visibility:
                        program.uniform_int("ism_params", (table.ism.size, table.ism.columns,
                                                           int(getattr(table.ism, "normal_offset", False)), 0))
                        program.uniform_sampler("ism_atlas", table.ism.texture)
                    batch.draw(program)
        finally:
            gpu.state.blend_set(saved[0])
            gpu.state.depth_test_set(saved[1])
            gpu.state.depth_mask_set(saved[2])
            gpu.state.viewport_set(*saved[3])
        return self.diffuse, self.specular

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        """The outputs as float32 (h, w, 4) arrays (reading back waits for the GPU)."""
        width, height = self._size
        return read_texture(self.diffuse, width, height), read_texture(self.specular, width, height)


def shade_gpu(gbuffer: ShadingGBuffer, camera, tables, diffuse_mode: str = DEFAULT_DIFFUSE_MODE,
              shading: VSGLShading | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Run the pass and read it back: (indirect_diffuse, indirect_specular), (h, w, 4) float32.
    `tables`: VSGLTable(s) or numpy VSGL dict(s) (uploaded for this call)."""
    if isinstance(tables, (VSGLTable, dict)):
        tables = [tables]
    tables = [upload_vsgl_table(table) if isinstance(table, dict) else table for table in tables]
    own = shading is None
    shading = VSGLShading() if own else shading
    try:
        shading.run(gbuffer, camera, tables, diffuse_mode)
        return shading.read()
    finally:
        if own:
            shading.free()
