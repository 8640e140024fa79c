# SPDX-License-Identifier: GPL-3.0-or-later
"""The rectangle proxies' debug outlines in the bpy module (vsgl_addon/proxy_outlines.py): the
timer builds them only while scene.vsgl.show_proxy_outlines is on, the draw shows them where the
demo floor's rectangle projects, the Object panel offers the per-object override, and switching
off or unregistering frees everything. The segments themselves: test_proxies.py."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import bpy
import numpy as np
import pytest

import vsgl_addon
from vsgl_addon import proxies as P, proxy_outlines, ui
from vsgl_addon.scene import extract_scene

pytestmark = pytest.mark.gpu

REPO = Path(__file__).resolve().parents[1]
SIZE = (160, 120)


@pytest.fixture
def demo():
    vsgl_addon.unregister()
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"), load_ui=False)
    vsgl_addon.register()
    yield bpy.context.scene
    vsgl_addon.unregister()
    assert proxy_outlines.state.gpu_resource_count() == 0 and not proxy_outlines.is_installed()
    bpy.ops.wm.read_factory_settings(use_empty=True)


def _draw(view, projection):
    import gpu
    from mathutils import Matrix

    offscreen = gpu.types.GPUOffScreen(*SIZE, format="RGBA32F")
    try:
        with offscreen.bind():
            framebuffer = gpu.state.active_framebuffer_get()
            framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0))
            gpu.state.viewport_set(0, 0, *SIZE)
            with gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
                gpu.matrix.load_matrix(Matrix(view.tolist()))
                gpu.matrix.load_projection_matrix(Matrix(projection.tolist()))
                drawn = proxy_outlines.draw(SIZE)
            buffer = framebuffer.read_color(0, 0, SIZE[0], SIZE[1], 4, 0, "FLOAT")
        buffer.dimensions = SIZE[0] * SIZE[1] * 4
        return drawn, np.array(buffer, np.float32).reshape(SIZE[1], SIZE[0], 4)
    finally:
        offscreen.free()


def test_outlines_are_built_while_on_drawn_over_the_floor_and_freed(demo):
    scene = demo
    assert proxy_outlines.is_installed()
    proxy_outlines.timer()
    assert proxy_outlines.state.gpu_resource_count() == 0  # off: nothing built
    scene.vsgl.show_proxy_outlines = True
    proxy_outlines.timer()
    state = proxy_outlines.state
    assert state.error is None and state.batch is not None and not state.dirty
    description = extract_scene(bpy.context.evaluated_depsgraph_get())
    built = P.build_proxies(description, scene.vsgl.caustic_roughness)
    assert built and state.segments == 4 * len(built) + len(P.lit_proxies(built, description))
    view, projection = description.camera.view_matrix(), description.camera.projection_matrix()
    drawn, image = _draw(view, projection)
    assert drawn
    lit = np.all(np.abs(image[..., :3] - np.float32(P.OUTLINE_LIT[:3])) < 0.02, axis=-1) & (image[..., 3] > 0.5)
    assert lit.sum() > 20  # the lit floor's edges
    # Every outline pixel is within two pixels of a projected edge of a proxy.
    corners = np.concatenate([p.corners() for p in built])
    clip = np.c_[corners, np.ones(len(corners))] @ (projection @ view).T
    screen = (clip[:, :2] / clip[:, 3:4] * 0.5 + 0.5) * SIZE
    ys, xs = np.nonzero(lit)
    pixels = np.c_[xs + 0.5, ys + 0.5]
    distance = np.full(len(pixels), np.inf)
    for r in range(len(built)):
        quad = screen[4 * r:4 * r + 4]
        for i in range(4):
            a, b = quad[i], quad[(i + 1) % 4]
            t = np.clip(((pixels - a) @ (b - a)) / max((b - a) @ (b - a), 1e-12), 0.0, 1.0)
            distance = np.minimum(distance, np.linalg.norm(pixels - (a + t[:, None] * (b - a)), axis=1))
    assert np.quantile(distance, 0.95) < 2.0, np.quantile(distance, 0.95)
    # A scene change marks them stale; the next timer call rebuilds.
    state.dirty = True
    proxy_outlines.timer()
    assert not state.dirty and state.batch is not None
    scene.vsgl.show_proxy_outlines = False
    assert state.gpu_resource_count() == 0
    assert not _draw(view, projection)[0]


def test_panels_offer_the_outlines_and_the_per_object_override(demo):
    from test_ui import RecordingLayout

    scene = demo
    layout = RecordingLayout()
    ui.VIEW3D_PT_vsgl_overlay.draw(SimpleNamespace(layout=layout), SimpleNamespace(scene=scene))
    assert "show_proxy_outlines" in layout.record["props"]
    assert len(scene.vsgl.bl_rna.properties["show_proxy_outlines"].description) > 40
    floor = next(obj for obj in scene.objects if obj.type == "MESH")
    context = SimpleNamespace(object=floor, scene=scene)
    assert ui.OBJECT_PT_vsgl_proxy.is_registered and ui.OBJECT_PT_vsgl_proxy.poll(context)
    layout = RecordingLayout()
    ui.OBJECT_PT_vsgl_proxy.draw(SimpleNamespace(layout=layout), context)
    assert layout.record["props"] == ["vsgl_proxy"]
    lamp = next(obj for obj in scene.objects if obj.type == "LIGHT")
    assert not ui.OBJECT_PT_vsgl_proxy.poll(SimpleNamespace(object=lamp, scene=scene))
