# SPDX-License-Identifier: GPL-3.0-or-later
"""The frame plan: what one frame of a scene needs, decided before any GPU work, and why.

bpy-free and GPU-free: from a SceneDescription and VSGLSettings, :func:`plan_frame` decides

* which lights get RSM views (a light whose views see no triangle it lights gets none; its views
  also give the direct light's shadows, so every light that reaches geometry keeps them) and at
  what size: a light expected to get the fraction s of the frame's VSGLs (from a CPU estimate of
  its bounce power) gets the side √s × the settings' size (a power of two, at least MIN_RSM_SIZE),
  so its texels per VSGL stay what the settings give one light alone (a lone light keeps the
  settings' size; on llvmpipe a 64² view costs a fifth of a 128² one);
* how the VSGL count N is spent: N is the frame's budget, not each light's. Once the RSM views
  are rendered, :meth:`FramePlan.allocate` shares N among all views of all lights in proportion to
  their bounce power lum(Σ Φ(Rd + Rs)) (the RSM total, the integral VSGL generation samples from,
  000 Eq. 5), so every VSGL carries about the same power whichever light it came from, as 000's N
  VSGLs of one light do. Each VSGL set of a view still sums to that view's RSM total (000 Eq. 5),
  so the estimate of each light's bounce stays what it was; only views whose summed power is
  negligible (at most NEGLIGIBLE_BOUNCE of the frame's bounce power, the dimmest first) get no
  VSGL, and the plan reports the fraction dropped;
* which passes run, from the cells of ../shared/reference/light-paths.md the scene fills: VSGL
  visibility (000 §5), MRP-ASG (001: a lit rectangle proxy and a glossy receiver it can serve),
  the glossy receivers' second VSGL set, the VPL caustics pass (004: a lit sharp reflector). In
  Auto and Budget quality modes (WEIGHING_MODES) the VPL pass and MRP-ASG must also be worth their
  cost: each runs when the share of the bounce its cell carries (CPU estimate, :func:`cell_powers`)
  is at least AUTO_SHARE_PER_COST times the fraction of the frame time the built-in cost model
  (budget.py) predicts it adds, the extra VSGL sets it needs included (:func:`weigh_passes`); a pass
  left out hands its cell to the VSGLs, as switching it off does.

Each decision carries a one-line reason; :meth:`FramePlan.summary_lines` are what the statistics
panel and the command line print, :meth:`FramePlan.to_dict` what the JSON report holds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .light_paths import needs_glossy_vpls
from .proxies import ProxyCache, lit_proxies, material_alpha, material_f0
from .reference.lights import light_intensity
from .reference.vsgl import LUMINANCE_WEIGHTS
from .settings import VSGLSettings
from .views import MIN_RSM_SIZE, light_view_specs, rsm_size_for_share, scene_bounds, view_sees_triangles

#: At most this fraction of the frame's bounce power (the dimmest views first) may go without
#: VSGLs: its light is still drawn directly, its bounce is dropped (a bias of at most this much).
NEGLIGIBLE_BOUNCE = 1e-3


#: GGX α of the receivers MRP-ASG shades (both ends included); rougher ones take the proxies' light
#: from the VSGLs. Measured: the receiver's SG (001 Eqs. 6, 8) fits a rough GGX NDF poorly (α ≥ 0.5
#: worse than VSGLs in docs/accuracy.md's error table; on the caustic panel's α 0.64 walls MRP-ASG
#: doubled the specular error, benchmarks/results/mrp_asg_suite.md). No lower bound: the table's
#: sharp receiver (α 0.05) is worse, but the suite's mirror-like floors (α 0.02) gain the most.
RECEIVER_ALPHA_RANGE = (0.0, 0.35)

#: Auto quality mode: the VPL pass or MRP-ASG runs when the share s of the frame's bounce power its
#: cell carries (cell_powers / the lights' bounce estimates) is at least this times the fraction f of
#: the frame time it adds (the built-in cost model: its own steps and the VSGL sets it splits off,
#: the glossy receivers' at GLOSSY_SET_FACTOR x N). s / f on the suite's scenes (each at its saved
#: resolution): below it glossy_floor_object's MRP-ASG 0.028 and VPL pass 0.026, sun_courtyard's
#: 0.003 and 0.003, closed_room's VPL pass 0.0001 (a scene's passes together took at most 8.5 % off
#: its relative RMSE for 2-9x the frame time, benchmarks/results/tradeoff_suite.md); above it the VPL
#: pass and MRP-ASG of caustic_panel, polished_metal_floor and occluded_reflector (0.32-1.0), the
#: demo's VPL pass 0.43 and, once that runs, the demo's MRP-ASG 0.059 (4.2 % of the bounce for a
#: third VSGL set at 2 N, +71 %; it halves the demo's error, 0.52 -> 0.27). 0.04 is the geometric
#: mean of the closest pair (0.028, 0.059); with the glossy set at N that pair was (0.056, 0.117) and
#: the threshold 0.08. What the cell's receivers make of its light is not weighed: the demo's MRP-ASG
#: is worth more than its 4 % suggests.
AUTO_SHARE_PER_COST = 0.04
#: The frame size Auto predicts its costs at when the scene has no camera (the ratios it weighs
#: hardly depend on it: the passes' costs are nearly all per pixel).
AUTO_FRAME_SIZE = (480, 270)
#: The passes Auto weighs (the others cost little or carry every path), each with its settings toggle.
AUTO_TOGGLES = {"vpl_pass": "caustics", "mrp_asg": "glossy_reflectors"}
AUTO_OPTIONAL = tuple(AUTO_TOGGLES)
#: The quality modes whose plan weighs AUTO_OPTIONAL: Auto, and Budget, which spends its time on N,
#: RSM size, δ, interleave and resolution for the passes Auto would run (a pass not worth its time at
#: the settings' N is not worth it on a budget either; FramePlan.pinned turns its toggle off in the
#: settings the budget chooses).
WEIGHING_MODES = ("auto", "budget")
#: The glossy receivers' VSGL set (with MRP-ASG: every reflector's light but the proxies' specular
#: flux, for the specular lobes MRP-ASG serves, GGX α up to 0.35) gets this many times N. Its
#: receivers are sharp and resolve each VSGL's position (a near-mirror floor shows them one by one),
#: so that set's sampling bounds the specular error (benchmarks/results/glossy_set_sampling.md,
#: seeds 0-2): twice its VSGLs take the polished metal floor's specular relative RMSE
#: 3.83 / 3.76 / 3.56 -> 2.47 / 2.53 / 2.51 for 1.11x the frame and the demo's 2.38 / 2.74 / 2.59 ->
#: 2.05 / 2.19 / 2.11 for 1.19x; four times gain little more (2.2-2.4, 1.9-2.0) for 1.5x, and smaller
#: kernels instead (K x 0.5) lose the occluded reflector 8 %.
GLOSSY_SET_FACTOR = 2

#: The plan's decisions, in the order the summary prints them: key -> label.
DECISIONS = {
    "vsgls": "VSGLs",
    "visibility": "Visibility",
    "mrp_asg": "MRP-ASG",
    "glossy_set": "Glossy VSGL set",
    "whole_set": "Whole VSGL set",
    "vpl_pass": "VPL pass",
    "view_pdf": "View PDF",
}

#: Barycentric points per triangle of the CPU bounce estimate (centroid and the three points halfway
#: from it to the corners): enough to tell a lit triangle's order of magnitude, cheap for 10⁵ triangles.
_ESTIMATE_BARYCENTRICS = np.array([[1 / 3, 1 / 3, 1 / 3], [2 / 3, 1 / 6, 1 / 6],
                                   [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])


@dataclass(frozen=True)
class Decision:
    """Whether one part of the frame runs, and why (one line)."""

    run: bool
    reason: str


@dataclass
class LightPlan:
    """One light's part of the frame: its RSM views (culled), their size, the CPU estimate of its
    bounce power, and, once allocated, its VSGLs per receiver-lobe set and the RSM's measured power."""

    index: int
    name: str
    rsm_views: int
    rsm_size: int
    bounce_estimate: float  # lum W, CPU (no occlusion), before any GPU work
    reason: str
    size_reason: str = ""  # why rsm_size (rsm_size_for_share), once the plan sets it
    # The RSMViewSpecs of its rsm_views views (light_reach found them; the RSM pass renders them)
    view_specs: list = field(default_factory=list, repr=False)
    rsm_power: dict = field(default_factory=dict)  # set -> lum Σ Φ(Rd + Rs) over its views, W
    # set -> function reading rsm_power back from the GPU when the statistics or the report ask
    # (the allocation did not need it: FramePlan.allocation_reads_powers); None once unreadable.
    power_readers: dict = field(default_factory=dict, repr=False)
    vsgls: dict = field(default_factory=dict)  # set -> VSGLs (sum over views)
    view_vsgls: dict = field(default_factory=dict)  # set -> VSGLs per view

    @property
    def gets_rsm(self) -> bool:
        return self.rsm_views > 0

    def measured_power(self, receiver_set: str, default: float | None = 0.0) -> float | None:
        """rsm_power[receiver_set] (``default`` without one), read back now if it was deferred;
        None when its tables were freed unread."""
        if receiver_set in self.power_readers:
            powers = self.power_readers[receiver_set]()
            if powers is None:
                return None
            del self.power_readers[receiver_set]
            self.rsm_power[receiver_set] = float(np.sum(powers))
        return self.rsm_power.get(receiver_set, default)

    def measured_powers(self) -> dict:
        return {name: power for name in [*self.rsm_power, *self.power_readers]
                if (power := self.measured_power(name, None)) is not None}


@dataclass(frozen=True)
class DeferredPowers:
    """A light's per-view powers not measured before the allocation: ``views`` views, ``read()``
    the powers (or None) when asked."""

    views: int
    read: object


@dataclass
class FramePlan:
    vsgl_budget: int  # N: VSGLs per receiver-lobe set for the whole frame (two-vsgl: unused)
    kernel: str
    lights: list
    decisions: dict  # DECISIONS key -> Decision
    proxies: list = field(default_factory=list)  # (RectangleProxy, lit-by mask) MRP-ASG keeps
    # set -> fraction of that set's RSM bounce power that got no VSGL (NEGLIGIBLE_BOUNCE at most,
    # more only where N is smaller than the lights with bounce power)
    dropped_bounce: dict = field(default_factory=dict)
    # Budget mode (budget.BudgetChoice): the settings the target frame time gave, predicted and
    # measured time; None in Manual mode.
    budget: object = None
    # Auto mode: pass -> (its cell's share of the bounce, predicted seconds it adds, predicted frame
    # seconds it adds them to) for the optional passes it weighed (weigh_passes).
    weighed: dict = field(default_factory=dict)

    def runs(self, name: str) -> bool:
        return self.decisions[name].run

    def pinned(self, settings: VSGLSettings) -> VSGLSettings:
        """``settings`` in Manual mode with the toggles of the passes this plan weighed and left out
        turned off: a plan of them runs this plan's passes whatever N they carry (Budget's chosen
        settings: a plan at another N would weigh the passes at another frame time)."""
        left_out = [name for name in self.weighed if not self.runs(name)]
        return settings.overridden(quality_mode="manual", **{AUTO_TOGGLES[name]: False for name in left_out})

    @property
    def receiver_sets(self) -> tuple[str, ...]:
        """The VSGL sets the frame generates (scene_description.RECEIVER_LOBES names)."""
        if not self.runs("glossy_set"):
            return ("all",)
        # The third is every reflector's light, for the receivers MRP-ASG leaves when the first no
        # longer holds it (the VPL split): renderer.SceneLights.whole_vsgls.
        return ("diffuse", "glossy", "all") if self.runs("whole_set") else ("diffuse", "glossy")

    def rsm_lights(self) -> list[int]:
        return [light.index for light in self.lights if light.gets_rsm]

    def allocation_reads_powers(self, view_counts: dict) -> bool:
        """Whether sharing one set's VSGLs among the views (``view_counts``: light index -> its
        views) needs their measured powers, a read-back before the kernels run: not with 003's two
        VSGLs per view, nor with one view in all, which allocate_vsgls gives all N (a view without
        power then gets VSGLs of zero power, which light nothing)."""
        return self.kernel != "two-vsgl" and sum(view_counts.values()) > 1

    def allocate(self, view_powers: dict, receiver_set: str = "all") -> dict:
        """light index -> VSGLs per view (int64 array) for one VSGL set, from each view's measured
        bounce power lum(Σ Φ(Rd + Rs)) (``view_powers``: light index -> per-view powers, or
        DeferredPowers where allocation_reads_powers is False); recorded in the plan. two-vsgl:
        two per view (003; N unused)."""
        deferred = {index: powers for index, powers in view_powers.items() if isinstance(powers, DeferredPowers)}
        if deferred and self.allocation_reads_powers({i: p.views for i, p in deferred.items()}
                                                     | {i: len(p) for i, p in view_powers.items() if i not in deferred}):
            raise ValueError("these views' shares depend on their powers: measure them first")
        if self.kernel == "two-vsgl":
            counts = {index: np.full(powers.views if index in deferred else len(powers), 2, np.int64)
                      for index, powers in view_powers.items()}
            dropped = 0.0
        else:
            # The one view's share is N whatever power it has; its dropped fraction is 0 either way.
            counts, dropped = allocate_vsgls(self.set_budget(receiver_set), {
                index: np.ones(deferred[index].views) if index in deferred else powers
                for index, powers in view_powers.items()})
        by_index = {light.index: light for light in self.lights}
        for index, powers in view_powers.items():
            light = by_index[index]
            if index in deferred:
                light.rsm_power.pop(receiver_set, None)
                light.power_readers[receiver_set] = powers.read
            else:
                light.power_readers.pop(receiver_set, None)
                light.rsm_power[receiver_set] = float(np.sum(powers))
            light.view_vsgls[receiver_set] = [int(c) for c in counts[index]]
            light.vsgls[receiver_set] = int(np.sum(counts[index]))
        self.dropped_bounce[receiver_set] = dropped
        return counts

    def set_budget(self, receiver_set: str) -> int:
        """The VSGLs one set shares among the views: N, and GLOSSY_SET_FACTOR × N for the glossy
        receivers' set when MRP-ASG runs (the set of the receivers it serves; without MRP-ASG a
        "glossy" set, the VPL split's, lights every receiver's specular lobe and keeps N)."""
        return self.vsgl_budget * (GLOSSY_SET_FACTOR if self.glossy_set_widened(receiver_set) else 1)

    def glossy_set_widened(self, receiver_set: str = "glossy") -> bool:
        """Whether ``receiver_set`` gets GLOSSY_SET_FACTOR × N (set_budget)."""
        return receiver_set == "glossy" and self.runs("mrp_asg")

    def total_vsgls(self, receiver_set: str | None = None) -> int:
        sets = self.receiver_sets if receiver_set is None else (receiver_set,)
        return sum(light.vsgls.get(name, 0) for light in self.lights for name in sets)

    def summary_lines(self) -> list[str]:
        """One line per decision, then one per light: what the frame ran and why."""
        lines = [f"{DECISIONS[name]}: {'on' if decision.run else 'off'} — {decision.reason}"
                 for name, decision in self.decisions.items()]
        lines += [self.light_line(light) for light in self.lights]
        return lines if self.budget is None else [self.budget.line(), *lines]

    def light_line(self, light: LightPlan) -> str:
        if not light.gets_rsm:
            return f"Light {light.name}: no RSM, no VSGL — {light.reason}"
        sets = [name for name in self.receiver_sets if name in light.vsgls]
        counts = ", ".join(f"{light.vsgls[name]} {'VSGLs' if len(sets) == 1 else name}" for name in sets)
        share = ""
        if sets:
            powers = [other.measured_power(sets[0]) for other in self.lights]
            total = sum(power for power in powers if power is not None)
            if total > 0.0 and None not in powers:
                share = f", {100.0 * light.measured_power(sets[0]) / total:.1f} % of the bounce"
        views = f"{light.rsm_views} RSM view{'s' if light.rsm_views != 1 else ''} {light.rsm_size}²"
        size = f"; {light.size_reason}" if light.size_reason else ""
        return f"Light {light.name}: {views}, {counts or 'VSGLs not allocated yet'}{share} — {light.reason}{size}"

    def to_dict(self) -> dict:
        """The JSON report's ``plan``."""
        return {
            "vsgl_budget": self.vsgl_budget,
            "kernel": self.kernel,
            "receiver_sets": list(self.receiver_sets),
            "vsgls": {name: self.total_vsgls(name) for name in self.receiver_sets},
            "dropped_bounce_fraction": dict(self.dropped_bounce),
            "decisions": {name: {"run": d.run, "reason": d.reason} for name, d in self.decisions.items()},
            "lights": [{"index": light.index, "name": light.name, "rsm_views": light.rsm_views,
                        "rsm_size": light.rsm_size, "size_reason": light.size_reason,
                        "bounce_estimate": light.bounce_estimate,
                        "rsm_power": light.measured_powers(), "vsgls": dict(light.vsgls),
                        "view_vsgls": dict(light.view_vsgls), "reason": light.reason}
                       for light in self.lights],
            "proxies": [{"object": int(proxy.object_index), "area": float(proxy.area),
                         "alpha": float(proxy.alpha), "lit_by": [int(i) for i in np.flatnonzero(mask)]}
                        for proxy, mask in self.proxies],
            "budget": None if self.budget is None else self.budget.to_dict(),
            "auto_weighed": {name: {"share": share, "added_ms": added * 1e3, "frame_ms": base * 1e3}
                             for name, (share, added, base) in self.weighed.items()},
            "summary": self.summary_lines(),
        }


def allocate_vsgls(budget: int, view_powers: dict) -> tuple[dict, float]:
    """Share ``budget`` VSGLs among every view of every light in proportion to its power.

    ``view_powers``: light index -> per-view bounce powers (≥ 0). Returns (light index -> int64
    counts per view, fraction of the total power left without VSGLs). Rules: the sum is at most
    ``budget`` (exactly ``budget`` when any view has power); views with no power get none; the
    dimmest views whose summed power is at most NEGLIGIBLE_BOUNCE of the total get none; every
    other view gets at least one while the budget allows (when it does not, each light's brightest
    view comes first, brightest lights first); above that one, counts follow the power (the views
    held at one are taken out and the rest shared again, then largest remainders).
    """
    keys = [(index, view) for index, powers in view_powers.items() for view in range(len(powers))]
    powers = np.array([max(float(view_powers[i][v]), 0.0) for i, v in keys], np.float64)
    powers = np.where(np.isfinite(powers), powers, 0.0)
    counts = np.zeros(len(keys), np.int64)
    total = powers.sum()

    def result():
        by_light = {i: counts[[k for k, key in enumerate(keys) if key[0] == i]] for i in view_powers}
        return by_light, (float(powers[counts == 0].sum() / total) if total > 0.0 else 0.0)

    if total <= 0.0 or budget <= 0:
        return result()
    kept = powers > 0.0
    order = np.argsort(powers, kind="stable")
    negligible = np.cumsum(powers[order]) <= NEGLIGIBLE_BOUNCE * total
    kept[order[negligible]] = False
    if kept.sum() > budget:
        # Not one VSGL each: each light's brightest view first (brightest lights first), then the rest.
        brightest = {}
        for k in np.flatnonzero(kept):
            light = keys[k][0]
            if light not in brightest or powers[k] > powers[brightest[light]]:
                brightest[light] = k
        firsts = sorted(brightest.values(), key=lambda k: -powers[k])
        others = sorted(set(np.flatnonzero(kept)) - set(firsts), key=lambda k: -powers[k])
        kept[:] = False
        kept[(firsts + others)[:budget]] = True
    floor = np.zeros(len(keys), bool)  # views held at one VSGL
    while True:
        free = kept & ~floor
        remaining = budget - int(floor.sum())
        quota = np.where(free, remaining * powers / max(powers[free].sum(), 1e-300), 0.0)
        below = free & (quota < 1.0)
        if not below.any():
            break
        floor |= below
    counts[floor] = 1
    free = kept & ~floor
    if free.any():
        counts[free] = share_counts(budget - int(floor.sum()), powers[free])
    return result()


def share_counts(count: int, powers) -> np.ndarray:
    """Split ``count`` in proportion to ``powers`` (largest remainders, sums to ``count``); all
    without power: none get any."""
    powers = np.maximum(np.asarray(powers, np.float64), 0.0)
    total = powers.sum()
    if not np.isfinite(total) or total <= 0.0:
        return np.zeros(len(powers), np.int64)
    quota = count * powers / total
    counts = np.floor(quota).astype(np.int64)
    order = np.argsort(-(quota - counts), kind="stable")
    counts[order[: count - counts.sum()]] += 1
    return counts


# --- What the scene holds (CPU, no occlusion) -----------------------------------------------------


def _receives(scene, light) -> np.ndarray:
    """(T,) bool: the triangles whose object receives ``light`` (light linking). Ray visibility is
    not asked: an object hidden from diffuse and glossy rays still takes the light's direct light
    and shadows, which need the RSM views (the RSM itself leaves out its bounce)."""
    objects = scene.geometry.object_index
    if light.receivers is None:
        return np.ones(len(objects), bool)
    return np.asarray(light.receivers, bool)[objects] if len(objects) else np.zeros(0, bool)


def light_reach(scene, light, bounds=None, seen=None) -> tuple[int, np.ndarray]:
    """(RSM views that see a triangle, (T,) bool triangles inside some such view that can bounce the
    light to a receiver). Conservative: a triangle not entirely outside one of a view's clip planes
    counts, occlusion is not tested. ``seen``: a list that receives those views' RSMViewSpecs."""
    positions = np.asarray(scene.geometry.positions, np.float64)
    bounds = scene_bounds(scene) if bounds is None else bounds
    reached = np.zeros(len(positions), bool)
    views = 0
    if bounds is None:
        return 0, reached
    receives = _receives(scene, light)
    for spec in light_view_specs(scene, light, bounds):
        if not view_sees_triangles(spec, positions, bounds):
            continue
        views += 1
        if seen is not None:
            seen.append(spec)
        clip = np.c_[positions.reshape(-1, 3), np.ones(positions.shape[0] * 3)] @ spec.view_projection.T
        clip = clip.reshape(-1, 3, 4)
        w = clip[..., 3]
        outside = np.zeros(len(positions), bool)
        for axis in range(3):
            outside |= np.all(clip[..., axis] > w, axis=-1) | np.all(clip[..., axis] < -w, axis=-1)
        reached |= ~outside
    return views, reached & receives


def _material_albedo(material) -> float:
    """lum of the reflectance a texel's Φ(Rd + Rs) carries, roughly: the diffuse base colour's
    (1 − metallic) share plus the Schlick F0 (a base colour image counts with its mean)."""
    base = np.asarray(material.base_color, np.float64)
    if material.base_color_image is not None:
        base = np.asarray(material.base_color_image, np.float64)[..., :3].reshape(-1, 3).mean(axis=0)
    metallic = float(np.clip(material.metallic, 0.0, 1.0))
    rgb = (1.0 - metallic) * np.clip(base, 0.0, 1.0) + material_f0(material)
    return float(np.clip(rgb, 0.0, 1.0) @ LUMINANCE_WEIGHTS)


def bounce_estimate(scene, light, reached: np.ndarray, reflectance=None) -> float:
    """lum W of the light's flux times reflectance on the ``reached`` triangles (sampled at four
    points each, two-sided, no occlusion): the order of magnitude of the RSM total before it is
    rendered. A sun: its irradiance over the reached triangles' projected area. ``reflectance``:
    (M,) lum reflectance per material instead of _material_albedo's (a part of it: one lobe's)."""
    positions = np.asarray(scene.geometry.positions, np.float64)[reached]
    if len(positions) == 0:
        return 0.0
    if reflectance is None:
        reflectance = [_material_albedo(m) for m in scene.materials]
    albedo = np.asarray(reflectance, np.float64)[scene.geometry.material_index[reached]]
    edge1, edge2 = positions[:, 1] - positions[:, 0], positions[:, 2] - positions[:, 0]
    cross = np.cross(edge1, edge2)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normal = cross / np.maximum(2.0 * area, 1e-30)[:, None]
    colour = float(np.asarray(light.color, np.float64) @ LUMINANCE_WEIGHTS)
    if light.type == "SUN":
        direction = np.asarray(light.direction, np.float64)
        direction = direction / np.linalg.norm(direction)
        irradiance = light.power * np.abs(normal @ direction)
        return float(colour * np.sum(irradiance * area * albedo))
    points = np.einsum("sk,tkc->tsc", _ESTIMATE_BARYCENTRICS, positions)  # (T, S, 3)
    offset = points - np.asarray(light.position, np.float64)
    # A point closer than the triangle's own size is at least that far on average (the 1/d² pole).
    distance2 = np.maximum(np.sum(offset * offset, axis=-1), area[:, None])
    directions = offset / np.sqrt(np.maximum(np.sum(offset * offset, axis=-1), 1e-30))[..., None]
    cosine = np.abs(np.sum(directions * normal[:, None, :], axis=-1))
    irradiance = light_intensity(light, directions) * cosine / np.maximum(distance2, 1e-30)
    return float(colour * np.sum(irradiance.mean(axis=1) * area * albedo))


def _in_view(scene, view_projection) -> np.ndarray:
    """(T,) bool: triangles not entirely outside one clip plane of ``view_projection`` (all
    triangles without one)."""
    positions = np.asarray(scene.geometry.positions, np.float64)
    if view_projection is None:
        return np.ones(len(positions), bool)
    clip = (np.c_[positions.reshape(-1, 3), np.ones(positions.shape[0] * 3)]
            @ np.asarray(view_projection, np.float64).T).reshape(-1, 3, 4)
    w = clip[..., 3]
    outside = np.zeros(len(positions), bool)
    for axis in range(3):
        outside |= np.all(clip[..., axis] > w, axis=-1) | np.all(clip[..., axis] < -w, axis=-1)
    return ~outside


def _material_alphas(scene) -> tuple[np.ndarray, np.ndarray]:
    """(GGX α, whether it has a specular lobe) per material."""
    alphas = np.array([material_alpha(m) for m in scene.materials])
    specular = np.array([float(np.max(material_f0(m))) > 0.0 for m in scene.materials])
    return alphas, specular


def glossy_receivers_in_view(scene, view_projection=None, alpha_range=RECEIVER_ALPHA_RANGE) -> int:
    """Triangles in view (all of them without a view) whose material has a specular lobe with GGX α
    in ``alpha_range``: the receivers MRP-ASG can serve."""
    if scene.geometry.triangle_count == 0:
        return 0
    alphas, specular = _material_alphas(scene)
    ok = specular & (alphas >= alpha_range[0]) & (alphas <= alpha_range[1])
    visible = scene.visibility()[:, :2].any(axis=1)[scene.geometry.object_index]
    return int(np.count_nonzero(ok[scene.geometry.material_index] & visible & _in_view(scene, view_projection)))


def vpl_pass_needed(scene, settings: VSGLSettings) -> Decision:
    """Whether the VPL caustics pass (004) has a cell to fill (light-paths.md: a sharp reflector's
    specular lobe, α < α_c, lighting diffuse receivers): light_paths.needs_glossy_vpls, the one test
    of that cell, which the renderer's pass is gated by."""
    if not settings.caustics:
        return Decision(False, "caustics off in the settings")
    if needs_glossy_vpls(scene, settings):
        return Decision(True, f"a lit reflector with GGX α < α_c = {settings.caustic_roughness:g}: the "
                              "VPLs carry its specular light to diffuse receivers")
    return Decision(False, f"no lit reflector with GGX α < α_c = {settings.caustic_roughness:g}")


def kept_proxies(scene, settings: VSGLSettings, proxy_cache: ProxyCache, overrides=None) -> list:
    """(proxy, lit-by mask) of the rectangle proxies of ``scene`` that some light reaches on their
    front side (vsgl_addon/proxies.py), without lights the proxy's object does not receive (light
    linking) and proxies glossy rays do not see (ray visibility). ``overrides``: object name ->
    proxies.PROXY_MODES (default: the scene description's ``proxy_overrides`` if it has them)."""
    if overrides is None:
        overrides = getattr(scene, "proxy_overrides", None)
    proxies = proxy_cache.get(scene, settings.caustic_roughness, overrides)
    visibility = scene.visibility()
    kept = []
    for proxy, mask in lit_proxies(proxies, scene):
        mask = mask.copy()
        for index, light in enumerate(scene.lights):
            if light.receivers is not None and not light.receivers[proxy.object_index]:
                mask[index] = False
        if mask.any() and visibility[proxy.object_index, 1]:
            kept.append((proxy, mask))
    return kept


def _specular_reflectance(scene) -> np.ndarray:
    """(M,) lum of each material's Schlick F0 (within [0, 1]): the part of _material_albedo its
    specular lobe carries, the RSM's Φ Rs at normal incidence."""
    return np.array([float(np.clip(material_f0(m), 0.0, 1.0) @ LUMINANCE_WEIGHTS) for m in scene.materials])


def proxy_triangles(scene, proxy) -> np.ndarray:
    """(T,) bool: the triangles of ``proxy``'s object and material whose centroid lies on its
    rectangle (within a thousandth of its size): the planar region it stands for."""
    geometry = scene.geometry
    positions = np.asarray(geometry.positions, np.float64)
    mine = (geometry.object_index == proxy.object_index) & (geometry.material_index == proxy.material_index)
    if not mine.any():
        return mine
    offset = positions[mine].mean(axis=1) - np.asarray(proxy.center, np.float64)
    tolerance = 1e-3 * max(proxy.half_u, proxy.half_v) + 1e-6
    inside = ((np.abs(offset @ np.asarray(proxy.normal, np.float64)) <= tolerance)
              & (np.abs(offset @ np.asarray(proxy.axis_u, np.float64)) <= proxy.half_u + tolerance)
              & (np.abs(offset @ np.asarray(proxy.axis_v, np.float64)) <= proxy.half_v + tolerance))
    mine[np.flatnonzero(mine)[~inside]] = False
    return mine


def cell_powers(scene, settings: VSGLSettings, lights: list, reaches: list, proxies: list) -> dict:
    """lum W (bounce_estimate's CPU estimate: no occlusion, reflectance at normal incidence) of the
    bounce the optional passes' cells carry (light-paths.md), summed over the lights with RSMs
    (``lights``: LightPlans, ``reaches``: each one's reached triangles, light_reach's):

    * "vpl_pass": the specular lobes (Φ Rs) of the sharp reflectors (GGX α < α_c, a specular lobe,
      seen by diffuse rays: light_paths' test) of the lights with a glossy factor;
    * "mrp_asg": the specular lobes of the kept ``proxies``' triangles (proxy_triangles), of the
      lights in each proxy's lit-by mask.

    What the cell's receivers make of it (a diffuse floor, a mirror-like sphere) is not weighed."""
    from .light_paths import _sharp_materials

    geometry = scene.geometry
    specular = _specular_reflectance(scene)
    sharp = _sharp_materials(scene, settings.caustic_roughness)[geometry.material_index]
    sharp &= scene.visibility()[geometry.object_index, 0]
    on_proxy = [(proxy_triangles(scene, proxy), mask) for proxy, mask in proxies]
    powers = {"vpl_pass": 0.0, "mrp_asg": 0.0}
    for light, reached in zip(lights, reaches):
        source = scene.lights[light.index]
        if not light.gets_rsm or not source.specular_factor > 0.0:
            continue
        powers["vpl_pass"] += bounce_estimate(scene, source, reached & sharp, specular)
        region = np.zeros(len(reached), bool)
        for triangles, mask in on_proxy:
            if mask[light.index]:
                region |= triangles
        powers["mrp_asg"] += bounce_estimate(scene, source, reached & region, specular)
    return powers


def weigh_passes(shares: dict, frame_seconds, threshold: float | None = None) -> tuple[frozenset, dict]:
    """Which optional passes Auto runs: from none, the pass with the largest share per fraction of
    frame time added, while that is at least ``threshold``; the fraction is the one it adds to the
    passes taken before it (a pass that needs the VSGL sets another one already split costs less).

    ``shares``: pass -> its cell's share of the frame's bounce; ``frame_seconds(passes)``: the
    predicted frame time with the passes in that frozenset running. Returns (the passes run, pass ->
    (share, seconds it adds, frame seconds it adds them to): where it was taken, or the last step
    it was weighed at). ``threshold``: AUTO_SHARE_PER_COST by default."""
    threshold = AUTO_SHARE_PER_COST if threshold is None else threshold
    chosen = frozenset()
    figures = {}
    remaining = set(shares)
    while remaining:
        base = float(frame_seconds(chosen))
        best = None
        for name in sorted(remaining):
            added = max(float(frame_seconds(chosen | {name})) - base, 0.0)
            share = max(float(shares[name]), 0.0)
            fraction = added / base if base > 0.0 else math.inf
            value = share / fraction if fraction > 0.0 else (math.inf if share > 0.0 else 0.0)
            figures[name] = (share, added, base)
            if best is None or value > best[0]:
                best = (value, name)
        if not best[0] >= threshold:
            break
        chosen |= {best[1]}
        remaining.discard(best[1])
    return chosen, figures


#: The light types whose VSGL kernels follow the view PDF (settings pdf "view", 000 §5). A sun's one
#: orthographic RSM covers the scene's box grown by its bounce reach (views.sun_fit_rectangle), far
#: more than the camera sees (38x and 42x on the suite's sun scenes), and there the view PDF takes the
#: relative RMSE 16 % and 67 % down; a local light's RSM is its own frustum (1.0-2.1x the view on the
#: suite), where it moved the error by -8 % to +3 % for up to 1.6x the frame time (the 24 point
#: lights' 141 views each pay its three stages; benchmarks/results/view_pdf.md).
VIEW_PDF_LIGHT_TYPES = ("SUN",)


def view_pdf_weighs(light) -> bool:
    """Whether this light's kernels follow the view PDF when the plan runs it (VIEW_PDF_LIGHT_TYPES)."""
    return light.type in VIEW_PDF_LIGHT_TYPES


def _view_pdf_lights(scene, lights) -> list[str]:
    """The names of the planned lights with RSM views whose kernels the view PDF would place."""
    return [light.name for light in lights if light.gets_rsm and view_pdf_weighs(scene.lights[light.index])]


def _pass_decisions(scene, settings: VSGLSettings, has_vsgls: bool, proxy_cache: ProxyCache,
                    view_projection, view_pdf_lights=()) -> tuple[dict, list]:
    """(decisions of every pass after "vsgls", in DECISIONS' order; the proxies MRP-ASG keeps).
    ``view_pdf_lights``: the names of the lights with RSM views whose kernels the view PDF would
    place (view_pdf_weighs)."""
    decisions = {}
    if not settings.visibility:
        decisions["visibility"] = Decision(False, "off in the settings")
    elif not has_vsgls:
        decisions["visibility"] = Decision(False, "no VSGL to shadow")
    else:
        decisions["visibility"] = Decision(True, f"one {settings.ism_size}² imperfect shadow map per VSGL (000 §5)")
    proxies = []
    lobe_split = scene.receiver_lobe_split
    if not settings.glossy_reflectors:
        decisions["mrp_asg"] = Decision(False, "glossy reflectors off in the settings")
    elif not has_vsgls:
        decisions["mrp_asg"] = Decision(False, "no light reaches a reflector")
    else:
        proxies = kept_proxies(scene, settings, proxy_cache)
        receivers = glossy_receivers_in_view(scene, view_projection,
                                             RECEIVER_ALPHA_RANGE if not lobe_split else (0.0, 1.0))
        where = "in view" if view_projection is not None else "in the scene"
        if not proxies:
            decisions["mrp_asg"] = Decision(False, f"no lit rectangle proxy (planar, GGX α < "
                                                   f"{settings.caustic_roughness:g}): its cell stays with VSGLs")
        elif not receivers:
            proxies = []
            decisions["mrp_asg"] = Decision(False, f"no glossy receiver (GGX α ≤ {RECEIVER_ALPHA_RANGE[1]:g}) "
                                                   f"{where}: the proxies' light stays with VSGLs")
        else:
            decisions["mrp_asg"] = Decision(True, f"{len(proxies)} lit proxies kept, {receivers} glossy receiver "
                                                  f"triangles {where}")
    vpl_pass = vpl_pass_needed(scene, settings) if has_vsgls else Decision(False, "no light reaches a reflector")
    if lobe_split and has_vsgls:
        decisions["glossy_set"] = Decision(True, "some object is hidden from diffuse or glossy rays")
    elif proxies:
        decisions["glossy_set"] = Decision(True, "the glossy receivers' VSGLs leave the proxies' specular flux "
                                                 f"to MRP-ASG; {GLOSSY_SET_FACTOR} × N of them (sharp receivers "
                                                 "resolve each VSGL)")
    elif vpl_pass.run:
        decisions["glossy_set"] = Decision(True, "the diffuse receivers' VSGLs leave the sharp reflectors' "
                                                 "specular flux to the VPLs")
    else:
        decisions["glossy_set"] = Decision(False, "one VSGL set serves both receiver lobes")
    decisions["vpl_pass"] = vpl_pass
    if vpl_pass.run and proxies and not lobe_split:
        decisions["whole_set"] = Decision(True, "the receivers MRP-ASG leaves (GGX α above the range) take "
                                                "every reflector's specular light from a third set")
    else:
        decisions["whole_set"] = Decision(False, "the two receiver sets hold every path" if decisions["glossy_set"].run
                                          else "one VSGL set")
    if settings.pdf != "view":
        decisions["view_pdf"] = Decision(False, "the light PDF (settings)")
    elif settings.kernel == "two-vsgl":
        decisions["view_pdf"] = Decision(False, "two-vsgl samples no PDF (003)")
    elif view_projection is None:
        decisions["view_pdf"] = Decision(False, "no single view to weigh the texels by (the viewport): the light PDF")
    elif not has_vsgls:
        decisions["view_pdf"] = Decision(False, "no VSGL to place")
    elif not view_pdf_lights:
        decisions["view_pdf"] = Decision(False, "no sun: a local light's RSM is its own frustum, about what the view "
                                                "sees, so the light PDF")
    else:
        decisions["view_pdf"] = Decision(True, f"{', '.join(view_pdf_lights)}: texels weighted by their form factor "
                                               "with G-buffer samples' diffuse lobes, mixed with the light PDF (000 "
                                               "§5); local lights and VSGL sets that light only specular lobes keep "
                                               "the light PDF")
    return decisions, proxies


def _auto_passes(scene, settings: VSGLSettings, lights: list, reaches: list, decisions: dict, proxies: list,
                 proxy_cache: ProxyCache, view_projection, cost_model) -> tuple[dict, list, dict]:
    """Auto quality mode: ``decisions`` (and the proxies kept) with the optional passes weigh_passes
    leaves out switched off, each optional pass's reason saying what it carries and costs; and
    weigh_passes' figures."""
    from .budget import CostModel, frame_features

    optional = [name for name in AUTO_OPTIONAL if decisions[name].run]
    if not optional:
        return decisions, proxies, {}
    total = sum(light.bounce_estimate for light in lights if light.gets_rsm)
    powers = cell_powers(scene, settings, lights, reaches, proxies) if math.isfinite(total) and total > 0.0 else {}
    shares = {name: powers[name] / total for name in optional} if powers else {}
    if not shares or not all(math.isfinite(share) for share in shares.values()):
        # No finite estimate to weigh by (a light of unbounded power, nothing reflective in reach): Manual's.
        return {name: Decision(d.run, d.reason + ("; Auto: no finite bounce estimate to weigh it by"
                                                  if name in optional else "")) for name, d in decisions.items()
                }, proxies, {}
    model = CostModel.fallback() if cost_model is None else cost_model
    size = tuple(scene.camera.resolution) if scene.camera is not None else AUTO_FRAME_SIZE
    view_pdf_lights = _view_pdf_lights(scene, lights)
    triangles = int(scene.geometry.triangle_count)
    variants = {}

    def variant(passes):
        if passes not in variants:
            chosen = settings.overridden(**{toggle: name in passes for name, toggle in AUTO_TOGGLES.items()
                                            if name in optional})
            rest, kept = _pass_decisions(scene, chosen, True, proxy_cache, view_projection, view_pdf_lights)
            variants[passes] = ({"vsgls": decisions["vsgls"], **rest}, kept)
        return variants[passes]

    def frame_seconds(passes):
        ran, kept = variant(frozenset(passes))
        plan = FramePlan(settings.vsgl_count, settings.kernel, lights, ran, kept)
        return model.predict(frame_features(plan, settings, size, size, triangles))

    chosen, figures = weigh_passes(shares, frame_seconds)
    final, kept = variant(chosen)
    final = dict(final)
    for name in optional:
        share, added, base = figures[name]
        fraction = added / base if base > 0.0 else math.inf
        value = share / fraction if fraction > 0.0 else math.inf
        weighed = (f"Auto: its cell carries {100.0 * share:.3g} % of the bounce (CPU estimate) for "
                   f"+{100.0 * fraction:.0f} % predicted frame time (+{added * 1e3:.0f} ms), {value:.3g} of the "
                   "bounce per frame time added")
        if name in chosen:
            final[name] = Decision(True, f"{decisions[name].reason}; {weighed} ≥ {AUTO_SHARE_PER_COST:g}")
        else:
            final[name] = Decision(False, f"{weighed} < {AUTO_SHARE_PER_COST:g}: its light stays with VSGLs")
    return final, kept, figures


# --- The plan -------------------------------------------------------------------------------------


def plan_frame(scene, settings: VSGLSettings, proxy_cache: ProxyCache | None = None,
               view_projection=None, cost_model=None) -> FramePlan:
    """The plan of one frame of ``scene`` (a SceneDescription) with ``settings``.

    ``view_projection``: the (4, 4) world -> clip matrix of the one view the frame is rendered from
    (F12); None when the light passes serve any view (the viewport), so "in view" means "in the
    scene". ``cost_model``: the budget.CostModel Auto quality mode weighs the passes' costs with
    (the built-in one by default)."""
    bounds = scene_bounds(scene)
    lights = []
    reaches = []
    for index, light in enumerate(scene.lights):
        specs = []
        views, mask = light_reach(scene, light, bounds, specs)
        estimate = bounce_estimate(scene, light, mask)
        if views == 0:
            reason = "its views see no triangle"
        elif not mask.any():
            views, reason = 0, "lights no object that receives it (light linking)"
        elif estimate <= 0.0:
            reason = "RSM for the direct light's shadows; no reflectance in reach, no bounce expected"
        else:
            reason = f"bounce ≈ {estimate:.3g} W (CPU estimate, no occlusion)"
        lights.append(LightPlan(index, light.name, views, settings.rsm_size, estimate, reason,
                                view_specs=specs if views else []))
        reaches.append(mask)
    if settings.kernel != "two-vsgl":
        total = sum(light.bounce_estimate for light in lights if light.gets_rsm)
        for light in lights:
            if light.gets_rsm and total > 0.0:
                share = light.bounce_estimate / total
                light.rsm_size = rsm_size_for_share(settings.rsm_size, share)
                light.size_reason = (f"RSM side √({100.0 * share:.3g} % expected share of N) × {settings.rsm_size}"
                                     f" → {light.rsm_size} (a power of two, at least "
                                     f"{min(MIN_RSM_SIZE, settings.rsm_size)})")
    rsm_lights = sum(light.gets_rsm for light in lights)
    decisions = {}
    if settings.kernel == "two-vsgl":
        decisions["vsgls"] = Decision(rsm_lights > 0, f"two per RSM view (003); N unused, {rsm_lights} lights with RSMs")
    elif rsm_lights:
        decisions["vsgls"] = Decision(True, f"N = {settings.vsgl_count} for the frame, shared by the RSM views of "
                                            f"{rsm_lights} lights in proportion to their bounce power")
    else:
        decisions["vsgls"] = Decision(False, "no light reaches a reflector")
    has_vsgls = decisions["vsgls"].run
    cache = PROXY_CACHE if proxy_cache is None else proxy_cache
    rest, proxies = _pass_decisions(scene, settings, has_vsgls, cache, view_projection,
                                    _view_pdf_lights(scene, lights))
    decisions.update(rest)
    weighed = {}
    if settings.quality_mode in WEIGHING_MODES and has_vsgls:
        decisions, proxies, weighed = _auto_passes(scene, settings, lights, reaches, decisions, proxies, cache,
                                                   view_projection, cost_model)
    return FramePlan(settings.vsgl_count, settings.kernel, lights, decisions, proxies, weighed=weighed)


#: The proxies of the last scene geometry (rebuilt only when it changes, not when a light or the view
#: moves), for callers that keep no cache of their own.
PROXY_CACHE = ProxyCache()


def view_power(totals) -> float:
    """lum of one view's RSM total Σ Φ(Rd + Rs) (RGB, W): what the budget is shared by."""
    return float(np.asarray(totals, np.float64) @ LUMINANCE_WEIGHTS)
