# SPDX-License-Identifier: GPL-3.0-or-later
"""Registering and unregistering the add-on in the bpy module (Blender as a Python module).

The add-on is loaded the way Blender loads an extension: the repository root imported as a
package (here named ENTRY, in Blender ``bl_ext.<repo>.vsgl``) whose ``__init__.py`` re-exports
register/unregister from ``.vsgl_addon``. All tests of one pytest process share one Blender, so
a fixture unregisters after every test and checks nothing is left.
"""

from __future__ import annotations

import ast
import importlib.util
import subprocess
import sys
import textwrap
from pathlib import Path

import bpy
import pytest

REPO = Path(__file__).resolve().parents[1]
ENTRY = "vsgl_extension_under_test"
PACKAGED_PY = [REPO / "__init__.py", *sorted((REPO / "vsgl_addon").rglob("*.py"))]


@pytest.fixture(scope="module")
def entry():
    """The repository root imported as a package, like Blender imports the installed extension."""
    spec = importlib.util.spec_from_file_location(ENTRY, REPO / "__init__.py", submodule_search_locations=[str(REPO)])
    module = importlib.util.module_from_spec(spec)
    sys.modules[ENTRY] = module
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        for name in [n for n in sys.modules if n == ENTRY or n.startswith(ENTRY + ".")]:
            del sys.modules[name]


@pytest.fixture
def registry(entry):
    return sys.modules[ENTRY + ".vsgl_addon"]._registry()


def handler_lists():
    return {
        name: list(getattr(bpy.app.handlers, name))
        for name in dir(bpy.app.handlers)
        if not name.startswith("_") and isinstance(getattr(bpy.app.handlers, name), list)
    }


def blender_state(registry):
    """What register()/unregister() may change, in a form that compares with ==."""
    return {
        "scene properties": sorted(bpy.types.Scene.bl_rna.properties.keys()),
        "Scene.vsgl attribute": hasattr(bpy.types.Scene, "vsgl"),
        "registered classes": {cls.__name__: cls.is_registered for cls in registry.classes},
        "bpy.types": sorted(dir(bpy.types)),
        "handlers": handler_lists(),
        "timers": {fn.__qualname__: bpy.app.timers.is_registered(fn) for fn, _ in registry.timers},
    }


@pytest.fixture
def baseline(entry, registry):
    """Blender's state without the add-on; after the test the add-on is unregistered and the state is back."""
    entry.unregister()  # in case an earlier test (or test file) left it registered
    before = blender_state(registry)
    assert "vsgl" not in before["scene properties"]
    yield before
    entry.unregister()
    assert blender_state(registry) == before


def expected_registered(before, registry):
    after = dict(before)
    after["scene properties"] = sorted([*before["scene properties"], "vsgl"])
    after["Scene.vsgl attribute"] = True
    after["registered classes"] = {cls.__name__: True for cls in registry.classes}
    handlers = {name: list(functions) for name, functions in before["handlers"].items()}
    for name, function in registry.handlers:
        handlers[name].append(function)
    after["handlers"] = handlers
    after["timers"] = {fn.__qualname__: True for fn, _ in registry.timers}
    return after


def test_entry_reexports_package_functions(entry):
    package = sys.modules[ENTRY + ".vsgl_addon"]
    assert entry.register is package.register
    assert entry.unregister is package.unregister
    assert not hasattr(entry, "bl_info"), "extensions take their metadata from blender_manifest.toml"


def test_register_unregister_twice(entry, registry, baseline):
    assert registry.classes, "the registry lists no classes"
    registered = expected_registered(baseline, registry)
    for round_ in (1, 2):
        entry.register()
        state = blender_state(registry)
        # bpy.types may list registered classes; everything else must match exactly.
        assert {k: v for k, v in state.items() if k != "bpy.types"} == {
            k: v for k, v in registered.items() if k != "bpy.types"
        }, f"after register #{round_}"
        assert set(baseline["bpy.types"]) <= set(state["bpy.types"])
        entry.unregister()
        assert blender_state(registry) == baseline, f"after unregister #{round_}"


def test_defaults_on_new_scene(entry, baseline):
    entry.register()
    scene = bpy.data.scenes.new("vsgl-defaults")
    try:
        s = scene.vsgl
        assert (s.vsgl_count, s.k, s.kernel, s.rsm_size, s.seed) == (256, 1.0, "MODIFIED", 128, 0)
    finally:
        bpy.data.scenes.remove(scene)


def test_property_ranges_and_tooltips(entry, baseline):
    entry.register()
    props = bpy.types.Scene.bl_rna.properties["vsgl"].fixed_type.properties
    ranges = {name: (props[name].hard_min, props[name].hard_max) for name in ("vsgl_count", "k", "rsm_size")}
    assert ranges == {"vsgl_count": (1, 4096), "k": (0.25, 16.0), "rsm_size": (1, 2048)}
    assert props["seed"].hard_min == 0
    kernel = props["kernel"]
    assert [item.identifier for item in kernel.enum_items] == ["MODIFIED", "ORIGINAL", "TWO_VSGL"]
    assert [item.name for item in kernel.enum_items] == ["Modified (Eq. 3)", "Original (Eqs. 1, 4)", "Two VSGLs (003)"]
    positions = props["positional_distribution"]
    assert [item.identifier for item in positions.enum_items] == ["PER_LOBE", "SHARED"]
    assert positions.default == "PER_LOBE"
    for name in ("vsgl_count", "k", "kernel", "rsm_size", "seed", "positional_distribution"):
        assert len(props[name].description) > 40, f"{name} needs a tooltip that explains the trade"
    for item in (*kernel.enum_items, *positions.enum_items):
        assert len(item.description) > 40, item.identifier


def test_register_is_idempotent(entry, registry, baseline):
    entry.register()
    entry.register()
    state = blender_state(registry)
    assert state["scene properties"].count("vsgl") == 1
    assert all(state["registered classes"].values())
    entry.unregister()
    assert blender_state(registry) == baseline


def test_unregister_when_partly_registered(entry, registry, baseline):
    entry.unregister()  # nothing registered: harmless
    bpy.utils.register_class(registry.classes[0])  # classes but no Scene.vsgl
    entry.unregister()
    assert blender_state(registry) == baseline


def test_failed_register_rolls_back(entry, registry, baseline, monkeypatch):
    package = sys.modules[ENTRY + ".vsgl_addon"]

    def broken_property():
        raise RuntimeError("broken on purpose")

    broken = registry._replace(properties=(*registry.properties, (bpy.types.Scene, "vsgl_broken", broken_property)))
    monkeypatch.setattr(package, "_registry", lambda: broken)
    with pytest.raises(RuntimeError, match="broken on purpose"):
        entry.register()
    assert blender_state(registry) == baseline


def test_packaged_modules_use_relative_imports_only():
    """Installed, the package is bl_ext.<repo>.vsgl: an absolute `import vsgl_addon` would fail there."""
    offenders = []
    for path in PACKAGED_PY:
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module or ""]
            else:
                continue
            offenders += [f"{path.relative_to(REPO)}:{node.lineno}: {n}" for n in names if n.split(".")[0] == "vsgl_addon"]
        if path.name == "__init__.py":
            assigned = {t.id for node in ast.walk(tree) if isinstance(node, ast.Assign) for t in node.targets
                        if isinstance(t, ast.Name)}
            assert "bl_info" not in assigned, f"{path.relative_to(REPO)}: bl_info is for legacy add-ons"
    assert not offenders, offenders


BLOCKED = ("bpy", "gpu", "mathutils", "bmesh", "bgl", "gpu_extras", "bpy_extras")


def test_reference_imports_without_bpy(tmp_path):
    """vsgl_addon and vsgl_addon.reference (with every submodule) import in plain Python with bpy unavailable."""
    blockers = tmp_path / "blockers"
    blockers.mkdir()
    for name in BLOCKED:
        (blockers / f"{name}.py").write_text(f"raise ImportError('{name} is blocked for this test')\n")
    code = textwrap.dedent(
        f"""
        import importlib, pkgutil, sys
        try:
            import bpy
        except ImportError as ex:
            assert "blocked" in str(ex), ex
        else:
            raise SystemExit("the bpy blocker did not work")
        import vsgl_addon
        import vsgl_addon.reference as reference
        imported = [reference.__name__]
        for info in pkgutil.walk_packages(reference.__path__, reference.__name__ + "."):
            importlib.import_module(info.name)
            imported.append(info.name)
        loaded = sorted(m for m in {BLOCKED!r} if m in sys.modules and sys.modules[m] is not None)
        assert not loaded, loaded
        print("imported without bpy:", imported)
        """
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        cwd=REPO,
        env={"PYTHONPATH": f"{blockers}:{REPO}", "PATH": "/usr/bin:/bin", "PYTHONDONTWRITEBYTECODE": "1"},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "imported without bpy" in proc.stdout
