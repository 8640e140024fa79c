# SPDX-License-Identifier: GPL-3.0-or-later
"""The extension as Blender 5.2 sees it: validate the manifest, build the zip, install and toggle it.

Runs the Blender application through ../shared/tools/real-blender (see helpers_blender.py).
"""

from __future__ import annotations

import textwrap
import zipfile
from pathlib import Path

import pytest

from helpers_blender import REPO, describe, run_blender, scratch_dir

pytestmark = pytest.mark.real_blender

MODULE = "bl_ext.user_default.vsgl"  # what Blender calls the add-on once installed into "user_default"
SUCCESS = "VSGL-EXTENSION-CHECK-OK"

# What the built zip must hold (top-level names) and what must never be in it.
REQUIRED = {"__init__.py", "blender_manifest.toml", "LICENSE", "vsgl_addon/__init__.py", "vsgl_addon/properties.py"}
REQUIRED_DIRS = ("vsgl_addon/", "glsl/")
FORBIDDEN_TOP = {"tests", "tools", "benchmarks", "docs", ".ci", ".venv", ".git", ".gitignore", ".pytest_cache",
                 "pyproject.toml", "requirements-dev.txt", "build", "out"}


@pytest.fixture(scope="module")
def built_zip():
    """``blender --command extension build`` of the source tree, once for this module."""
    with scratch_dir("vsgl-build-") as out:
        proc = run_blender("--command", "extension", "build", "--source-dir", str(REPO), "--output-dir", str(out))
        assert proc.returncode == 0, describe(proc)
        zips = sorted(out.glob("*.zip"))
        assert [z.name for z in zips] == ["vsgl-0.1.0.zip"], describe(proc)
        yield zips[0]


def test_validate_source_tree():
    proc = run_blender("--command", "extension", "validate", str(REPO))
    assert proc.returncode == 0, describe(proc)
    assert "Success parsing TOML" in proc.stdout, describe(proc)


def test_build_zip_contents(built_zip: Path):
    with zipfile.ZipFile(built_zip) as zf:
        names = zf.namelist()
    missing = REQUIRED - set(names)
    assert not missing, f"missing from {built_zip.name}: {sorted(missing)}; has {names}"
    for prefix in REQUIRED_DIRS:
        assert any(n.startswith(prefix) for n in names), f"nothing under {prefix} in {names}"
    # Every GLSL source of the tree ships (the add-on loads them at run time from <root>/glsl).
    glsl_sources = {p.relative_to(REPO).as_posix() for p in (REPO / "glsl").rglob("*") if p.is_file()}
    assert glsl_sources <= set(names), sorted(glsl_sources - set(names))
    leaked = sorted(n for n in names if n.split("/")[0] in FORBIDDEN_TOP)
    assert not leaked, leaked
    caches = sorted(n for n in names if "__pycache__" in n.split("/") or n.endswith((".pyc", ".pyo")))
    assert not caches, caches
    assert not any(n.endswith(".zip") for n in names), names
    # The archive itself passes validation too.
    proc = run_blender("--command", "extension", "validate", str(built_zip))
    assert proc.returncode == 0, describe(proc)


# Runs inside Blender, started normally (not --factory-startup, which ignores the user
# preferences and so the enabled extension). Any failed check raises -> exit code 1.
CHECK_SCRIPT = textwrap.dedent(
    """
    import sys
    import bpy

    MODULE = {module!r}
    addons = bpy.context.preferences.addons

    def handler_names():
        # Every function in every bpy.app.handlers list, by module and name.
        return sorted(
            (name, getattr(f, "__module__", "?"), getattr(f, "__qualname__", repr(f)))
            for name in dir(bpy.app.handlers) if not name.startswith("_")
            and isinstance(getattr(bpy.app.handlers, name), list)
            for f in getattr(bpy.app.handlers, name)
        )

    def check(cond, what):
        if not cond:
            raise AssertionError(what)

    # Installed with --enable: enabled at start-up, through relative imports only.
    check(MODULE in addons.keys(), f"{{MODULE}} not enabled at start-up: {{list(addons.keys())}}")
    check("vsgl_addon" not in sys.modules, "top-level vsgl_addon imported: an absolute import slipped in")
    package = sys.modules[MODULE + ".vsgl_addon"]
    registry = package._registry()
    check(registry.classes, "no classes in the registry")

    def check_enabled(step):
        check(MODULE in addons.keys(), f"{{step}}: not in preferences.addons")
        check("vsgl" in bpy.types.Scene.bl_rna.properties.keys(), f"{{step}}: no Scene.vsgl")
        for cls in registry.classes:
            check(cls.is_registered, f"{{step}}: {{cls.__name__}} not registered")
        pointer = bpy.types.Scene.bl_rna.properties["vsgl"]
        check(pointer.fixed_type.identifier == "VSGLSceneSettings", f"{{step}}: Scene.vsgl is {{pointer.fixed_type}}")
        for fn, _opts in registry.timers:
            check(bpy.app.timers.is_registered(fn), f"{{step}}: timer {{fn}} not registered")
        check(handler_names() == handlers_enabled, f"{{step}}: handlers {{handler_names()}} != {{handlers_enabled}}")
        settings = bpy.data.scenes.new("vsgl-check").vsgl
        values = (settings.vsgl_count, settings.k, settings.kernel, settings.rsm_size, settings.seed)
        check(values == (256, 1.0, "MODIFIED", 128, 0), f"{{step}}: defaults {{values}}")
        bpy.data.scenes.remove(bpy.data.scenes["vsgl-check"])

    def check_disabled(step):
        check(MODULE not in addons.keys(), f"{{step}}: still in preferences.addons")
        check("vsgl" not in bpy.types.Scene.bl_rna.properties.keys(), f"{{step}}: Scene.vsgl left behind")
        check(not hasattr(bpy.types.Scene, "vsgl"), f"{{step}}: Scene.vsgl attribute left behind")
        for cls in registry.classes:
            check(not cls.is_registered, f"{{step}}: {{cls.__name__}} still registered")
        for fn, _opts in registry.timers:
            check(not bpy.app.timers.is_registered(fn), f"{{step}}: timer {{fn}} left behind")
        ours = [h for h in handler_names() if h[1].startswith(MODULE)]
        check(not ours, f"{{step}}: handlers left behind: {{ours}}")
        check(handler_names() == handlers_disabled, f"{{step}}: handlers {{handler_names()}} != {{handlers_disabled}}")

    handlers_enabled = handler_names()
    handlers_disabled = [h for h in handlers_enabled if not h[1].startswith(MODULE)]
    check_enabled("start-up")
    for round_ in (1, 2):
        result = bpy.ops.preferences.addon_disable(module=MODULE)
        check(result == {{"FINISHED"}}, f"addon_disable returned {{result}}")
        check_disabled(f"disable #{{round_}}")
        result = bpy.ops.preferences.addon_enable(module=MODULE)
        check(result == {{"FINISHED"}}, f"addon_enable returned {{result}}")
        check_enabled(f"enable #{{round_}}")
    print({success!r})
    """
)


def test_install_enable_disable(built_zip: Path):
    with scratch_dir("vsgl-user-") as user, scratch_dir("vsgl-script-") as scripts:
        env = {"BLENDER_USER_RESOURCES": str(user)}
        proc = run_blender("--command", "extension", "install-file", "-r", "user_default", "-e", str(built_zip),
                           blender_env=env)
        assert proc.returncode == 0, describe(proc)
        assert (user / "extensions" / "user_default" / "vsgl" / "blender_manifest.toml").is_file(), describe(proc)
        assert (user / "extensions" / "user_default" / "vsgl" / "glsl").is_dir(), describe(proc)

        script = scripts / "check_vsgl.py"
        script.write_text(CHECK_SCRIPT.format(module=MODULE, success=SUCCESS))
        proc = run_blender("-b", "--python-exit-code", "1", "--python", str(script), blender_env=env)
        assert proc.returncode == 0, describe(proc)
        assert SUCCESS in proc.stdout, describe(proc)
        # Blender reports an add-on that fails to load or register on stderr and carries on.
        assert "Traceback" not in proc.stdout + proc.stderr, describe(proc)
