# SPDX-License-Identifier: GPL-3.0-or-later
"""The debug overlay of the rectangle proxies (001): their outlines drawn in every 3D viewport
(Blender glue; the segments come from the bpy-free ``proxies.outline_lines``).

``scene.vsgl.show_proxy_outlines`` switches it on. Three parts, as the light overlay's (overlay.py):

* the **draw callback** (``SpaceView3D.draw_handler_add``, POST_VIEW, so Blender's view and
  projection matrices apply) only draws the cached line batch with Blender's built-in polyline
  shader: nothing is built or uploaded there;
* the **depsgraph handler** marks the outlines stale when something that can change them changed
  (overlay._light_changed's rule: geometry, a material, a light moving changes which side is lit);
* the **timer** rebuilds the batch when stale: the scene description, the proxies (the renderer's
  cache, so unchanged geometry is not refitted) and which sides a light reaches.

Everything is freed when the option is switched off, a file is loaded or the add-on is unregistered.
"""

from __future__ import annotations

from .settings import VSGLSettings

#: Width of the outlines in pixels.
LINE_WIDTH = 2.0
BUSY_INTERVAL = 0.1
OFF_INTERVAL = 0.5


class OutlineState:
    """The cached batch (and its shader) and what it was built from."""

    def __init__(self):
        self.batch = None
        self.shader = None
        self.dirty = True
        self.segments = 0  # line segments in the batch
        self.settings_key = None  # α_c and glossy_reflectors the batch was built with
        self.error: str | None = None

    def free(self) -> None:
        self.batch = None
        self.shader = None
        self.segments = 0
        self.dirty = True
        self.settings_key = None
        self.error = None

    def gpu_resource_count(self) -> int:
        return (self.batch is not None) + (self.shader is not None)


state = OutlineState()
_draw_handle = None


def build(description, settings: VSGLSettings) -> None:
    """Make the batch of ``description``'s proxy outlines (main thread, GPU context)."""
    import gpu
    from gpu_extras.batch import batch_for_shader

    from .proxies import outline_lines
    from .renderer import PROXY_CACHE, scene_proxies

    overrides = getattr(description, "proxy_overrides", None)
    proxies = PROXY_CACHE.get(description, settings.caustic_roughness, overrides)
    lit = scene_proxies(description, settings) if settings.glossy_reflectors else []
    positions, colours = outline_lines(proxies, lit)
    if state.shader is None:
        state.shader = gpu.shader.from_builtin("POLYLINE_SMOOTH_COLOR")
    state.batch = batch_for_shader(state.shader, "LINES", {"pos": positions.tolist(), "color": colours.tolist()}) \
        if len(positions) else None
    state.segments = len(positions) // 2
    state.dirty = False


def draw(viewport_size) -> bool:
    """Draw the cached outlines with the bound framebuffer's matrices; False when there are none."""
    import gpu

    if state.batch is None or state.shader is None:
        return False
    saved = (gpu.state.blend_get(), gpu.state.depth_test_get())
    try:
        # Always on top: an outline lies in its surface's plane and would z-fight with it.
        gpu.state.depth_test_set("NONE")
        gpu.state.blend_set("ALPHA")
        state.shader.bind()
        state.shader.uniform_float("viewportSize", (float(viewport_size[0]), float(viewport_size[1])))
        state.shader.uniform_float("lineWidth", LINE_WIDTH)
        state.batch.draw(state.shader)
    finally:
        gpu.state.blend_set(saved[0])
        gpu.state.depth_test_set(saved[1])
    return True


def draw_callback() -> None:
    import bpy

    context = bpy.context
    settings = getattr(context.scene, "vsgl", None)
    if settings is None or not settings.show_proxy_outlines or context.region is None:
        return
    space = context.space_data
    if space is not None and not space.overlay.show_overlays:
        return
    draw((context.region.width, context.region.height))


def _tag_redraw() -> None:
    from .overlay import _tag_redraw as tag

    tag()


def _settings_key(settings: VSGLSettings):
    return (settings.caustic_roughness, settings.glossy_reflectors)


def timer() -> float:
    """bpy.app.timers callback: rebuild stale outlines while the option is on."""
    import bpy

    from .overlay import describe_context_scene

    scene = getattr(bpy.context, "scene", None)
    properties = getattr(scene, "vsgl", None) if scene is not None else None
    if properties is None or not properties.show_proxy_outlines:
        if state.gpu_resource_count():
            state.free()
        return OFF_INTERVAL
    try:
        settings = VSGLSettings.from_properties(properties)
    except ValueError as error:
        state.error = str(error)
        return OFF_INTERVAL
    if state.dirty or state.settings_key != _settings_key(settings):
        try:
            build(describe_context_scene(), settings)
            state.settings_key = _settings_key(settings)
            state.error = None
        except Exception as error:  # noqa: BLE001 - a debug display never raises into Blender's loop
            state.error = f"{type(error).__name__}: {error}"
            state.dirty = False
        _tag_redraw()
    return BUSY_INTERVAL


def on_toggled(enabled: bool) -> None:
    """show_proxy_outlines changed: on -> build on the next timer call; off -> free."""
    state.free()
    _tag_redraw()


def _persistent(function):
    import bpy

    return bpy.app.handlers.persistent(function)


@_persistent
def on_depsgraph_update(scene, depsgraph) -> None:
    from .overlay import _light_changed

    settings = getattr(scene, "vsgl", None)
    if settings is not None and settings.show_proxy_outlines and _light_changed(depsgraph):
        state.dirty = True


@_persistent
def on_load_pre(*_args) -> None:
    state.free()


def install() -> None:
    global _draw_handle
    import bpy

    if _draw_handle is None:
        _draw_handle = bpy.types.SpaceView3D.draw_handler_add(draw_callback, (), "WINDOW", "POST_VIEW")


def uninstall() -> None:
    global _draw_handle
    import bpy

    if _draw_handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_draw_handle, "WINDOW")
        _draw_handle = None
    state.free()


def is_installed() -> bool:
    return _draw_handle is not None


HANDLERS = (("depsgraph_update_post", on_depsgraph_update), ("load_pre", on_load_pre))
TIMERS = ((timer, {"first_interval": OFF_INTERVAL, "persistent": True}),)
HOOKS = ((install, uninstall),)
