"""GLSL sources from `glsl/`, composed into Blender `GPUShaderCreateInfo`s.

Sources carry no declarations (the create-info does, Blender's rule). A source names the shared
libraries it needs with `// @require lib/NAME.glsl` lines; they are included once each, in
dependency order, before it.

Blender reports a compile failure as a bare "Shader Compile Error, see console" and writes the
GLSL compiler's messages to the console with line numbers of its own composite source. We tag every
included file with a `#line` directive whose number encodes the file (file k starts at line
k * LINE_STRIDE), capture the console output of the compile, and turn each message back into
`glsl/<file>:<line>:<column>: error: <compiler's message>` in the exception we raise.

Sources are looked up in one root (`glsl/` by default) or in a list of roots, first hit wins, so a
stage file kept elsewhere (the tests' GLSL harness) can `@require` the shipped `glsl/lib` files.
Messages name a file by its path relative to the repository (`glsl/lib/sg.glsl`), or absolute when
it lies outside.
"""

from __future__ import annotations

import ctypes
import os
import re
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence, Union

GLSL_ROOT = Path(__file__).resolve().parent.parent / "glsl"
_REPOSITORY = GLSL_ROOT.parent
# One folder or several, searched in order.
Roots = Union[str, os.PathLike, Sequence[Union[str, os.PathLike]]]
LINE_STRIDE = 100_000

_REQUIRE = re.compile(r"^\s*//\s*@require\s+(\S+)\s*$", re.MULTILINE)
# Blender 5.x reformats the driver's messages as "name:LINE:COL: Error: text"; Mesa's own form is
# "0:LINE(COL): error: text". Both are accepted.
_MESSAGE = re.compile(
    r"(?P<line>\d+)(?::(?P<col>\d+)|\((?P<pcol>\d+)\)):\s*(?:(?P<kind>error|warning)\s*:\s*)?(?P<text>.*\S)",
    re.IGNORECASE,
)


class ShaderCompileError(RuntimeError):
    """A GLSL compile or link failure, with the compiler's messages mapped to our source files."""

    def __init__(self, shader_name: str, messages: list[str], raw_log: str):
        self.shader_name = shader_name
        self.messages = messages
        self.raw_log = raw_log
        detail = "\n".join(messages) if messages else raw_log.strip() or "(the compiler printed nothing)"
        super().__init__(f"GLSL shader '{shader_name}' failed to compile:\n{detail}")


class ShaderSourceError(FileNotFoundError):
    """A stage source or an `@require`d library is missing from glsl/."""


@dataclass
class ComposedSource:
    """One stage's source with every library it requires, and the files in the order of their tags."""

    text: str
    files: list[str]  # as messages name them: relative to the repository, or absolute
    first_tag: int = 1  # files[0] is tagged first_tag * LINE_STRIDE; stages of a shader do not overlap

    def locate(self, tagged_line: int) -> tuple[str, int] | None:
        index, line = divmod(tagged_line, LINE_STRIDE)
        if 0 <= index - self.first_tag < len(self.files):
            return self.files[index - self.first_tag], line
        return None


def _roots(root: Roots) -> tuple[Path, ...]:
    if isinstance(root, (str, os.PathLike)):
        return (Path(root),)
    return tuple(Path(folder) for folder in root)


def _find(relative: str, roots: tuple[Path, ...]) -> Path:
    for folder in roots:
        path = folder / relative
        if path.is_file():
            return path
    where = ", ".join(str(folder) for folder in roots)
    raise ShaderSourceError(f"GLSL source '{relative}' not found in {where}")


def _display_name(path: Path) -> str:
    try:
        return path.resolve().relative_to(_REPOSITORY).as_posix()
    except ValueError:
        return str(path)


def _dependency_order(stage: str, roots: tuple[Path, ...]) -> list[tuple[str, Path]]:
    order: list[tuple[str, Path]] = []
    done: set[str] = set()
    visiting: list[str] = []

    def visit(relative: str) -> None:
        if relative in done:
            return
        if relative in visiting:
            cycle = " -> ".join(visiting + [relative])
            raise ShaderSourceError(f"GLSL @require cycle: {cycle}")
        path = _find(relative, roots)
        visiting.append(relative)
        for required in _REQUIRE.findall(path.read_text(encoding="utf-8")):
            visit(required)
        visiting.pop()
        done.add(relative)
        order.append((relative, path))

    visit(stage)
    return order


def _ism_defines() -> dict[str, object]:
    from .reference import ism

    return {"ISM_ORIGIN_SIGMAS": repr(float(ism.SHADOW_ORIGIN_SIGMAS)),
            "ISM_NORMAL_OFFSET": repr(float(ism.NORMAL_OFFSET)),
            "ISM_NORMAL_OFFSET_DEPTH": repr(float(ism.NORMAL_OFFSET_DEPTH)),
            "ISM_BACK_OFFSET": repr(float(ism.BACK_OFFSET)),
            "ISM_SPREAD": repr(float(ism.SPREAD_BIAS)),
            "ISM_SURFACE_OFFSET": repr(float(ism.SURFACE_NORMAL_OFFSET)),
            "ISM_SURFACE_OFFSET_DEPTH": repr(float(ism.SURFACE_NORMAL_OFFSET_DEPTH))}


#: Defines a library takes from its float64 twin, added to every shader that requires it (read at
#: compile time, so each of its users compiles with the twin's current value; a shader's own
#: defines win).
LIBRARY_DEFINES = {"lib/ism.glsl": _ism_defines}

#: How messages name the generated code of ``compose(..., code=...)``.
GENERATED_CODE = "<generated layout code>"


def compose(stage: str, root: Roots = GLSL_ROOT, defines: dict[str, object] | None = None,
            first_tag: int = 1, code: str = "") -> ComposedSource:
    """The stage source `stage` (relative to a root) preceded by its libraries, each `#line`-tagged.

    `defines` (after those of the libraries it requires, LIBRARY_DEFINES) become `#define NAME
    VALUE` lines at the top; `code` (GLSL generated from a layout
    declaration, :mod:`vsgl_addon.layouts`) follows them, tagged like a file, before the libraries.
    Files are tagged first_tag, first_tag + 1, ...: the stages of one shader take disjoint ranges,
    or a message could not tell a vertex file from a fragment file.
    """
    order = _dependency_order(stage, _roots(root))
    files = [(GENERATED_CODE, code)] if code.strip() else []
    files += [(_display_name(path), path) for _, path in order]
    defines = {**{name: value for relative, _ in order if relative in LIBRARY_DEFINES
                  for name, value in LIBRARY_DEFINES[relative]().items()}, **(defines or {})}
    parts = [f"#define {name} {value}" for name, value in defines.items()]
    for index, (_, source) in enumerate(files, start=first_tag):
        # `#line N` numbers the next line N (GLSL 3.30+), so a file's first line is tagged index*STRIDE + 1.
        parts.append(f"#line {index * LINE_STRIDE + 1}")
        text = source if isinstance(source, str) else source.read_text(encoding="utf-8")
        parts.append(text.rstrip("\n"))
    return ComposedSource("\n".join(parts) + "\n", [name for name, _ in files], first_tag)


def map_messages(log: str, sources: list[ComposedSource]) -> list[str]:
    """Compiler messages of `log` as `<file>:<line>:<col>: <kind>: <text>` (unique, in order)."""
    messages: list[str] = []
    for match in _MESSAGE.finditer(log):
        tagged = int(match["line"])
        column = match["col"] or match["pcol"]
        where = None
        for source in sources:
            where = source.locate(tagged)
            if where is not None:
                break
        if match["kind"] is None and where is None:
            # Only the compiler's messages name a kind; an untagged line (Blender 5.2's own GLSL
            # preprocessor reports that way) counts when its line number is one of our tags.
            continue
        place = f"{where[0]}:{where[1]}" if where else f"<Blender's generated code>:{tagged}"
        kind = (match["kind"] or "error").lower()
        message = f"{place}:{column}: {kind}: {match['text']}"
        if message not in messages:
            messages.append(message)
    return messages


class _CapturedConsole:
    """Redirects the process's stdout and stderr (file descriptors 1 and 2) into a temporary file.

    Blender's logger writes with C stdio, so C's buffers are flushed before the descriptors return.
    """

    def __enter__(self):
        sys.stdout.flush()
        sys.stderr.flush()
        self._file = tempfile.TemporaryFile()
        self._saved = [os.dup(1), os.dup(2)]
        os.dup2(self._file.fileno(), 1)
        os.dup2(self._file.fileno(), 2)
        return self

    def __exit__(self, *exc):
        try:
            ctypes.CDLL(None).fflush(None)
        except (OSError, AttributeError):
            pass
        sys.stdout.flush()
        sys.stderr.flush()
        for fd, saved in zip((1, 2), self._saved):
            os.dup2(saved, fd)
            os.close(saved)
        self._file.seek(0)
        self.text = self._file.read().decode("utf-8", "replace")
        self._file.close()
        return False


@dataclass
class ShaderInterface:
    """Declarations of one shader (Blender create-info terms); names come from the GLSL sources."""

    push_constants: list[tuple[str, str]] = field(default_factory=list)  # (type, name)
    samplers: list[tuple[str, str]] = field(default_factory=list)  # (type, name); slots in order
    images: list[tuple[str, str, str]] = field(default_factory=list)  # (format, type, name)
    vertex_inputs: list[tuple[str, str]] = field(default_factory=list)  # (type, name)
    varyings: list[tuple[str, str]] = field(default_factory=list)  # (type, name), smooth
    flat_varyings: list[tuple[str, str]] = field(default_factory=list)
    fragment_outputs: list[tuple[str, str]] = field(default_factory=list)  # (type, name)
    local_group_size: tuple[int, ...] | None = None
    # Compute-shader `shared` declarations: Blender 5.2 drops a `shared` written in compute_source,
    # typedef_source keeps it on 5.0 and 5.2 (blender-gpu.md).
    shared: str = ""


def create_shader(name: str, interface: ShaderInterface, *, vertex: str | None = None,
                  fragment: str | None = None, compute: str | None = None,
                  defines: dict[str, object] | None = None, root: Roots = GLSL_ROOT,
                  code: dict[str, str] | None = None):
    """Compile a shader from stage files under `root` (glsl/ by default; a folder or a list of
    folders searched in order), each stage preceded by `defines` and its generated `code`
    (stage name "vertex" / "fragment" / "compute" -> GLSL, see compose); raise ShaderCompileError
    with mapped messages."""
    import gpu

    info = gpu.types.GPUShaderCreateInfo()
    for glsl_type, constant in interface.push_constants:
        info.push_constant(glsl_type, constant)
    for slot, (glsl_type, sampler) in enumerate(interface.samplers):
        info.sampler(slot, glsl_type, sampler)
    for slot, (image_format, glsl_type, image) in enumerate(interface.images):
        info.image(slot, image_format, glsl_type, image, qualifiers={"READ", "WRITE"})
    for slot, (glsl_type, attribute) in enumerate(interface.vertex_inputs):
        info.vertex_in(slot, glsl_type, attribute)
    stage_interface = None
    if interface.varyings or interface.flat_varyings:
        # The interface name becomes a GLSL identifier in Blender's generated code.
        stage_interface = gpu.types.GPUStageInterfaceInfo(re.sub(r"\W", "_", f"{name}_interface"))
        for glsl_type, varying in interface.varyings:
            stage_interface.smooth(glsl_type, varying)
        for glsl_type, varying in interface.flat_varyings:
            stage_interface.flat(glsl_type, varying)
        info.vertex_out(stage_interface)
    for slot, (glsl_type, output) in enumerate(interface.fragment_outputs):
        info.fragment_out(slot, glsl_type, output)
    if interface.local_group_size:
        info.local_group_size(*interface.local_group_size)
    if interface.shared:
        info.typedef_source(interface.shared)

    sources = []
    code = code or {}
    for kind, stage, setter in (("vertex", vertex, info.vertex_source), ("fragment", fragment, info.fragment_source),
                                ("compute", compute, info.compute_source)):
        if stage is not None:
            first_tag = sum(len(source.files) for source in sources) + 1
            composed = compose(stage, root, defines, first_tag, code.get(kind, ""))
            setter(composed.text)
            sources.append(composed)

    with _CapturedConsole() as console:
        try:
            shader = gpu.shader.create_from_info(info)
            failed = None
        except Exception as error:  # Blender raises a bare Exception for compile errors.
            shader, failed = None, error
    if failed is not None:
        raise ShaderCompileError(name, map_messages(console.text, sources), console.text) from failed
    if console.text.strip():
        sys.stderr.write(console.text)
    return shader
