# SPDX-License-Identifier: GPL-3.0-or-later
"""VSGL add-on package: real-time glossy indirect illumination with virtual spherical Gaussian lights.

Importing this package must not import ``bpy``: ``vsgl_addon.reference`` (pure numpy) and the
command-line module (``python -m vsgl_addon``) run in plain Python. Everything that needs Blender is
imported inside :func:`register` / :func:`unregister`, from submodules only they import.

What the add-on adds to Blender is declared in one place, :func:`_registry`:

* ``classes``: ``bpy.types`` subclasses, registered in order and unregistered in reverse;
* ``properties``: ``(owner type, attribute, make_property)`` for properties added to Blender types
  (``bpy.types.Scene.vsgl``), attached after the classes and removed before them;
* ``handlers``: ``(bpy.app.handlers list name, function)``; decorate the function with
  ``@bpy.app.handlers.persistent`` if it must survive loading another .blend file;
* ``timers``: ``(function, keyword arguments of bpy.app.timers.register)``;
* ``hooks``: ``(install, uninstall)`` pairs for hooks of another kind (e.g. the overlay's
  ``SpaceView3D.draw_handler_add``, which returns a handle): install() is called last in register(),
  uninstall() first in unregister(); uninstall() must be harmless when nothing is installed.

A new pass's panel, handler or timer is one more entry there.
:func:`unregister` removes exactly what is present, so it also cleans up after a register() that
failed part-way, and calling it twice is harmless.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple


class Registry(NamedTuple):
    classes: tuple[type, ...]
    properties: tuple[tuple[type, str, Callable[[], Any]], ...]
    handlers: tuple[tuple[str, Callable[..., Any]], ...]
    timers: tuple[tuple[Callable[[], float | None], dict[str, Any]], ...]
    hooks: tuple[tuple[Callable[[], None], Callable[[], None]], ...] = ()


def _registry() -> Registry:
    """Everything register() adds, built on demand (it imports bpy-dependent submodules)."""
    from . import engine, operators, overlay, properties, proxy_outlines, ui

    return Registry(
        classes=(*properties.CLASSES, *engine.CLASSES, *operators.CLASSES, *ui.CLASSES),
        properties=(*properties.TYPE_PROPERTIES,),
        handlers=(*overlay.HANDLERS, *proxy_outlines.HANDLERS),
        timers=(*overlay.TIMERS, *engine.TIMERS, *proxy_outlines.TIMERS),
        hooks=(*overlay.HOOKS, *engine.HOOKS, *ui.HOOKS, *proxy_outlines.HOOKS),
    )


def register() -> None:
    import bpy

    reg = _registry()
    try:
        for cls in reg.classes:
            if not cls.is_registered:
                bpy.utils.register_class(cls)
        for owner, attr, make_property in reg.properties:
            setattr(owner, attr, make_property())
        for list_name, function in reg.handlers:
            handler_list = getattr(bpy.app.handlers, list_name)
            if function not in handler_list:
                handler_list.append(function)
        for function, options in reg.timers:
            if not bpy.app.timers.is_registered(function):
                bpy.app.timers.register(function, **options)
        for install, _uninstall in reg.hooks:
            install()
    except Exception:
        # Leave Blender as it was: undo whatever part of the above did happen.
        unregister()
        raise


def unregister() -> None:
    import bpy

    reg = _registry()
    errors: list[str] = []
    for _install, uninstall in reversed(reg.hooks):
        try:
            uninstall()
        except Exception as ex:  # noqa: BLE001 - keep removing the rest
            errors.append(f"{getattr(uninstall, '__qualname__', uninstall)}: {ex}")
    for function, _options in reversed(reg.timers):
        if bpy.app.timers.is_registered(function):
            bpy.app.timers.unregister(function)
    for list_name, function in reversed(reg.handlers):
        handler_list = getattr(bpy.app.handlers, list_name)
        while function in handler_list:
            handler_list.remove(function)
    for owner, attr, _make_property in reversed(reg.properties):
        if attr in owner.bl_rna.properties.keys():
            try:
                delattr(owner, attr)
            except (AttributeError, RuntimeError) as ex:
                errors.append(f"{owner.__name__}.{attr}: {ex}")
    for cls in reversed(reg.classes):
        if cls.is_registered:
            try:
                bpy.utils.unregister_class(cls)
            except RuntimeError as ex:
                errors.append(f"{cls.__name__}: {ex}")
    if errors:
        raise RuntimeError("VSGL: could not unregister " + "; ".join(errors))
