# SPDX-License-Identifier: GPL-3.0-or-later
"""The choice tables (vsgl_addon/settings.py) and what is derived from them, without Blender.

A .blend file stores an enum property's identifier and item number, so both are fixed here as
they are in every saved file (demo.blend included); labels and descriptions may change.
"""

from __future__ import annotations

import numpy as np
import pytest

from vsgl_addon import settings
from vsgl_addon.cli import UsageError, build_parser
from vsgl_addon.reference import vsgl as reference_vsgl
from vsgl_addon.settings import (KERNELS, LOOKDEV_PASSES, OVERLAY_DISPLAYS, PDFS, POSITIONS, PROXY_OVERRIDES,
                                REFLECTOR_MODES, VIEWPORT_PASSES, Choice, Choices,
                                 VSGLSettings)

STORED = {
    "kernel": (KERNELS, ["MODIFIED", "ORIGINAL", "TWO_VSGL"]),
    "positional_distribution": (POSITIONS, ["PER_LOBE", "SHARED"]),
    "overlay_mode": (OVERLAY_DISPLAYS, ["INDIRECT", "ADDED", "INDIRECT_DIFFUSE", "INDIRECT_SPECULAR", "DIRECT",
                                        "COMBINED", "INDIRECT_CAUSTICS", "INDIRECT_GLOSSY_REFLECTORS"]),
    "viewport_pass": (VIEWPORT_PASSES, ["COMBINED", "DIRECT", "INDIRECT", "INDIRECT_DIFFUSE", "INDIRECT_SPECULAR",
                                        "INDIRECT_CAUSTICS", "INDIRECT_GLOSSY_REFLECTORS"]),
    "vpl_interleave": (settings.INTERLEAVE_CHOICES, ["AUTO", "N1", "N2", "N4", "N8"]),
    "reflector_mode": (REFLECTOR_MODES, ["ASG", "SG"]),
    "vsgl_proxy": (PROXY_OVERRIDES, ["AUTO", "ALWAYS", "NEVER"]),
    "pdf": (PDFS, ["LIGHT", "VIEW"]),
}


@pytest.mark.parametrize("prop", sorted(STORED))
def test_stored_identifiers_and_numbers_never_change(prop):
    table, identifiers = STORED[prop]
    assert list(table.identifiers) == identifiers
    assert [table.number(choice.name) for choice in table] == list(range(len(identifiers)))
    for choice in table:
        assert table.identified(choice.identifier) is table.named(choice.name) is choice
        assert len(choice.description) > 40, choice.identifier


def test_pass_names_are_the_tables():
    assert settings.KERNEL_MODES == KERNELS.names == ("modified", "original", "two-vsgl")
    assert settings.POSITIONAL_DISTRIBUTIONS == POSITIONS.names == ("per-lobe", "shared")
    assert reference_vsgl.KERNEL_MODES is settings.KERNEL_MODES  # the reference validates against the same
    assert reference_vsgl.POSITIONAL_DISTRIBUTIONS is settings.POSITIONAL_DISTRIBUTIONS
    assert LOOKDEV_PASSES.names == ("combined", "indirect", "indirect_diffuse", "indirect_specular", "direct")


def test_settings_from_properties_maps_identifiers_to_names():
    for kernel in KERNELS:
        for position in POSITIONS:
            stored = dict(vsgl_count=64, k=2.0, kernel=kernel.identifier, rsm_size=100, seed=3,
                          positional_distribution=position.identifier)
            result = VSGLSettings.from_properties(type("Props", (), stored))
            assert (result.kernel, result.positional_distribution, result.rsm_size) == (
                kernel.name, position.name, 128)
    with pytest.raises(KeyError):
        KERNELS.identified("modified")  # a pass name is not an identifier


@pytest.mark.parametrize("command", ["vsgl", "render"])
def test_cli_choices_are_the_pass_names(command):
    parser = build_parser()
    base = [command, "scene.blend", "--out", "out.file"]
    for kernel, position in zip(KERNELS.names, POSITIONS.names * 2):
        arguments = parser.parse_args([*base, "--kernel", kernel, "--positional-distribution", position])
        assert (arguments.kernel, arguments.positional_distribution) == (kernel, position)
    for flag, identifier in (("--kernel", "MODIFIED"), ("--positional-distribution", "PER_LOBE")):
        with pytest.raises(UsageError, match="invalid choice"):
            parser.parse_args([*base, flag, identifier])  # the .blend identifiers are not the CLI's names


def test_only_the_two_vsgl_kernel_ignores_settings():
    assert {choice.name: choice.ignores for choice in KERNELS} == {
        "modified": (), "original": (), "two-vsgl": ("vsgl_count", "k", "positional_distribution")}
    assert [choice.tag for choice in KERNELS] == ["Modified", "Original", "TwoVSGL"]  # preview image names


def test_a_table_rejects_duplicates():
    with pytest.raises(ValueError, match="duplicate identifier"):
        Choices(Choice("a", "A", "A", "first"), Choice("b", "A", "B", "second"))
    with pytest.raises(ValueError, match="duplicate name"):
        Choices(Choice("a", "A", "A", "first"), Choice("a", "B", "B", "second"))


def test_glossy_reflector_flags_and_settings():
    from vsgl_addon import proxies
    from vsgl_addon.cli import _settings
    from vsgl_addon.reference import mrp_asg

    assert REFLECTOR_MODES.names == mrp_asg.MODES and PROXY_OVERRIDES.names == proxies.PROXY_MODES
    arguments = build_parser().parse_args(["render", "scene.blend", "--out", "out.exr", "--glossy-reflectors", "off",
                                           "--disk-radius", "0.25", "--caustic-roughness", "0.05",
                                           "--reflector-mode", "sg"])
    stored = dict(vsgl_count=64, k=1.0, kernel="MODIFIED", rsm_size=64, seed=0, positional_distribution="PER_LOBE",
                  glossy_reflectors=True, disk_radius=0.1, caustic_roughness=0.1, reflector_mode="ASG")
    scene = type("Scene", (), {"vsgl": type("Props", (), stored)})
    result = _settings(scene, arguments)
    assert (result.glossy_reflectors, result.disk_radius, result.caustic_roughness, result.reflector_mode) == (
        False, 0.25, 0.05, "sg")
    defaults = VSGLSettings.from_properties(type("Props", (), stored))
    assert defaults.glossy_reflectors and defaults.reflector_mode == "asg"
    for bad in (["--disk-radius", "0"], ["--disk-radius", "nan"], ["--caustic-roughness", "2"]):
        arguments = build_parser().parse_args(["render", "scene.blend", "--out", "out.exr", *bad])
        with pytest.raises(UsageError):
            _settings(scene, arguments)


@pytest.mark.parametrize("command", ["render", "vsgl"])
def test_caustics_flags_and_settings(command):
    """The glossy VPL pass's settings: flags on both commands, δ at both ends of its range, the
    interleave table, the panel's log10 control read back as typed."""
    from vsgl_addon.cli import _settings
    from vsgl_addon.settings import DELTA_RANGE, INTERLEAVE_CHOICES, delta_from_log10, interleave_factor

    ext = ".exr" if command == "render" else ".npz"
    stored = dict(vsgl_count=64, k=1.0, kernel="MODIFIED", rsm_size=64, seed=0, positional_distribution="PER_LOBE",
                  delta_log10=np.float32(np.log10(0.0035)), vpl_interleave="N4")
    scene = type("Scene", (), {"vsgl": type("Props", (), stored)})
    defaults = VSGLSettings()
    assert (defaults.caustics, defaults.delta, defaults.vpl_interleave, defaults.vpl_filter_radius,
            defaults.vpl_samples, defaults.vpl_visibility) == (True, 1e-3, "auto", 8, 1, True)
    from_scene = VSGLSettings.from_properties(scene.vsgl)
    assert from_scene.delta == 0.0035 and from_scene.vpl_interleave == "4" and from_scene.vpl_visibility
    arguments = build_parser().parse_args([command, "scene.blend", "--out", "out" + ext, "--caustics", "off",
                                           "--delta", "1e-6", "--vpl-interleave", "8", "--vpl-filter-radius", "0",
                                           "--vpl-samples", "3", "--vpl-visibility", "off"])
    result = _settings(scene, arguments)
    assert (result.caustics, result.delta, result.vpl_interleave, result.vpl_filter_radius, result.vpl_samples,
            result.vpl_visibility) == (False, 1e-6, "8", 0, 3, False)
    for low, high in (DELTA_RANGE,):
        assert delta_from_log10(np.float32(np.log10(low))) == low and delta_from_log10(np.float32(np.log10(high))) == high
    for bad in (["--delta", "0"], ["--delta", "0.2"], ["--delta", "nan"], ["--vpl-filter-radius", "17"],
                ["--vpl-samples", "0"]):
        arguments = build_parser().parse_args([command, "scene.blend", "--out", "out" + ext, *bad])
        with pytest.raises(UsageError):
            _settings(scene, arguments)
    with pytest.raises(UsageError):
        build_parser().parse_args([command, "scene.blend", "--out", "out" + ext, "--vpl-interleave", "3"])
    assert INTERLEAVE_CHOICES.names == ("auto", "1", "2", "4", "8")
    # 004 §6: N = 8 at 1080p; the suite's 240 x 180 shades every VPL in every pixel.
    assert interleave_factor("auto", 1920, 1080) == 8 and interleave_factor("auto", 240, 180) == 1
    assert interleave_factor("auto", 960, 540) == 4 and interleave_factor("2", 1920, 1080) == 2
