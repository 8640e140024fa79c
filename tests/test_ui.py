# SPDX-License-Identifier: GPL-3.0-or-later
"""Panels, overlay properties and look-dev operators in the bpy module (ui.py, properties.py, operators.py).

Panels are drawn into a recording layout (no window here); the real sidebar is checked on screen
by test_overlay_real_blender.py.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import bpy
import numpy as np
import pytest

import vsgl_addon
from vsgl_addon import engine, overlay, ui
from vsgl_addon.operators import settings_image_name
from vsgl_addon.settings import KERNELS, OVERLAY_DISPLAYS, POSITIONS, QUALITY_MODES, VSGLSettings

REPO = Path(__file__).resolve().parents[1]


class RecordingLayout:
    """Stands in for bpy.types.UILayout: records every prop, label and operator drawn."""

    def __init__(self, record=None):
        self.record = record if record is not None else {"props": [], "labels": [], "operators": [], "layouts": []}
        self.record["layouts"].append(self)
        self.use_property_split = self.use_property_decorate = False
        self.active = self.enabled = True
        self.props = []  # drawn into this layout itself

    def _child(self, *args, **kwargs):
        return RecordingLayout(self.record)

    column = row = box = grid_flow = split = _child

    def separator(self, **kwargs):
        pass

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, name
        self.record["props"].append(name)
        self.props.append(name)

    def label(self, text="", **kwargs):
        self.record["labels"].append(text)

    def operator(self, idname, **kwargs):
        self.record["operators"].append(idname)


@pytest.fixture
def registered():
    vsgl_addon.unregister()
    # Module state the panels draw from: a render or overlay of an earlier test (of any file) filled it.
    overlay.views.free()
    engine.last_frame_statistics.clear()
    bpy.ops.wm.open_mainfile(filepath=str(REPO / "demo.blend"), load_ui=False)
    vsgl_addon.register()
    yield bpy.context.scene
    vsgl_addon.unregister()
    overlay.views.free()
    engine.last_frame_statistics.clear()
    bpy.ops.wm.read_factory_settings(use_empty=True)


def draw(panel_class, scene):
    layout = RecordingLayout()
    panel = SimpleNamespace(layout=layout)
    context = SimpleNamespace(scene=scene, engine=scene.render.engine)
    panel_class.draw(panel, context)
    return layout.record


def test_sidebar_tab_and_render_properties_show_every_setting(registered):
    scene = registered
    for cls in ui.CLASSES:
        assert cls.is_registered
    sidebar = [cls for cls in ui.CLASSES if cls.bl_space_type == "VIEW_3D"]
    assert {cls.bl_category for cls in sidebar} == {"VSGL"} and {cls.bl_region_type for cls in sidebar} == {"UI"}
    wanted = {"vsgl_count", "k", "kernel", "positional_distribution", "rsm_size", "seed", "show_overlay", "overlay_mode",
              "overlay_resolution_scale", "overlay_intensity"}
    for prefix in ("VIEW3D_PT_vsgl", "RENDER_PT_vsgl"):
        drawn = set()
        for cls in ui.CLASSES:
            if cls.__name__.startswith(prefix):
                drawn |= set(draw(cls, scene)["props"])
                if hasattr(cls, "draw_header"):
                    drawn |= set(draw_header(cls, scene))
        assert wanted <= drawn, f"{prefix}: missing {wanted - drawn}"
    operators = set()
    for cls in (ui.VIEW3D_PT_vsgl_lookdev, ui.RENDER_PT_vsgl_lookdev):
        operators |= set(draw(cls, scene)["operators"])
    assert operators == {"vsgl.render_preview", "vsgl.render_to_file"}


def test_pass_settings_a_kernel_ignores_are_greyed_out(registered):
    scene = registered
    for kernel in KERNELS:
        scene.vsgl.kernel = kernel.identifier
        layouts = draw(ui.VIEW3D_PT_vsgl_passes, scene)["layouts"]
        greyed = {name for layout in layouts if not layout.enabled for name in layout.props}
        # Manual mode has no target frame time.
        assert greyed == set(kernel.ignores) | {"time_budget_ms"}, kernel.identifier
    assert KERNELS.identified("TWO_VSGL").ignores  # the case that greys something


def test_budget_mode_greys_out_what_it_chooses(registered):
    scene = registered
    scene.vsgl.kernel = "MODIFIED"
    scene.vsgl.quality_mode = "BUDGET"
    try:
        layouts = draw(ui.VIEW3D_PT_vsgl_passes, scene)["layouts"]
        greyed = {name for layout in layouts if not layout.enabled for name in layout.props}
        assert greyed == set(QUALITY_MODES.named("budget").ignores) == {
            "vsgl_count", "rsm_size", "delta_log10", "vpl_interleave"}
    finally:
        scene.vsgl.quality_mode = "MANUAL"


def test_enum_properties_are_the_settings_tables(registered):
    properties = registered.vsgl.bl_rna.properties
    for prop, table in (("kernel", KERNELS), ("positional_distribution", POSITIONS),
                        ("overlay_mode", OVERLAY_DISPLAYS)):
        items = [(item.identifier, item.name, item.description, item.value) for item in properties[prop].enum_items]
        assert items == [(choice.identifier, choice.label, choice.description, number)
                         for number, choice in enumerate(table)], prop
    operator = bpy.ops.vsgl.render_preview.get_rna_type().properties["pass_name"]
    assert [item.identifier for item in operator.enum_items] == ["COMBINED", "INDIRECT", "INDIRECT_DIFFUSE",
                                                                 "INDIRECT_SPECULAR", "DIRECT"]


def draw_header(cls, scene):
    layout = RecordingLayout()
    cls.draw_header(SimpleNamespace(layout=layout), SimpleNamespace(scene=scene))
    return layout.record["props"]


def test_render_panels_only_with_the_vsgl_engine(registered):
    scene = registered
    assert ui.RENDER_PT_vsgl.poll(SimpleNamespace(engine="VSGL", scene=scene))
    assert not ui.RENDER_PT_vsgl.poll(SimpleNamespace(engine="CYCLES", scene=scene))
    assert ui.VIEW3D_PT_vsgl.poll(SimpleNamespace(scene=scene))


def test_pass_sections_name_real_properties_so_new_ones_slot_in(registered):
    names = [name for _heading, names in ui.PASS_SECTIONS for name in names]
    assert set(names) == {"quality_mode", "time_budget_ms", "rsm_size", "vsgl_count", "k", "kernel", "pdf", "positional_distribution", "seed", "visibility",
                          "ism_size", "ism_points", "glossy_reflectors", "disk_radius", "caustic_roughness",
                          "reflector_mode", "caustics", "delta_log10", "vpl_interleave", "vpl_filter_radius",
                          "vpl_samples", "vpl_visibility"}
    for name in names:
        assert name in registered.vsgl.bl_rna.properties


def test_statistics_and_warnings_are_shown(registered):
    scene = registered
    assert "Turn on the overlay or render to see timings" in draw(ui.VIEW3D_PT_vsgl_statistics, scene)["labels"]
    plan = {"summary": ["VSGLs: on — N = 256 for the frame", "MRP-ASG: off — no lit rectangle proxy"]}
    engine.last_frame_statistics.update(timings={"gbuffer": 0.012, "vsgl_shading": 0.5}, counts={"vsgls": 256},
                                        resolution=[96, 72], warnings=["VSGL: skipped lights: Sun"],
                                        proxies=[{"object": "Floor", "size": [4.0, 3.0], "roughness": 0.2,
                                                  "lit_by": ["Spot", "Sun"]}], plan=plan)
    pipeline = overlay.views.pipeline(1)  # a viewport's pipeline whose last step was a coarse image
    pipeline.statistics = {"work": "lights", "level": "coarse", "seconds": 0.2, "size": (80, 60),
                           "light_seconds": 0.05, "view_seconds": 0.15, "counts": {"lights": 1}}
    overlay.views.last = pipeline
    overlay.views.settings_error = "ShaderCompileError: broken"
    labels = draw(ui.VIEW3D_PT_vsgl_statistics, scene)["labels"]
    for text in ("VSGL Shading", "500.0 ms", "150.0 ms", "Light passes", "50.0 ms", "VSGLs", "256",
                 "Last render 96×72", "Overlay: last step (coarse 80×60)", "Last step", "200.0 ms",
                 "Rectangle proxies (MRP-ASG):", "Floor: 4.00 × 3.00 m, roughness 0.200, lit by Spot, Sun",
                 "Frame plan", *plan["summary"]):
        assert text in labels, text
    top = draw(ui.VIEW3D_PT_vsgl, scene)["labels"]
    assert "Overlay stopped: ShaderCompileError: broken" in top and "VSGL: skipped lights: Sun" in top


def test_overlay_properties_defaults_ranges_tooltips(registered):
    settings = registered.vsgl
    properties = settings.bl_rna.properties
    assert settings.show_overlay is False
    assert settings.overlay_mode == "INDIRECT"
    assert {item.identifier for item in properties["overlay_mode"].enum_items} == set(OVERLAY_DISPLAYS.identifiers)
    scale = properties["overlay_resolution_scale"]
    assert (scale.default, scale.hard_min, scale.hard_max) == pytest.approx((0.25, 0.02, 1.0))
    intensity = properties["overlay_intensity"]
    assert intensity.default == 1.0 and intensity.hard_min == 0.0
    for name in ("show_overlay", "overlay_mode", "overlay_resolution_scale", "overlay_intensity"):
        assert len(properties[name].description) > 40, name
    assert "square" in scale.description  # the cost
    settings.overlay_resolution_scale = 5.0
    assert settings.overlay_resolution_scale == 1.0


@pytest.mark.gpu
def test_preview_operator_makes_an_image_named_for_its_settings(registered):
    scene = registered
    scene.vsgl.vsgl_count, scene.vsgl.rsm_size = 32, 32
    width = scene.render.resolution_x * scene.render.resolution_percentage // 100 * 10 // 100
    assert bpy.ops.vsgl.render_preview(percentage=10) == {"FINISHED"}
    name = settings_image_name(VSGLSettings.from_properties(scene.vsgl))
    assert name == "VSGL N32 K1 Modified RSM32 Seed0 Combined"
    image = bpy.data.images[name]
    assert image.size[0] == width
    pixels = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(pixels)
    assert pixels.reshape(-1, 4)[:, :3].max() > 0
    # Other settings: another image beside it (A/B); the same settings again: the same image.
    scene.vsgl.k = 2.0
    assert bpy.ops.vsgl.render_preview(percentage=10, pass_name="INDIRECT") == {"FINISHED"}
    assert "VSGL N32 K2 Modified RSM32 Seed0 Indirect" in bpy.data.images
    count = len(bpy.data.images)
    assert bpy.ops.vsgl.render_preview(percentage=10, pass_name="INDIRECT") == {"FINISHED"}
    assert len(bpy.data.images) == count


@pytest.mark.gpu
@pytest.mark.parametrize("file_format, extension", [("OPEN_EXR", ".exr"), ("PNG", ".png")])
def test_render_to_file(registered, tmp_path, file_format, extension):
    scene = registered
    scene.vsgl.vsgl_count, scene.vsgl.rsm_size = 16, 32
    images_before = set(bpy.data.images.keys())
    target = tmp_path / "out" / "render"
    assert bpy.ops.vsgl.render_to_file(filepath=str(target), file_format=file_format, percentage=10) == {"FINISHED"}
    written = target.with_suffix(extension)
    assert written.is_file() and written.stat().st_size > 100
    assert set(bpy.data.images.keys()) == images_before  # its temporary image is gone
    loaded = bpy.data.images.load(str(written))
    try:
        assert loaded.size[0] == scene.render.resolution_x * scene.render.resolution_percentage // 100 * 10 // 100
    finally:
        bpy.data.images.remove(loaded)


@pytest.mark.gpu
def test_render_to_file_reports_failure(registered, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(RuntimeError, match="failed"):
        bpy.ops.vsgl.render_to_file(filepath=str(blocker / "x.exr"), percentage=5)
