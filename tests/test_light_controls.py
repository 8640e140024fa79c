# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender's light and object controls, against Cycles (max bounces 1), for direct light and for
each light's bounce: a light's Diffuse / Specular factors, objects' ray visibility (diffuse,
glossy, shadow), light linking and shadow linking.

Each case renders a small scene twice, control off (the baseline) and on, with our renderer and
with Cycles, and compares the mean luminance of the pass the control acts on over the *affected
pixels*: one object's pixels (Cycles' Object Index pass, eroded by a pixel so silhouettes do not
count) where that pass is not negligible in either render; for shadows, the floor pixels whose
direct light the control changes by more than 20 %. The assertions:

* Cycles' own mean there changes by more than 20 % (else the case could not tell a renderer that
  ignores the control from one that honours it);
* ours / Cycles within 5 % with the control on; where the control leaves almost nothing (Cycles'
  mean below 20 % of the baseline's: a factor 0, an invisible reflector, an unlinked receiver) a
  ratio of near-zero means says nothing, so there the difference must be within 5 % of Cycles'
  baseline mean instead (at most 5 % of the light that must vanish is left).

The scenes are built so that the baseline already agrees within a few per cent on the measured
pass (printed with -s, or all at once by ``python tests/test_light_controls.py``): direct light
is measured on direct passes (calibrated against Cycles), bounces on open scenes with nothing
between reflector and receiver (VSGL shading has no visibility, so an occluder would leak). One
exception: a diffuse floor's bounce on a diffuse wall is about 24 % dark in ours (the diffuse SG
lobe, lambda 2, is dim at grazing angles; 5-8 % even for a ceiling right above the floor), so that
pair is only used where the control must remove the bounce, which the difference rule measures
whatever the baseline; where part of a diffuse bounce must stay, the receiver is a metal wall
leaning over the floor (baseline within 1 %).

Cycles' ray visibility follows the sampled ray, not the closure: on a receiver with a diffuse and
a rough glossy closure (a rough dielectric Principled), much of its indirect glossy arrives along
rays its diffuse closure sampled and obeys diffuse visibility. The receivers here are therefore
either diffuse only (Specular IOR Level 0) or metal (glossy only), where the two agree.

What Cycles does with each control (measured in Blender 5.0.1):

* Light Diffuse / Specular factors (``Light.diffuse_factor``, ``specular_factor``) are EEVEE's:
  Cycles ignores them (its image does not change). Cycles' control for the same thing is the
  light *object's* ray visibility: ``visible_diffuse = False`` drops the light's contribution to
  every diffuse closure it is sampled by, wherever on a path (the floor's diffuse reflection of
  the light, hence its diffuse bounce, goes too), ``visible_glossy`` likewise for glossy
  closures. A factor f is therefore that exclusion made fractional, and the truth for factors
  (d, s) is, by linearity, d x (the render with the light invisible to glossy rays) + s x (the
  render with it invisible to diffuse rays). The light object's own ray visibility is tested
  too, against the plain Cycles render.
* An object invisible to diffuse (glossy) rays is missing from every other surface's indirect
  diffuse (glossy) light; camera rays still see it, lit as before.
* An object invisible to shadow rays occludes no light.
* Light linking: only a light's receivers (INCLUDE entries of its ``receiver_collection``; with
  only EXCLUDE entries, every object but those) are lit by it, so an unlinked reflector bounces
  none of its light. Shadow linking likewise picks which objects block its light
  (``blocker_collection``). ``Collection.collection_objects`` holds each object's link state in
  the order of ``Collection.objects`` (it has no string keys and no reference to the object).

Cycles renders with filter width 0.01 px (every sample at the pixel centre, as our rasteriser),
two seeds averaged; their difference is the noise estimate, which must stay below 1.5 % of the
mean. Renders are kept in memory for the module, never on disk.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import bpy
import numpy as np
import pytest

import cycles_truth
import scene_builders as sb
from vsgl_addon.renderer import FrameRenderer
from vsgl_addon.scene import extract_scene
from vsgl_addon.settings import VSGLSettings

WIDTH, HEIGHT = 64, 48
CYCLES_SAMPLES = 256
CYCLES_SEEDS = (0, 1)
SETTINGS = VSGLSettings(vsgl_count=256, rsm_size=128)
TOLERANCE = 0.05  # ours / Cycles, with the control on
MIN_CYCLES_CHANGE = 0.20  # the control must move Cycles' mean by more than this
VANISHED = 0.20  # Cycles' mean below this fraction of the baseline's: compare differences instead
MAX_NOISE = 0.015

# Object Index of each object (Cycles' pass index) for the masks.
FLOOR, WALL, BOX = 1, 2, 3
INDEX = {"floor": FLOOR, "wall": WALL, "box": BOX}

# Pass name -> Cycles' (light, colour) passes.
CYCLES_PASSES = {
    "direct_diffuse": ("DiffDir", "DiffCol"),
    "direct_specular": ("GlossDir", "GlossCol"),
    "indirect_diffuse": ("DiffInd", "DiffCol"),
    "indirect_specular": ("GlossInd", "GlossCol"),
}


def _luminance(rgb):
    return np.asarray(rgb, np.float64) @ np.array([0.2126, 0.7152, 0.0722])


def _erode(mask):
    padded = np.pad(mask, 1, constant_values=False)
    out = np.ones_like(mask)
    h, w = mask.shape
    for dy in range(3):
        for dx in range(3):
            out &= padded[dy:dy + h, dx:dx + w]
    return out


# --- Scenes -----------------------------------------------------------------------------------------


DIFFUSE_RED = dict(base_color=(0.8, 0.25, 0.1), roughness=0.5, specular_ior_level=0.0)
DIFFUSE_WHITE = dict(base_color=(0.8, 0.8, 0.8), roughness=0.5, specular_ior_level=0.0)
GOLD_METAL = dict(base_color=(0.9, 0.6, 0.3), roughness=0.3, metallic=1.0)
SILVER_METAL = dict(base_color=(0.9, 0.9, 0.9), roughness=0.3, metallic=1.0)


def _floor_and_wall(floor_material, wall_material):
    floor = sb.plane("Floor", size=4.0, material=sb.principled("FloorMaterial", **floor_material))
    wall = sb.plane("Wall", size=4.0, location=(0, 1.5, 1.5), rotation=(math.radians(90), 0, 0),
                    material=sb.principled("WallMaterial", **wall_material))
    floor.pass_index, wall.pass_index = FLOOR, WALL
    return floor, wall


def scene_diffuse_bounce():
    """A spot on a diffuse red floor next to a diffuse white wall (which the cone's edge also
    lights): the floor's diffuse bounce on the wall."""
    sb.reset()
    floor, wall = _floor_and_wall(DIFFUSE_RED, DIFFUSE_WHITE)
    spot = sb.spot_light(power=800.0, location=(0, -0.5, 3), look_at_point=(0, 0.6, 0),
                         spot_size=math.radians(60), spot_blend=0.2, name="Spot")
    sb.camera(location=(0, -4, 2), look_at_point=(0, 0.5, 0.8), resolution=(WIDTH, HEIGHT))
    return dict(floor=floor, wall=wall, light=spot)


def scene_glossy_bounce():
    """A spot on a glossy gold floor (metal, roughness 0.3) whose reflection falls on a diffuse
    white wall (which the cone's edge also lights): the floor's glossy bounce on the wall."""
    sb.reset()
    floor, wall = _floor_and_wall(GOLD_METAL, DIFFUSE_WHITE)
    spot = sb.spot_light(power=800.0, location=(0, -1.5, 2.0), look_at_point=(0, 0.5, 0),
                         spot_size=math.radians(55), spot_blend=0.2, name="Spot")
    sb.camera(location=(0, -4, 2), look_at_point=(0, 0.5, 0.8), resolution=(WIDTH, HEIGHT))
    return dict(floor=floor, wall=wall, light=spot)


def scene_glossy_receiver():
    """A spot on a diffuse red floor seen in a glossy silver wall (metal, roughness 0.3) that leans
    45 degrees over it from the floor's far edge: the floor's diffuse light in the wall's indirect
    glossy. Metal rather than diffuse: ours has a diffuse floor's bounce on a diffuse wall about a
    quarter dark (see the module doc), its reflection in a metal one within 1 %."""
    sb.reset()
    floor, wall = _floor_and_wall(DIFFUSE_RED, SILVER_METAL)
    tilt = math.radians(135)  # the wall's local +y then runs (0, cos, sin) from its lower edge
    wall.rotation_euler = (tilt, 0, 0)
    wall.location = (0, 1.5 + 2 * math.cos(tilt), 2 * math.sin(tilt))
    spot = sb.spot_light(power=800.0, location=(0, -1.5, 1.5), look_at_point=(0, 0.5, 0),
                         spot_size=math.radians(60), spot_blend=0.2, name="Spot")
    sb.camera(location=(0, -4, 2), look_at_point=(0, 0.5, 0.8), resolution=(WIDTH, HEIGHT))
    return dict(floor=floor, wall=wall, light=spot)


def scene_shadow():
    """A diffuse floor and a box lit by two spots from either side, each casting the box's shadow
    on the floor beside it; seen from above."""
    sb.reset()
    floor = sb.plane("Floor", size=5.0, material=sb.principled("FloorMaterial", **DIFFUSE_WHITE))
    box = sb.box("Box", size=(0.6, 0.6, 0.8), location=(0, 0, 0.4),
                 material=sb.principled("BoxMaterial", **DIFFUSE_RED))
    floor.pass_index, box.pass_index = FLOOR, BOX
    left = sb.spot_light(power=600.0, location=(-2.0, -0.3, 2.2), look_at_point=(0.3, 0, 0),
                         spot_size=math.radians(70), spot_blend=0.2, name="SpotLeft")
    right = sb.spot_light(power=600.0, location=(2.0, 0.3, 2.2), look_at_point=(-0.3, 0, 0),
                          spot_size=math.radians(70), spot_blend=0.2, name="SpotRight")
    sb.camera(location=(0, -3.5, 4.0), look_at_point=(0, 0, 0), resolution=(WIDTH, HEIGHT))
    return dict(floor=floor, box=box, light=left, other_light=right)


SCENES = {
    "diffuse_bounce": scene_diffuse_bounce,
    "glossy_bounce": scene_glossy_bounce,
    "glossy_receiver": scene_glossy_receiver,
    "shadow": scene_shadow,
}


# --- Controls -------------------------------------------------------------------------------------


def _linking_collection(name, objects, state):
    """A light- or shadow-linking collection holding ``objects``, each with link state ``state``."""
    collection = bpy.data.collections.new(name)
    for obj in objects:
        collection.objects.link(obj)
    # collection_objects follows collection.objects' order and cannot be looked up by name; every
    # entry gets the same state here, so the order does not matter.
    for entry in collection.collection_objects:
        entry.light_linking.link_state = state
    return collection


def _set(path, value):
    """A control that sets ``objects[key].attribute = value``, ``path`` = "key.attribute"."""
    key, attribute = path.split(".")
    return lambda objects: setattr(objects[key], attribute, value)


def _receivers(names, state):
    def apply(objects):
        objects["light"].light_linking.receiver_collection = _linking_collection(
            "Receivers", [objects[n] for n in names], state)
    return apply


def _blockers(names, state):
    def apply(objects):
        objects["light"].light_linking.blocker_collection = _linking_collection(
            "Blockers", [objects[n] for n in names], state)
    return apply


#: Control name -> what it sets in the scene's objects. A light factor (d, s) has no Cycles
#: render of its own: its truth is mixed from the "light diffuse only" / "light glossy only"
#: renders (see the module doc).
CONTROLS: dict[str, Callable] = {
    "none": lambda objects: None,
    "light glossy only": _set("light.visible_diffuse", False),
    "light diffuse only": _set("light.visible_glossy", False),
    "floor invisible to diffuse": _set("floor.visible_diffuse", False),
    "floor invisible to glossy": _set("floor.visible_glossy", False),
    "box invisible to shadow": _set("box.visible_shadow", False),
    "receivers: include wall": _receivers(["wall"], "INCLUDE"),
    "receivers: exclude floor": _receivers(["floor"], "EXCLUDE"),
    "blockers: exclude box": _blockers(["box"], "EXCLUDE"),
    "blockers: include floor": _blockers(["floor"], "INCLUDE"),
}


def _factor_control(diffuse, specular):
    def apply(objects):
        objects["light"].data.diffuse_factor = diffuse
        objects["light"].data.specular_factor = specular
    return apply


# --- Rendering ------------------------------------------------------------------------------------


@dataclass
class Frame:
    """One scene state rendered both ways: per pass name, our image and Cycles' (H, W) luminance,
    rows bottom-up; Cycles' per-seed means come from ``cycles_seeds``."""

    ours: dict[str, np.ndarray]
    cycles: dict[str, np.ndarray]
    cycles_seeds: list[dict[str, np.ndarray]]
    index: np.ndarray  # (H, W) int, Cycles' Object Index, rows bottom-up


_FRAMES: dict[tuple, Frame] = {}


def _render_cycles(scene):
    scene.view_layers[0].use_pass_object_index = True
    seeds, index = [], None
    for seed in CYCLES_SEEDS:
        passes = cycles_truth.render_cycles(scene, samples=CYCLES_SAMPLES, max_bounces=1, seed=seed,
                                            filter_width=0.01)
        seeds.append({name: _luminance(passes[a] * passes[b])[::-1] for name, (a, b) in CYCLES_PASSES.items()})
        index = np.rint(passes["Object Index"][::-1]).astype(int)
    mean = {name: np.mean([s[name] for s in seeds], axis=0) for name in CYCLES_PASSES}
    return mean, seeds, index


def _render_ours(scene):
    description = extract_scene(sb.depsgraph(scene))
    renderer = FrameRenderer()
    try:
        images = renderer.render(description, SETTINGS, WIDTH, HEIGHT)
    finally:
        renderer.free()
    return {name: _luminance(getattr(images, name)) for name in CYCLES_PASSES}


def render(scene_name, control_name, factors=None):
    """The Frame of ``SCENES[scene_name]`` with ``CONTROLS[control_name]`` applied, or with the light's
    (diffuse, specular) ``factors`` (ours renders the factors; Cycles' truth is mixed)."""
    key = (scene_name, control_name, factors)
    if key in _FRAMES:
        return _FRAMES[key]
    if factors is not None:
        diffuse, specular = factors
        only_diffuse = render(scene_name, "light diffuse only")
        only_glossy = render(scene_name, "light glossy only")
        objects = SCENES[scene_name]()
        _factor_control(diffuse, specular)(objects)
        ours = _render_ours(bpy.context.scene)
        mix = lambda a, b: {n: diffuse * a[n] + specular * b[n] for n in CYCLES_PASSES}  # noqa: E731
        frame = Frame(ours, mix(only_diffuse.cycles, only_glossy.cycles),
                      [mix(a, b) for a, b in zip(only_diffuse.cycles_seeds, only_glossy.cycles_seeds)],
                      only_diffuse.index)
    else:
        objects = SCENES[scene_name]()
        CONTROLS[control_name](objects)
        scene = bpy.context.scene
        ours = _render_ours(scene)
        cycles, seeds, index = _render_cycles(scene)
        frame = Frame(ours, cycles, seeds, index)
    _FRAMES[key] = frame
    return frame


# --- Comparison -----------------------------------------------------------------------------------


def object_mask(frame, name):
    return _erode(frame.index == INDEX[name])


def significant(mask, *images, fraction=0.01):
    """``mask`` where any of ``images`` reaches ``fraction`` of the largest of their 99th
    percentiles inside ``mask`` (the far tails of a lobe or a cone's edge, where a relative error
    of tiny values means nothing, are left out)."""
    if not mask.any():
        return mask
    level = fraction * max(np.percentile(image[mask], 99) for image in images)
    return mask & np.any([image >= level for image in images], axis=0) & (level > 0)


@dataclass
class Comparison:
    label: str
    pass_name: str
    pixels: int
    ours_base: float
    cycles_base: float
    ours: float
    cycles: float
    noise: float  # half the two seeds' difference of the mean, relative to the larger Cycles mean

    @property
    def base_ratio(self):
        return self.ours_base / self.cycles_base if self.cycles_base > 0 else math.nan

    @property
    def ratio(self):
        return self.ours / self.cycles if self.cycles > 0 else math.nan

    @property
    def cycles_change(self):
        return abs(self.cycles - self.cycles_base) / max(self.cycles, self.cycles_base)

    @property
    def vanished(self):
        return self.cycles < VANISHED * self.cycles_base

    @property
    def error(self):
        """ours against Cycles with the control on: |ratio - 1|, or the difference relative to the
        baseline where the light vanished."""
        if self.vanished:
            return abs(self.ours - self.cycles) / self.cycles_base
        return abs(self.ratio - 1.0)

    def line(self):
        kind = "diff/base" if self.vanished else "ratio-1"
        return (f"{self.label:58s} {self.pass_name:17s} {self.pixels:5d} px | baseline ours/Cycles "
                f"{self.base_ratio:6.3f} | control ours/Cycles {self.ratio:6.3f} (ours {self.ours:.4g}, "
                f"Cycles {self.cycles:.4g}) | Cycles change {self.cycles_change:5.1%} | error ({kind}) "
                f"{self.error:6.3f} | noise {self.noise:.4f}")


def compare(label, base, frame, pass_name, mask):
    t0, t = base.cycles[pass_name], frame.cycles[pass_name]
    seed_means = [s[pass_name][mask].mean() for s in frame.cycles_seeds]
    scale = max(t0[mask].mean(), t[mask].mean())
    result = Comparison(label, pass_name, int(mask.sum()), float(base.ours[pass_name][mask].mean()),
                        float(t0[mask].mean()), float(frame.ours[pass_name][mask].mean()),
                        float(t[mask].mean()), float(abs(seed_means[0] - seed_means[1]) / 2 / scale))
    print(result.line())
    return result


def problems(result, expect_change=True):
    """What is wrong with ``result`` by the module doc's rules; ``expect_change=False`` for a pass
    the control must leave alone (Cycles must not change and ours must still agree), None for a
    pass where only the agreement is checked."""
    found = []
    if result.pixels < 40:
        found.append("too few pixels")
    if result.noise >= MAX_NOISE:
        found.append("Cycles too noisy")
    if expect_change is True and result.cycles_change <= MIN_CYCLES_CHANGE:
        found.append("the control does not change Cycles")
    if expect_change is False and result.cycles_change >= 0.02:
        found.append("Cycles changed where the control should change nothing")
    if not result.error <= TOLERANCE:
        found.append(f"ours is off by {result.error:.3f} > {TOLERANCE}")
    return [f"{', '.join(found)}: {result.line()}"] if found else []


def check(changed=(), kept=(), agree=()):
    """Assert once, listing every failing comparison: ``changed`` passes the control must change,
    ``kept`` ones it must leave alone, ``agree`` ones where only ours against Cycles counts."""
    found = [line for result in changed for line in problems(result)]
    found += [line for result in kept for line in problems(result, expect_change=False)]
    found += [line for result in agree for line in problems(result, expect_change=None)]
    assert not found, "\n".join(found)


def measure(scene_name, control, label, measurements, factors=None):
    """Render the baseline and the controlled scene; compare each (pass, object) of
    ``measurements``; returns the comparisons."""
    base = render(scene_name, "none")
    frame = render(scene_name, control, factors)
    results = []
    for pass_name, object_name in measurements:
        mask = significant(object_mask(base, object_name), base.cycles[pass_name], frame.cycles[pass_name])
        results.append(compare(f"{scene_name}: {label} on the {object_name}", base, frame, pass_name, mask))
    return results


# --- Light factors --------------------------------------------------------------------------------


def _check_mixed_truth(scene_name, measurements):
    """The mixed truth at factors (1, 1) is Cycles' baseline: every light sample reaches a closure
    that is either diffuse or glossy, so the two exclusions split the light without gap or overlap."""
    base = render(scene_name, "none")
    mixed = render(scene_name, None, factors=(1.0, 1.0))
    for pass_name, object_name in measurements:
        mask = significant(object_mask(base, object_name), base.cycles[pass_name])
        a, b = mixed.cycles[pass_name][mask].mean(), base.cycles[pass_name][mask].mean()
        assert abs(a - b) <= 0.01 * b, (scene_name, pass_name, object_name, a, b)


@pytest.mark.gpu
@pytest.mark.parametrize("factor", [0.0, 0.5])
def test_light_diffuse_factor_scales_direct_diffuse_and_the_diffuse_bounce(factor):
    """Diffuse factor f: the diffuse floor's direct light and its bounce, seen in the metal wall,
    are f times the baseline's; the metal wall's direct (glossy) light stays.

    The bounce is compared as a change against the baseline (ours control/baseline against Cycles'),
    not in absolute terms: since the VSGLs' diffuse lobes are normalised over the hemisphere
    (reference/sg.py DIFFUSE_HEMISPHERE_SCALE) the floor's bounce on this wall leaning over it is
    15 % brighter than Cycles' in the baseline already (the SG is 15.6 % above the cosine at the
    normal; docs/accuracy.md), which says nothing about the control."""
    measurements = [("direct_diffuse", "floor"), ("indirect_specular", "wall"), ("direct_specular", "wall")]
    _check_mixed_truth("glossy_receiver", measurements)
    direct, bounce, kept = measure("glossy_receiver", None, f"light diffuse factor {factor:g}", measurements,
                                   factors=(factor, 1.0))
    check([direct], kept=[kept])  # kept: the wall's own glossy reflection of the light
    if bounce.vanished:
        check([bounce])
    else:
        change = abs(bounce.ratio / bounce.base_ratio - 1.0)
        assert bounce.cycles_change > MIN_CYCLES_CHANGE, bounce.line()
        assert change <= TOLERANCE, f"the bounce's change is off by {change:.3f}: {bounce.line()}"


@pytest.mark.gpu
@pytest.mark.parametrize("factor", [0.0, 0.5])
def test_light_specular_factor_scales_direct_glossy_and_the_glossy_bounce(factor):
    """Specular factor f on a metal floor: its direct glossy light and its glossy bounce on the
    white wall (the wall's indirect diffuse) are f times the baseline's; the wall's direct
    (diffuse) light stays."""
    measurements = [("direct_specular", "floor"), ("indirect_diffuse", "wall"), ("direct_diffuse", "wall")]
    _check_mixed_truth("glossy_bounce", measurements)
    *changed, kept = measure("glossy_bounce", None, f"light specular factor {factor:g}", measurements,
                             factors=(1.0, factor))
    check(changed, kept=[kept])


@pytest.mark.gpu
@pytest.mark.parametrize("scene_name, control, measurements", [
    ("diffuse_bounce", "light glossy only", [("direct_diffuse", "floor"), ("indirect_diffuse", "wall")]),
    ("glossy_bounce", "light diffuse only", [("direct_specular", "floor"), ("indirect_diffuse", "wall")]),
], ids=["light-invisible-to-diffuse", "light-invisible-to-glossy"])
def test_light_ray_visibility_drops_its_diffuse_or_glossy_light_and_bounce(scene_name, control, measurements):
    """Cycles' own per-light control: the light object invisible to diffuse (glossy) rays lights no
    diffuse (glossy) closure, so that part of its direct light and of its bounce goes."""
    check(measure(scene_name, control, control, measurements))


# --- Object ray visibility ------------------------------------------------------------------------


@pytest.mark.gpu
def test_reflector_invisible_to_diffuse_rays_gives_no_diffuse_bounce():
    """The floor invisible to diffuse rays: the wall's indirect diffuse goes; the floor itself, seen
    by the camera, keeps its direct light."""
    gone, kept = measure("diffuse_bounce", "floor invisible to diffuse", "floor invisible to diffuse",
                         [("indirect_diffuse", "wall"), ("direct_diffuse", "floor")])
    check([gone], kept=[kept])


@pytest.mark.gpu
def test_reflector_invisible_to_glossy_rays_gives_no_glossy_bounce():
    """The floor invisible to glossy rays: the metal wall's indirect glossy (its reflection of the
    lit floor) goes; the floor keeps its direct light."""
    gone, kept = measure("glossy_receiver", "floor invisible to glossy", "floor invisible to glossy",
                         [("indirect_specular", "wall"), ("direct_diffuse", "floor")])
    check([gone], kept=[kept])


def _changed_floor(base, frame):
    """Floor pixels whose direct light differs by more than 20 % between the two frames."""
    t0, t = base.cycles["direct_diffuse"], frame.cycles["direct_diffuse"]
    return object_mask(base, "floor") & (np.abs(t - t0) > 0.2 * np.maximum(t, t0))


def _shadow_case(control):
    """(baseline, frame, changed pixels, comparisons): where the floor's direct light changes, and
    the whole floor (the shadows the control leaves must stay)."""
    base = render("shadow", "none")
    frame = render("shadow", control)
    changed = _changed_floor(base, frame)
    where = compare(f"shadow: {control}, where the floor's light changes", base, frame, "direct_diffuse", changed)
    floor = object_mask(base, "floor")
    whole = significant(floor, base.cycles["direct_diffuse"], frame.cycles["direct_diffuse"])
    everywhere = compare(f"shadow: {control}, the whole floor", base, frame, "direct_diffuse", whole)
    return base, frame, changed, where, everywhere


@pytest.mark.gpu
def test_object_invisible_to_shadow_rays_occludes_nothing():
    """The box invisible to shadow rays: the floor is lit where both spots' shadows of it were."""
    _, _, _, where, everywhere = _shadow_case("box invisible to shadow")
    check([where], agree=[everywhere])


# --- Light and shadow linking ---------------------------------------------------------------------


@pytest.mark.gpu
@pytest.mark.parametrize("control", ["receivers: include wall", "receivers: exclude floor"])
def test_light_linking_unlinked_reflector_is_unlit_and_bounces_nothing(control):
    """The spot lights the wall only: the floor gets no direct light from it, hence bounces none on
    the wall; the wall's own direct light stays."""
    floor_direct, bounce, wall_direct = measure(
        "diffuse_bounce", control, f"light linking ({control})",
        [("direct_diffuse", "floor"), ("indirect_diffuse", "wall"), ("direct_diffuse", "wall")])
    check([floor_direct, bounce], kept=[wall_direct])


@pytest.mark.gpu
@pytest.mark.parametrize("control", ["blockers: exclude box", "blockers: include floor"])
def test_shadow_linking_unlinked_blocker_casts_no_shadow_from_that_light(control):
    """The left spot's blockers leave the box out: the floor is lit where the left spot's shadow of
    the box was; the right spot's shadow stays."""
    base, frame, changed, where, everywhere = _shadow_case(control)
    # The right spot's shadow: where the floor lights up once the box blocks nothing, but not with
    # this control. It must stay, in Cycles (it is most of the box's shadows) and in ours; its edge
    # pixels are left out (a hard shadow edge falls inside a pixel, our RSM places it within about
    # a texel).
    right = _erode(_changed_floor(base, render("shadow", "box invisible to shadow")) & ~changed)
    assert right.sum() > changed.sum() / 2, (int(right.sum()), int(changed.sum()))
    kept = compare(f"shadow: {control}, the right spot's shadow", base, frame, "direct_diffuse", right)
    check([where], kept=[kept], agree=[everywhere])


# --- Baselines --------------------------------------------------------------------------------------


#: (scene, pass, object) measured by the tests above, for the baseline report.
BASELINES = [
    ("diffuse_bounce", "direct_diffuse", "floor"), ("diffuse_bounce", "indirect_diffuse", "wall"),
    ("diffuse_bounce", "direct_diffuse", "wall"), ("glossy_bounce", "direct_specular", "floor"),
    ("glossy_bounce", "indirect_diffuse", "wall"), ("glossy_bounce", "direct_diffuse", "wall"),
    ("glossy_receiver", "indirect_specular", "wall"),
    ("glossy_receiver", "direct_diffuse", "floor"), ("glossy_receiver", "direct_specular", "wall"),
    ("shadow", "direct_diffuse", "floor"),
]


def report_baselines():
    """Print ours / Cycles of every measured pass with every control off."""
    for scene_name, pass_name, object_name in BASELINES:
        base = render(scene_name, "none")
        mask = significant(object_mask(base, object_name), base.cycles[pass_name])
        compare(f"{scene_name}: baseline on the {object_name}", base, base, pass_name, mask)


if __name__ == "__main__":
    from vsgl_addon.gpu_context import ensure_gpu_context

    ensure_gpu_context()
    report_baselines()
