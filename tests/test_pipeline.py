# SPDX-License-Identifier: GPL-3.0-or-later
"""Scene description -> RSM views -> VSGLs of every light (vsgl_addon/pipeline.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import scene_builders as sb
from vsgl_addon.pipeline import generate_scene_vsgls, share_vsgl_count
from vsgl_addon.scene import extract_scene
from vsgl_addon.settings import VSGLSettings


def test_share_vsgl_count_is_proportional_and_sums_to_n():
    assert share_vsgl_count(10, [1.0, 1.0]).tolist() == [5, 5]
    assert share_vsgl_count(7, [3.0, 0.0, 1.0]).tolist() == [5, 0, 2]
    assert share_vsgl_count(1, [0.2, 0.5, 0.3]).tolist() == [0, 1, 0]
    assert share_vsgl_count(4096, np.arange(6.0)).sum() == 4096
    assert share_vsgl_count(64, [0.0, 0.0]).tolist() == [0, 0]
    assert share_vsgl_count(64, []).tolist() == []


@pytest.mark.gpu
@pytest.mark.parametrize("kernel", ["modified", "original", "two-vsgl"])
def test_a_light_that_hits_nothing_costs_nothing_and_the_other_is_whole(kernel):
    scene = sb.reset()
    sb.plane("Floor", size=6.0)
    sb.spot_light(name="Away", power=500.0, location=(0, 0, 2), look_at_point=(0, 0, 10))
    sb.point_light(name="Down", power=300.0, location=(0, 0, 1.5))
    sb.camera()
    description = extract_scene(sb.depsgraph(scene))
    names = [light.name for light in description.lights]
    away, down = names.index("Away"), names.index("Down")
    table = generate_scene_vsgls(description, VSGLSettings(vsgl_count=64, rsm_size=64, kernel=kernel))
    for name, values in table.items():
        assert np.all(np.isfinite(values)), name
    assert table["rsm_view_count"][away] == 0
    assert not np.any(table["light_index"] == away)
    assert np.all(table["rsm_total_power"][away] == 0)
    rows = table["light_index"] == down
    # A point light over a plane: only its downward cube faces see geometry; N is shared among them.
    expected = 2 * table["rsm_view_count"][down] if kernel == "two-vsgl" else 64
    assert rows.sum() == expected
    np.testing.assert_allclose(table["power"][rows].sum(axis=0), table["rsm_total_power"][down], rtol=0.05)


@pytest.mark.gpu
def test_one_view_without_power_gets_vsgls_of_zero_power_that_light_nothing():
    """One RSM view in the frame gets all N without its power being read back
    (FramePlan.allocation_reads_powers); when it reflects nothing (a black floor without specular), those N
    VSGLs carry zero power, finite, and the frame's indirect light stays zero."""
    scene = sb.reset()
    sb.plane("Floor", size=6.0, material=sb.principled("Black", base_color=(0.0, 0.0, 0.0), specular_ior_level=0.0))
    sb.spot_light(name="Down", power=500.0, location=(0, 0, 2), look_at_point=(0, 0, 0))
    sb.camera()
    description = extract_scene(sb.depsgraph(scene))
    settings = VSGLSettings(vsgl_count=64, rsm_size=64)
    table = generate_scene_vsgls(description, settings)
    for name, values in table.items():
        assert np.all(np.isfinite(values)), name
    assert table["rsm_view_count"].tolist() == [1] and len(table["light_index"]) == 64
    assert np.all(table["power"] == 0.0) and np.all(table["rsm_total_power"] == 0.0)
    images = sb.render_frame(description, settings, 48, 36)
    sb.assert_finite_frame(images)
    assert images.indirect.max() == 0.0


def test_positional_distribution_setting_is_checked_and_read_from_the_scene():
    from types import SimpleNamespace

    from vsgl_addon.settings import SettingsError, VSGLSettings

    assert VSGLSettings().positional_distribution == "per-lobe"
    with pytest.raises(SettingsError, match="positional distribution must be one of per-lobe, shared"):
        VSGLSettings(positional_distribution="paper")
    properties = SimpleNamespace(vsgl_count=64, k=2.0, kernel="ORIGINAL", rsm_size=100, seed=3,
                                 positional_distribution="SHARED")
    settings = VSGLSettings.from_properties(properties)
    assert (settings.positional_distribution, settings.rsm_size, settings.kernel) == ("shared", 128, "original")
    assert settings.overridden(positional_distribution="per-lobe").positional_distribution == "per-lobe"
