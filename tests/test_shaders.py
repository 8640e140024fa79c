"""vsgl_addon.shaders: composing glsl/ sources with `// @require` and mapping compile errors back."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from vsgl_addon.shaders import (GENERATED_CODE, GLSL_ROOT, LINE_STRIDE, ShaderCompileError, ShaderInterface,
                                ShaderSourceError, compose, create_shader, map_messages)

REPO = Path(__file__).resolve().parents[1]


def _write(root: Path, files: dict[str, str]) -> Path:
    for relative, text in files.items():
        path = root / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root


def _bodies(text: str) -> list[str]:
    """The source lines that are neither `#line` tags nor `@require` comments."""
    return [line for line in text.splitlines()
            if line and not line.startswith("#line") and "@require" not in line]


def test_requires_come_first_in_dependency_order_each_once(tmp_path):
    root = _write(tmp_path, {
        "lib/a.glsl": "float a() { return 1.0; }\n",
        "lib/b.glsl": "// @require lib/a.glsl\nfloat b() { return a(); }\n",
        "lib/c.glsl": "// @require lib/a.glsl\n// @require lib/b.glsl\nfloat c() { return a() + b(); }\n",
        "stage.glsl": "// @require lib/c.glsl\n// @require lib/b.glsl\n  //   @require   lib/a.glsl  \nvoid main() {}\n",
    })
    composed = compose("stage.glsl", root)
    assert _bodies(composed.text) == ["float a() { return 1.0; }", "float b() { return a(); }",
                                      "float c() { return a() + b(); }", "void main() {}"]
    assert [Path(name).name for name in composed.files] == ["a.glsl", "b.glsl", "c.glsl", "stage.glsl"]
    # Each file is tagged so that a compiler line number names the file and the line in it.
    tags = [int(n) for n in re.findall(r"^#line (\d+)$", composed.text, re.MULTILINE)]
    assert tags == [k * LINE_STRIDE + 1 for k in range(1, 5)]
    assert composed.locate(3 * LINE_STRIDE + 1)[1] == 1
    assert Path(composed.locate(4 * LINE_STRIDE + 4)[0]).name == "stage.glsl"
    assert composed.locate(7 * LINE_STRIDE + 1) is None


def test_defines_precede_every_source(tmp_path):
    root = _write(tmp_path, {"stage.glsl": "void main() {}\n"})
    text = compose("stage.glsl", root, defines={"COUNT": 4, "SCALE": "2.0"}).text
    assert text.splitlines()[:2] == ["#define COUNT 4", "#define SCALE 2.0"]


def test_generated_code_follows_the_defines_and_precedes_the_libraries_tagged_as_a_file(tmp_path):
    root = _write(tmp_path, {"lib/a.glsl": "float a() { return 1.0; }\n",
                             "stage.glsl": "// @require lib/a.glsl\nvoid main() {}\n"})
    composed = compose("stage.glsl", root, defines={"N": 3}, code="float generated() { return N; }\n")
    assert composed.files[0] == GENERATED_CODE and len(composed.files) == 3
    text = composed.text
    assert text.index("#define N 3") < text.index("float generated()") < text.index("float a()")
    assert composed.locate(LINE_STRIDE + 1) == (GENERATED_CODE, 1)
    assert compose("stage.glsl", root, code="  \n").files == compose("stage.glsl", root).files


def test_a_require_cycle_is_reported_with_its_path(tmp_path):
    root = _write(tmp_path, {
        "lib/a.glsl": "// @require lib/b.glsl\n",
        "lib/b.glsl": "// @require lib/a.glsl\n",
        "stage.glsl": "// @require lib/a.glsl\nvoid main() {}\n",
    })
    with pytest.raises(ShaderSourceError, match=r"cycle: stage\.glsl -> lib/a\.glsl -> lib/b\.glsl -> lib/a\.glsl"):
        compose("stage.glsl", root)


def test_a_missing_file_is_named_with_where_it_was_looked_for(tmp_path):
    root = _write(tmp_path, {"stage.glsl": "// @require lib/nowhere.glsl\nvoid main() {}\n"})
    with pytest.raises(ShaderSourceError) as caught:
        compose("stage.glsl", root)
    assert "lib/nowhere.glsl" in str(caught.value) and str(tmp_path) in str(caught.value)
    with pytest.raises(FileNotFoundError):  # ShaderSourceError is one
        compose("no_stage.glsl", root)


def test_several_roots_first_hit_wins_and_names_are_repository_relative(tmp_path):
    """A stage kept outside glsl/ (the tests' harness) can require the shipped libraries."""
    root = _write(tmp_path, {"probe.frag.glsl": "// @require lib/math.glsl\nvoid main() {}\n",
                             "lib/extra.glsl": "float extra() { return 2.0; }\n"})
    composed = compose("probe.frag.glsl", [root, GLSL_ROOT])
    assert composed.files == ["glsl/lib/math.glsl", str(root / "probe.frag.glsl")]
    assert "float expm1(float x)" in composed.text
    # The earlier root shadows a later one.
    _write(tmp_path, {"lib/math.glsl": "float shadowed() { return 0.0; }\n"})
    assert "shadowed" in compose("probe.frag.glsl", [root, GLSL_ROOT]).text


def test_messages_of_both_log_formats_are_mapped_to_files_and_lines(tmp_path):
    root = _write(tmp_path, {"lib/a.glsl": "float a() { return 1.0; }\n",
                             "stage.glsl": "// @require lib/a.glsl\nvoid main() {}\n"})
    composed = compose("stage.glsl", root)
    log = (f"0:{LINE_STRIDE + 1}(12): error: first problem\n"
           f"GPU_shader:{2 * LINE_STRIDE + 2}:3: Error: second problem\n"
           f"0:{2 * LINE_STRIDE + 2}(3): warning: a warning\n"
           "0:17(1): error: in Blender's own code\n")
    messages = map_messages(log, [composed])
    assert messages == [f"{root / 'lib/a.glsl'}:1:12: error: first problem",
                        f"{root / 'stage.glsl'}:2:3: error: second problem",
                        f"{root / 'stage.glsl'}:2:3: warning: a warning",
                        "<Blender's generated code>:17:1: error: in Blender's own code"]


# --- Compiling through Blender's gpu module ---------------------------------------------------

_INTERFACE = ShaderInterface(vertex_inputs=[("VEC2", "position")], varyings=[("VEC2", "uv")],
                             fragment_outputs=[("VEC4", "color")])


@pytest.mark.gpu
@pytest.mark.parametrize("library", ["math.glsl", "sg.glsl", "asg.glsl", "ggx.glsl"])
def test_the_shared_math_libraries_compile_on_their_own(tmp_path, library):
    """Each pulls in what it needs by @require (in a fragment stage; they are stage-agnostic)."""
    root = _write(tmp_path, {"stage.frag.glsl": f"// @require lib/{library}\n"
                                                "void main() { color = vec4(uv, 0.0, 1.0); }\n"})
    assert create_shader(f"library_{library.split('.')[0]}", _INTERFACE, vertex="fullscreen_triangle.vert.glsl",
                         fragment="stage.frag.glsl", root=[root, GLSL_ROOT]) is not None


@pytest.mark.gpu
def test_a_compile_error_names_the_file_and_line_and_carries_the_compiler_text(tmp_path):
    root = _write(tmp_path, {
        "lib/helper.glsl": "float helper(float x)\n{\n  return x * 2.0;\n}\n",
        "broken.frag.glsl": ("// @require lib/helper.glsl\n"
                             "void main()\n"
                             "{\n"
                             "  float value = helper(uv.x) + undeclared_variable;\n"
                             "  color = vec4(value);\n"
                             "}\n"),
    })
    with pytest.raises(ShaderCompileError) as caught:
        create_shader("broken", _INTERFACE, vertex="fullscreen_triangle.vert.glsl",
                      fragment="broken.frag.glsl", root=[root, GLSL_ROOT])
    error = caught.value
    where = f"{root / 'broken.frag.glsl'}:4:"
    assert any(message.startswith(where) and "undeclared_variable" in message for message in error.messages), \
        error.messages
    assert where in str(error) and "broken" in str(error)
    assert "undeclared_variable" in error.raw_log  # the compiler's own text is kept
    # The vertex stage (a file of glsl/) is not blamed for the fragment stage's line.
    assert not any("fullscreen_triangle" in message for message in error.messages)


@pytest.mark.gpu
def test_an_error_in_generated_code_is_named_as_such(tmp_path):
    root = _write(tmp_path, {"ok.frag.glsl": "void main()\n{\n  color = vec4(generated());\n}\n"})
    code = {"fragment": "float generated()\n{\n  return undeclared_in_generated;\n}\n"}
    with pytest.raises(ShaderCompileError) as caught:
        create_shader("generated", _INTERFACE, vertex="fullscreen_triangle.vert.glsl", fragment="ok.frag.glsl",
                      root=[root, GLSL_ROOT], code=code)
    assert any(message.startswith(f"{GENERATED_CODE}:3:") for message in caught.value.messages), \
        caught.value.messages
    code["fragment"] = "float generated()\n{\n  return 0.5;\n}\n"
    assert create_shader("generated_ok", _INTERFACE, vertex="fullscreen_triangle.vert.glsl",
                         fragment="ok.frag.glsl", root=[root, GLSL_ROOT], code=code) is not None


@pytest.mark.gpu
def test_an_error_in_a_library_names_the_library(tmp_path):
    root = _write(tmp_path, {
        "lib/bad.glsl": "float bad()\n{\n  return 1.0 +;\n}\n",
        "stage.frag.glsl": "// @require lib/bad.glsl\nvoid main() { color = vec4(bad()); }\n",
    })
    with pytest.raises(ShaderCompileError) as caught:
        create_shader("bad_library", _INTERFACE, vertex="fullscreen_triangle.vert.glsl",
                      fragment="stage.frag.glsl", root=[root, GLSL_ROOT])
    assert any(message.startswith(f"{root / 'lib/bad.glsl'}:3:") for message in caught.value.messages), \
        caught.value.messages


@pytest.mark.gpu
def test_an_error_in_a_shipped_file_is_named_relative_to_the_repository(tmp_path):
    """A define that breaks a line of glsl/lib/math.glsl: the message says glsl/lib/math.glsl:LINE."""
    root = _write(tmp_path, {"stage.frag.glsl": "// @require lib/math.glsl\nvoid main() { color = vec4(uv, 0.0, 1.0); }\n"})
    lines = (GLSL_ROOT / "lib/math.glsl").read_text(encoding="utf-8").splitlines()
    line = next(number for number, text in enumerate(lines, start=1) if text.startswith("const float FOUR_PI"))
    with pytest.raises(ShaderCompileError) as caught:
        create_shader("broken_define", _INTERFACE, vertex="fullscreen_triangle.vert.glsl",
                      fragment="stage.frag.glsl", defines={"FOUR_PI": "+"}, root=[root, GLSL_ROOT])
    assert any(message.startswith(f"glsl/lib/math.glsl:{line}:") for message in caught.value.messages), \
        caught.value.messages


@pytest.mark.gpu
def test_a_shader_name_need_not_be_an_identifier(tmp_path):
    """The name also names the stage interface, which Blender writes into GLSL."""
    root = _write(tmp_path, {"stage.frag.glsl": "void main() { color = vec4(uv, 0.0, 1.0); }\n"})
    assert create_shader("a name with spaces & symbols", _INTERFACE, vertex="fullscreen_triangle.vert.glsl",
                         fragment="stage.frag.glsl", root=[root, GLSL_ROOT]) is not None


def test_glsl_sources_have_no_block_comments():
    """Blender 5.2 preprocesses Python shader sources and reads `/*` even inside a `//` comment as
    the start of a block comment ("Malformed multi-line comment"); 5.0 does not, so only the real
    application would notice. Comments are `//` only, and never contain `/*` or `*/`."""
    offenders = [f"{path.relative_to(REPO)}:{number}"
                 for path in sorted((REPO / "glsl").rglob("*.glsl"))
                 for number, line in enumerate(path.read_text().splitlines(), start=1)
                 if "/*" in line or "*/" in line]
    assert not offenders, offenders


@pytest.mark.gpu
def test_every_pass_shader_compiles_in_the_bpy_module():
    from vsgl_addon.passes import compile_all_shaders

    compile_all_shaders()


def test_blender_5_2_preprocessor_messages_are_mapped_too():
    """5.2's GLSL preprocessor reports without a kind ("name:LINE:COL: text"); when LINE is one of our
    tags it is ours, when not (Blender's own libraries) it is left out."""
    source = compose("rsm/rsm.frag.glsl", first_tag=2)
    third = source.files[2]
    log = (f"python_shader.glsl:{4 * LINE_STRIDE + 3}:80: Malformed multi-line comment.\n"
           "  |  draw_colormanagement_lib.glsl:45:2: preprocessor error: #error conversion failled\n")
    assert map_messages(log, [source]) == [f"{third}:3:80: error: Malformed multi-line comment."]
