"""Evaluate GLSL functions on the GPU over many parameter points, for comparison with numpy.

    values = evaluate_glsl("sg_evaluate(omega, axis, sharpness)",
                           {"omega": omega, "axis": axis, "sharpness": sharpness},
                           libraries=["lib/sg.glsl"])

Each input is an (n,) or (n, k ≤ 4) array, rounded to float32 (what the GPU sees; use
:func:`as_gpu_floats` to get the same values for the reference) and visible in the GLSL body as a
local ``float``/``vecK`` of the same name. The n points are laid out on a W×H grid of fragments; all
inputs share one RGBA32F texture (input j fills rows j·H … j·H+H−1) and are read with texelFetch.
One full-screen triangle is drawn into RGBA32F colour attachments (one per output, at most 6), and
the attachments are read back as float64.

``body`` is GLSL statements run in ``main()`` that assign the outputs; a bare expression (no ``;``)
means ``result = (expression);``. ``outputs`` is the number of floats of the single output
``result`` (1 → shape (n,), k → (n, k)), or a dict ``{name: k}`` of several outputs, returned as a
dict of arrays. Outputs start at 0. ``declarations`` is GLSL placed before ``main()`` (helpers);
``libraries`` are ``@require``d (``lib/sg.glsl``), looked up in ``roots`` first, then in ``glsl/``.
``images`` (name → (H, W, 4) array, row 0 = texture row 0) are RGBA32F textures bound to samplers
of those names, for functions that read an image (``lib/image.glsl``).

A compiled probe is cached by its source, so evaluating the same body again (other inputs, other n)
costs no shader compile (40–60 ms of JIT each on llvmpipe). Needs a GPU context (main thread).
Fragment shader arithmetic flushes denormals to zero on llvmpipe: inputs below ~1.2e-38 arrive as 0
(compute shaders keep them; denormal_mode.py).
"""

from __future__ import annotations

import atexit
import hashlib
import math
import shutil
import tempfile
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from vsgl_addon.shaders import GLSL_ROOT, ShaderCompileError, ShaderInterface, create_shader

MAX_OUTPUTS = 6  # colour attachments of a GPUFrameBuffer
MAX_SIDE = 16384  # texture and viewport side on llvmpipe (and most GPUs)
_WIDTH = 2048  # grid width when n is large

_GLSL_TYPES = {1: "float", 2: "vec2", 3: "vec3", 4: "vec4"}
_SWIZZLES = {1: ".x", 2: ".xy", 3: ".xyz", 4: ""}
_ZERO = {1: "0.0", 2: "vec2(0.0)", 3: "vec3(0.0)", 4: "vec4(0.0)"}
_PADDING = {1: ", 0.0, 0.0, 0.0", 2: ", 0.0, 0.0", 3: ", 0.0", 4: ""}

_stage_folder: Path | None = None
_probes: dict[str, "GLSLProbe"] = {}


def as_gpu_floats(values) -> np.ndarray:
    """`values` as the GPU sees them (rounded to float32), returned as float64 for a reference."""
    return np.asarray(values, dtype=np.float64).astype(np.float32).astype(np.float64)


def _stage_dir() -> Path:
    """A per-process folder for generated stage files (removed at exit)."""
    global _stage_folder
    if _stage_folder is None:
        _stage_folder = Path(tempfile.mkdtemp(prefix="vsgl_glsl_probe_"))
        atexit.register(shutil.rmtree, _stage_folder, True)
    return _stage_folder


def _components(shape: tuple[int, ...], name: str) -> int:
    if len(shape) == 1:
        return 1
    if len(shape) == 2 and 1 <= shape[1] <= 4:
        return shape[1]
    raise ValueError(f"input '{name}' must have shape (n,) or (n, k<=4), not {shape}")


class GLSLProbe:
    """One compiled probe shader: call it with a dict of input arrays to evaluate the body."""

    def __init__(self, body: str, input_sizes: Mapping[str, int], outputs: int | Mapping[str, int] = 1,
                 *, libraries: Sequence[str] = (), declarations: str = "",
                 roots: Sequence[Path] = (), image_names: Sequence[str] = ()):
        import gpu
        from gpu_extras.batch import batch_for_shader

        self.single = not isinstance(outputs, Mapping)
        self.outputs = {"result": outputs} if self.single else dict(outputs)
        if not 1 <= len(self.outputs) <= MAX_OUTPUTS:
            raise ValueError(f"between 1 and {MAX_OUTPUTS} outputs, not {len(self.outputs)}")
        for name, size in self.outputs.items():
            if size not in _GLSL_TYPES:
                raise ValueError(f"output '{name}' must have 1 to 4 floats, not {size}")
        self.input_sizes = dict(input_sizes)
        if ";" not in body:
            if not self.single:
                raise ValueError("a bare expression needs a single output")
            body = f"result = ({body});"
        self.source = self._stage_source(body, libraries, declarations)
        digest = hashlib.sha1(self.source.encode()).hexdigest()[:16]
        stage = f"probe_{digest}.frag.glsl"
        (_stage_dir() / stage).write_text(self.source, encoding="utf-8")
        interface = ShaderInterface(
            push_constants=[("INT", "probe_rows")],
            samplers=([("FLOAT_2D", "probe_inputs")] if self.input_sizes else [])
            + [("FLOAT_2D", name) for name in image_names],
            vertex_inputs=[("VEC2", "position")],
            varyings=[("VEC2", "uv")],
            fragment_outputs=[("VEC4", f"probe_out_{name}") for name in self.outputs],
        )
        try:
            self.shader = create_shader(f"glsl_probe_{digest}", interface,
                                        vertex="fullscreen_triangle.vert.glsl", fragment=stage,
                                        root=[_stage_dir(), *roots, GLSL_ROOT])
        except ShaderCompileError as error:
            numbered = "\n".join(f"{number:4d}  {line}"
                                 for number, line in enumerate(self.source.splitlines(), start=1))
            error.add_note(f"generated stage {stage}:\n{numbered}")
            raise
        self.batch = batch_for_shader(self.shader, "TRIS",
                                      {"position": [(-1.0, -1.0), (3.0, -1.0), (-1.0, 3.0)]})
        self._gpu = gpu
        self.image_names = tuple(image_names)

    def _stage_source(self, body: str, libraries: Sequence[str], declarations: str) -> str:
        lines = [f"// @require {library}" for library in libraries]
        lines.append("// Generated by tests/glsl_harness.py.")
        if declarations:
            lines.append(declarations.rstrip("\n"))
        lines += ["void main()", "{", "  ivec2 probe_texel = ivec2(gl_FragCoord.xy);"]
        for index, (name, size) in enumerate(self.input_sizes.items()):
            lines.append(f"  {_GLSL_TYPES[size]} {name} = texelFetch(probe_inputs, "
                         f"probe_texel + ivec2(0, {index} * probe_rows), 0){_SWIZZLES[size]};")
        for name, size in self.outputs.items():
            lines.append(f"  {_GLSL_TYPES[size]} {name} = {_ZERO[size]};")
        lines.append("  {")
        lines += [f"    {line}" for line in body.strip("\n").splitlines()]
        lines.append("  }")
        for name, size in self.outputs.items():
            lines.append(f"  probe_out_{name} = vec4({name}{_PADDING[size]});")
        lines.append("}")
        return "\n".join(lines) + "\n"

    def __call__(self, inputs: Mapping[str, np.ndarray],
                 images: Mapping[str, np.ndarray] | None = None) -> np.ndarray | dict[str, np.ndarray]:
        gpu = self._gpu
        if set(inputs) != set(self.input_sizes):
            raise ValueError(f"inputs {sorted(inputs)} differ from the probe's {sorted(self.input_sizes)}")
        images = dict(images or {})
        if set(images) != set(self.image_names):
            raise ValueError(f"images {sorted(images)} differ from the probe's {sorted(self.image_names)}")
        image_textures = {}
        for name, image in images.items():
            data = np.ascontiguousarray(image, dtype=np.float32)
            if data.ndim != 3 or data.shape[2] != 4:
                raise ValueError(f"image '{name}' must have shape (H, W, 4), not {data.shape}")
            image_textures[name] = gpu.types.GPUTexture((data.shape[1], data.shape[0]), format="RGBA32F",
                                                        data=gpu.types.Buffer("FLOAT", data.shape, data))
        arrays = {}
        counts = set()
        for name, size in self.input_sizes.items():
            array = np.asarray(inputs[name], dtype=np.float32)
            if _components(array.shape, name) != size:
                raise ValueError(f"input '{name}' has shape {array.shape}, the probe expects {size} floats")
            arrays[name] = array.reshape(len(array), size)
            counts.add(len(array))
        if len(counts) != 1:
            raise ValueError(f"inputs differ in length: { {n: len(a) for n, a in arrays.items()} }")
        n = counts.pop()
        if n == 0:
            empty = {name: np.zeros((0,) if size == 1 else (0, size)) for name, size in self.outputs.items()}
            return empty["result"] if self.single else empty
        width = min(n, _WIDTH)
        rows = math.ceil(n / width)
        if rows * max(len(arrays), 1) > MAX_SIDE:
            raise ValueError(f"{n} points x {len(arrays)} inputs do not fit one {MAX_SIDE}-texel texture")

        texture = None
        if arrays:
            packed = np.zeros((len(arrays), rows * width, 4), dtype=np.float32)
            for index, array in enumerate(arrays.values()):
                packed[index, :n, :array.shape[1]] = array
            packed = np.ascontiguousarray(packed.reshape(len(arrays) * rows, width, 4))
            texture = gpu.types.GPUTexture((width, len(arrays) * rows), format="RGBA32F",
                                           data=gpu.types.Buffer("FLOAT", packed.shape, packed))
        targets = [gpu.types.GPUTexture((width, rows), format="RGBA32F") for _ in self.outputs]
        framebuffer = gpu.types.GPUFrameBuffer(color_slots=targets)
        with framebuffer.bind():
            framebuffer.clear(color=(math.nan, math.nan, math.nan, math.nan))
            gpu.state.viewport_set(0, 0, width, rows)
            gpu.state.blend_set("NONE")
            gpu.state.depth_test_set("NONE")
            gpu.state.depth_mask_set(False)
            gpu.state.face_culling_set("NONE")
            self.shader.bind()
            # The compiler drops unused inputs (a body that folds to a constant reads none).
            try:
                self.shader.uniform_int("probe_rows", rows)
            except ValueError:
                pass
            if texture is not None:
                self.shader.uniform_sampler("probe_inputs", texture)
            for name, image_texture in image_textures.items():
                self.shader.uniform_sampler(name, image_texture)
            self.batch.draw(self.shader)

        results = {}
        for (name, size), target in zip(self.outputs.items(), targets):
            buffer = target.read()
            # np.asarray on a multi-dimensional gpu Buffer gets the strides wrong: flatten first.
            buffer.dimensions = rows * width * 4
            values = np.array(buffer, dtype=np.float32).reshape(rows * width, 4)[:n, :size]
            values = values.astype(np.float64)
            results[name] = values[:, 0] if size == 1 else values
        return results["result"] if self.single else results


def probe(body: str, input_sizes: Mapping[str, int], outputs: int | Mapping[str, int] = 1, *,
          libraries: Sequence[str] = (), declarations: str = "", roots: Sequence[Path] = (),
          image_names: Sequence[str] = ()) -> GLSLProbe:
    """The compiled probe for this body and interface (cached by its source, samplers and the
    libraries' current defines, shaders.LIBRARY_DEFINES)."""
    from vsgl_addon.shaders import LIBRARY_DEFINES

    defines = [(library, sorted(LIBRARY_DEFINES[library]().items())) for library in sorted(LIBRARY_DEFINES)]
    key = repr((body, defines, list(input_sizes.items()),
                outputs if not isinstance(outputs, Mapping) else list(outputs.items()),
                list(libraries), declarations, [str(root) for root in roots], list(image_names)))
    if key not in _probes:
        _probes[key] = GLSLProbe(body, input_sizes, outputs, libraries=libraries,
                                 declarations=declarations, roots=roots, image_names=image_names)
    return _probes[key]


def evaluate_glsl(body: str, inputs: Mapping[str, np.ndarray], outputs: int | Mapping[str, int] = 1, *,
                  libraries: Sequence[str] = (), declarations: str = "",
                  roots: Sequence[Path] = (),
                  images: Mapping[str, np.ndarray] | None = None) -> np.ndarray | dict[str, np.ndarray]:
    """Evaluate `body` at every point of `inputs` on the GPU; float64 results (see the module doc)."""
    sizes = {}
    for name, values in inputs.items():
        sizes[name] = _components(np.shape(values), name)
    images = dict(images or {})
    return probe(body, sizes, outputs, libraries=libraries, declarations=declarations, roots=roots,
                 image_names=sorted(images))(inputs, images)


# --- Comparison with a float64 reference -------------------------------------------------------

RELATIVE_TOLERANCE = 1e-4
ABSOLUTE_TOLERANCE = 1e-7
SIGNIFICANT_FRACTION = 1e-6


class Accuracy:
    """How a GPU result compares with its float64 reference, by the project's criterion:

    relative error <= `relative` wherever |reference| > `significant` * M, M the largest |reference|
    of the point's group, absolute error <= `absolute` * max(M, 1) elsewhere, and every GPU value
    finite. `groups` (one label per point, e.g. the sharpness) splits the grid into slices with
    their own maximum, for outputs that span many orders of magnitude by construction; None = one
    grid. For (n, k) outputs (vectors) the value is the Euclidean norm of a row and the error the
    norm of the difference.

    The absolute bound is in units of M when M > 1: the criterion is applied to the output divided
    by its slice maximum. For outputs of at most 1 it is the 1e-7 as is; in absolute units
    it could not hold for large slices (below 1e-6 of M = 1e10 lie values like 7e3, whose float32
    spacing is 5e-4).
    """

    def __init__(self, gpu, reference, groups=None, *, relative=RELATIVE_TOLERANCE,
                 absolute=ABSOLUTE_TOLERANCE, significant=SIGNIFICANT_FRACTION):
        gpu = np.asarray(gpu, dtype=np.float64)
        reference = np.asarray(reference, dtype=np.float64)
        if gpu.shape != reference.shape:
            raise ValueError(f"GPU result {gpu.shape} and reference {reference.shape} differ in shape")
        if not np.all(np.isfinite(reference)):
            raise ValueError("the reference has non-finite values: fix the grid or the reference")
        vector = gpu.ndim == 2
        self.nonfinite = ~np.all(np.isfinite(gpu), axis=-1) if vector else ~np.isfinite(gpu)
        magnitude = np.linalg.norm(reference, axis=-1) if vector else np.abs(reference)
        with np.errstate(invalid="ignore"):
            error = np.linalg.norm(gpu - reference, axis=-1) if vector else np.abs(gpu - reference)
        error = np.where(self.nonfinite, np.inf, error)
        if groups is None:
            largest = np.full(magnitude.shape, magnitude.max(initial=0.0))
        else:
            labels, inverse = np.unique(np.asarray(groups), axis=0, return_inverse=True)
            inverse = inverse.reshape(-1)
            group_max = np.zeros(len(labels))
            np.maximum.at(group_max, inverse, magnitude)
            largest = group_max[inverse]
        self.significant = magnitude > significant * largest
        self.relative_error = np.where(self.significant, error / np.where(self.significant, magnitude, 1.0), 0.0)
        # In units of the slice maximum when that exceeds 1 (see the class documentation).
        self.absolute_error = np.where(self.significant, 0.0, error / np.maximum(largest, 1.0))
        self.failed = (self.nonfinite | (self.relative_error > relative) | (self.absolute_error > absolute))
        self.gpu, self.reference, self.magnitude = gpu, reference, magnitude
        self.count = len(magnitude)

    @property
    def ok(self) -> bool:
        return not self.failed.any()

    @property
    def worst_relative(self) -> float:
        return float(self.relative_error.max(initial=0.0))

    @property
    def worst_absolute(self) -> float:
        return float(self.absolute_error.max(initial=0.0))

    def summary(self) -> str:
        return (f"{self.count} points ({int(self.significant.sum())} by relative error): worst relative "
                f"{self.worst_relative:.3g}, worst absolute {self.worst_absolute:.3g}, "
                f"{int(self.nonfinite.sum())} non-finite, {int(self.failed.sum())} failed")

    def report(self, inputs: Mapping[str, np.ndarray] | None = None, limit: int = 8) -> str:
        """The summary and the worst failing points with their inputs."""
        lines = [self.summary()]
        score = np.maximum(self.relative_error / RELATIVE_TOLERANCE, self.absolute_error / ABSOLUTE_TOLERANCE)
        score = np.where(self.nonfinite, np.inf, score)
        for index in np.argsort(-score)[:limit]:
            if not self.failed[index]:
                break
            where = ", ".join(f"{name}={np.asarray(values)[index]!r}" for name, values in (inputs or {}).items())
            lines.append(f"  [{index}] gpu={self.gpu[index]!r} reference={self.reference[index]!r} "
                         f"rel={self.relative_error[index]:.3g} abs={self.absolute_error[index]:.3g}  {where}")
        return "\n".join(lines)
