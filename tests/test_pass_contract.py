# SPDX-License-Identifier: GPL-3.0-or-later
"""One pass contract (vsgl_addon/passes/contract.py): every pass in PASSES compiles and frees its
shaders, its reads come from earlier passes, and the frame's timings and the statistics labels
come from PASSES."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vsgl_addon import layouts, passes
from vsgl_addon.passes.contract import GPUPass, ShaderSpec, Step


def test_every_pass_module_declares_its_pass_once():
    modules = [passes.rsm, passes.brsm, passes.vsgl_generation, passes.ism, passes.mrp_visibility, passes.gbuffer,
               passes.direct_light, passes.shading_inputs, passes.vsgl_shading, passes.vpl_culling, passes.mrp_asg]
    assert [module.PASS for module in modules] == list(passes.PASSES)
    assert len({gpu_pass.name for gpu_pass in passes.PASSES}) == len(passes.PASSES)
    for gpu_pass in passes.PASSES:
        assert isinstance(gpu_pass, GPUPass) and gpu_pass.shaders and callable(gpu_pass.run)


def test_reads_come_from_the_scene_or_an_earlier_pass_and_layout_names_are_declared():
    available = {"scene"}
    for gpu_pass in passes.PASSES:
        missing = set(gpu_pass.reads) - available
        assert not missing, f"{gpu_pass.name} reads {missing} before any pass writes them"
        available |= set(gpu_pass.writes)
    for name in ("vsgl_table", "rsm", "gbuffer", "shading_inputs"):
        assert name in layouts.LAYOUTS and name in available


def test_timing_steps_and_labels_come_from_passes():
    assert [step.name for step in passes.STEPS] == [
        "scene_extraction", "upload", "rsm_and_vsgl_generation", "ism", "vpl_extraction", "mrp_visibility", "gbuffer",
        "direct_light", "vsgl_shading", "vpl_culling", "mrp_asg", "read_back"]
    assert passes.TIMING_LABELS == {step.name: step.label for step in passes.STEPS}
    assert set(passes.COUNT_LABELS) == {"lights", "rsm_views", "vsgls", "triangles", "proxies", "vpls",
                                        "vpls_per_pixel"}


def test_a_new_pass_brings_its_own_step_and_labels(monkeypatch):
    extra = GPUPass(name="ism", label="Imperfect Shadow Maps", step=Step("ism", "ISM", {"points": "ISM Points"}),
                    shaders={}, reads=("scene",), writes=("ism",), run=lambda: None)
    monkeypatch.setattr(passes, "PASSES", passes.PASSES + (extra,))
    steps = passes._steps()
    assert steps[-2] == extra.step and steps[-1] == passes.READ_BACK


def test_ui_labels_are_the_passes_labels():
    from vsgl_addon import ui

    assert ui.TIMING_LABELS is passes.TIMING_LABELS
    assert ui.COUNT_LABELS is passes.COUNT_LABELS


@pytest.mark.gpu
@pytest.mark.parametrize("gpu_pass", passes.PASSES, ids=[p.name for p in passes.PASSES])
def test_every_pass_compiles_and_frees_its_shaders(gpu_pass):
    gpu_pass.free_shaders()
    gpu_pass.compile_shaders()
    compiled = {key: gpu_pass.shader(key) for key in gpu_pass.shaders}
    assert all(hasattr(shader, "bind") for shader in compiled.values())
    assert all(gpu_pass.shader(key) is shader for key, shader in compiled.items())  # cached
    gpu_pass.free_shaders()
    assert all(gpu_pass.shader(key) is not shader for key, shader in compiled.items())  # rebuilt
    gpu_pass.free_shaders()


@pytest.mark.gpu
def test_compile_all_and_free_all_cover_every_pass():
    passes.free_all_shaders()
    passes.compile_all_shaders()
    for gpu_pass in passes.PASSES:
        assert all(key in gpu_pass._cache for key in gpu_pass.shaders), gpu_pass.name
    passes.free_all_shaders()
    assert all(not gpu_pass._cache for gpu_pass in passes.PASSES)


@pytest.mark.gpu
def test_a_frame_times_exactly_the_declared_steps_and_each_run_result_frees():
    import scene_builders as sb
    from vsgl_addon.scene import extract_scene
    from vsgl_addon.settings import VSGLSettings

    scene = sb.reset()
    sb.plane("Floor", size=4.0)
    sb.spot_light(power=500.0, location=(0, 0, 2), look_at_point=(0, 0, 0))
    sb.camera()
    description = extract_scene(sb.depsgraph(scene))
    frame = sb.render_frame(description, VSGLSettings(vsgl_count=8, rsm_size=16), 16, 12)
    assert list(frame.timings) == [step.name for step in passes.STEPS if step is not passes.SCENE_EXTRACTION]
    assert set(frame.counts) == set(passes.COUNT_LABELS)

    views = passes.rsm.PASS.run(description, 0, 16)
    assert views and all(view.textures for view in views)
    passes.rsm.PASS.free(views)
    assert all(not view.textures for view in views)
    generation = passes.vsgl_generation.PASS.run(_lit_rsm(), 4)
    assert generation.table is not None
    passes.vsgl_generation.PASS.free(generation)
    assert generation.table is None


def _lit_rsm(size=4):
    from vsgl_addon.reference.vsgl import RSM

    ones = np.ones((size, size, 3))
    position = np.zeros((size, size, 3))
    normal = np.broadcast_to([0.0, 0.0, 1.0], (size, size, 3))
    return RSM(position, normal, ones, 0.5 * ones, normal, np.full((size, size), 10.0))


def test_shader_specs_are_read_at_compile_time():
    # defines and generated code are callables, so a patched layout reaches the next compile.
    spec = passes.vsgl_shading.PASS.shaders["cosine"]
    assert isinstance(spec, ShaderSpec)
    assert "VSGLRecord vsgl_table_load" in spec.code()["fragment"]
    assert spec.defines()["VSGL_DIFFUSE_MODE"] == 0 and spec.defines()["VSGL_VISIBILITY"] == 0
    with pytest.raises(dataclasses.FrozenInstanceError):
        spec.stages = {}
