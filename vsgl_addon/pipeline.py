# SPDX-License-Identifier: GPL-3.0-or-later
"""Scene description -> VSGLs of every light: the RSM pass, then VSGL generation (000 §3-4).

Never touches bpy.context. Needs a GPU context (gpu_context.ensure_gpu_context), main thread.

A light may have several RSM views (a point or area light: cube faces; a wide spot: cube faces).
VSGL count N is the frame's (planner.py): every view of every light the plan gives RSM views is
rendered first, then N is shared among all of them in proportion to each view's power
lum(Σ Φ(Rd + Rs)) (planner.allocate_vsgls), so the VSGLs go where the frame's bounce is, whichever
light it comes from. Views with no power (or a negligible share) get none. In 003's two-VSGL mode
every view gives its two VSGLs (meant for one spot view, 003).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .layouts import VSGL_TABLE
from .passes.rsm import SceneGPU, render_rsm_views
from .passes.vsgl_generation import VSGLGeneration
from .planner import DeferredPowers, plan_frame, share_counts, view_pdf_weighs, view_power
from .reference.vsgl import LUMINANCE_WEIGHTS
from .scene_description import LIGHT_TYPES
from .scene_points import triangle_areas
from .settings import VSGLSettings

# Per-VSGL arrays of the VSGL table (vsgl_addon.layouts.VSGL_TABLE) that the exported table keeps
# (one row per VSGL), in the export's order; the warp's texel is generation's own diagnostic.
VSGL_FIELDS = ("mean", "variance", "diffuse_mean", "diffuse_variance", "specular_mean",
               "specular_variance", "diffuse_amplitude", "diffuse_axis", "diffuse_sharpness",
               "specular_amplitude", "specular_axis", "specular_sharpness", "power",
               "kernel_center", "kernel_level")


def share_vsgl_count(vsgl_count: int, view_powers) -> np.ndarray:
    """Split N among views in proportion to their power (largest remainders, sums to N).

    All views without power: none get any. N smaller than the number of lit views: the brightest get one.
    """
    return share_counts(vsgl_count, view_powers)


def _rotation(seed: int, light_index: int, view_index: int) -> np.ndarray:
    """Independent lattice rotations per light and view, all fixed by the seed."""
    return np.random.default_rng([seed, light_index, view_index]).random(2)


def _empty_table() -> dict:
    return {name: np.zeros((0, *VSGL_TABLE.field_shape(name))) for name in VSGL_FIELDS}


@dataclass
class SceneVSGLs:
    """The RSM views of every light and the VSGL tables made from them, still on the GPU.

    The render keeps the views for the direct light's shadows and hands the tables to VSGL shading;
    the export reads the tables back. `free()` releases every texture.
    """

    views_by_light: dict[int, list]
    generations: list[tuple[int, int, VSGLGeneration]]  # (light index, view index, its table)
    rsm_total_power: np.ndarray  # (L, 3)
    rsm_size: int
    # The imperfect shadow maps of each shading table's VSGLs (passes/ism.py), in the same order
    # (table_arrays()); empty without visibility.
    isms: list = field(default_factory=list)
    # (table dict, VSGLTable) of every generation's VSGLs in one table (merge()), or None.
    merged: tuple | None = None
    # Lights whose rsm_total_power is still in their tables only (render_scene_vsgls did not need it).
    deferred_totals: set = field(default_factory=set)

    @property
    def vsgl_count(self) -> int:
        """The VSGLs shading gets: the merged table's, or the sum of the views' tables."""
        if self.merged is not None:
            return self.merged[1].count
        return sum(generation.vsgl_count for _, _, generation in self.generations)

    def tables(self) -> list:
        from .passes.vsgl_shading import VSGLTable

        if self.merged is not None:
            table = self.merged[1]
            return [VSGLTable(table.texture, table.count, table.shared_positions, self.isms[0] if self.isms else None)]
        isms = self.isms or [None] * len(self.generations)
        return [VSGLTable.from_generation(generation, ism) for (_, _, generation), ism in zip(self.generations, isms)]

    def table_arrays(self) -> list[dict]:
        """The shading tables' VSGLs as numpy dicts, in the order of tables() (and of isms)."""
        if self.merged is not None:
            return [self.merged[0]]
        return [generation.read_table() for _, _, generation in self.generations]

    def merge(self, normalize: bool = False) -> None:
        """Every generation's VSGLs in one shading table: with N shared by many lights' views, one
        shading draw and one atlas of shadow maps instead of one per view (each pays a full-screen
        pass; the sum over VSGLs is the same). ``normalize``: scale each view's VSGL powers (both
        lobes' amplitudes) so that their luminance sums to the view's RSM total exactly. 000 Eq. 5
        gives that sum only where the PDF is smooth at the kernels' scale: with the view PDF
        (reference/brsm.py) the few wide kernels over the dim part of a view read a filtered PDF
        mass larger than theirs and the sum comes out low (12-19 % at N = 64 over a point light's
        five views, 3 % at N = 1024; tests/test_reference_brsm.py's room), so the view PDF's frames
        would be darker. A table with plane-split slots (VSGLGeneration.generate's ``plane_split``)
        is merged even alone: reading it drops its unused slots, which shading would loop over."""
        from .passes.vsgl_shading import upload_vsgl_table

        split = any(generation.plane_split for _, _, generation in self.generations)
        if self.merged is not None or not self.generations or (len(self.generations) < 2 and not normalize
                                                                and not split):
            return
        tables = [generation.read_table() for _, _, generation in self.generations]
        if normalize:
            for table in tables:
                total = float(np.asarray(table["rsm_total_power"]) @ LUMINANCE_WEIGHTS)
                summed = float(np.sum(table["power"], axis=0) @ LUMINANCE_WEIGHTS)
                scale = total / summed if summed > 0.0 and np.isfinite(total / summed) else 1.0
                for name in ("power", "diffuse_amplitude", "specular_amplitude"):
                    table[name] = table[name] * scale
        merged = {name: np.concatenate([table[name] for table in tables]) for name in VSGL_TABLE.record_fields()}
        merged["rsm_total_power"] = np.sum([table["rsm_total_power"] for table in tables], axis=0)
        self.merged = (merged, upload_vsgl_table(merged))

    def read(self) -> dict[str, np.ndarray]:
        """The export table (see generate_scene_vsgls), read back from the GPU."""
        tables, light_rows, view_rows = [], [], []
        read = [generation.read_table() for _, _, generation in self.generations]
        for (light_index, view_index, generation), table in zip(self.generations, read):
            tables.append({name: table[name] for name in VSGL_FIELDS})
            light_rows.append(np.full(len(table["power"]), light_index))
            view_rows.append(np.full(len(table["power"]), view_index))
        merged = ({name: np.concatenate([t[name] for t in tables]) for name in VSGL_FIELDS}
                  if tables else _empty_table())
        if self.merged is not None:  # the shading table, normalized where merge() normalized it
            merged.update({name: np.asarray(self.merged[0][name]) for name in VSGL_FIELDS})
        merged["light_index"] = np.concatenate(light_rows) if light_rows else np.zeros(0, np.int64)
        merged["view_index"] = np.concatenate(view_rows) if view_rows else np.zeros(0, np.int64)
        light_count = len(self.rsm_total_power)
        merged["rsm_total_power"] = self.rsm_total_power.copy()
        for light_index in self.deferred_totals:  # every view of theirs has a table
            merged["rsm_total_power"][light_index] = np.sum(
                [table["rsm_total_power"] for table, (index, _, _) in zip(read, self.generations)
                 if index == light_index] or [np.zeros(3)], axis=0)
        merged["rsm_size"] = np.full(light_count, self.rsm_size, np.int64)
        merged["rsm_view_count"] = np.array([len(self.views_by_light.get(i, [])) for i in range(light_count)],
                                            np.int64)
        return merged

    def free(self) -> None:
        for atlas in self.isms:
            atlas.free()
        self.isms.clear()
        self.merged = None  # Blender frees a GPUTexture with its last reference
        self.deferred_totals = set()
        for _, _, generation in self.generations:
            generation.free()
        self.generations.clear()
        for views in self.views_by_light.values():
            for view in views:
                view.free()
        self.views_by_light.clear()


#: Camera G-buffer side (pixels, the longer side) and at most this many of its covered pixels as the
#: receivers of the view PDF (reference/brsm.py): enough to tell where the view's light matters.
VIEW_PDF_GBUFFER = 64
VIEW_PDF_RECEIVERS = 256
#: The view PDF's pole radius r, as a fraction of the scene's bounding diagonal.
VIEW_PDF_RADIUS = 0.02
#: With the view PDF, each view's VSGL powers scaled to its RSM total (SceneVSGLs.merge; read when
#: called, so benchmarks/view_pdf.py can measure both). Off: 000 Eq. 5 with this high-frequency PDF
#: sums short where the PDF is low, far from what the camera sees (the suns' views at N = 64 / 256 /
#: 1024: 0.77-0.81 / 0.93-0.95 / 0.98 of the RSM total), and one scale per view would raise the near
#: kernels with them: the sun courtyard's mean 1.08 -> 1.13 of Cycles, the open sun ground's
#: 1.00 -> 1.08, while without it both keep the light PDF's means (benchmarks/results/view_pdf.md).
#: (A point-lit room at N = 64 over five views sums 12-19 % short; the view PDF weighs only suns,
#: planner.VIEW_PDF_LIGHT_TYPES.)
NORMALIZE_VIEW_PDF_POWERS = False


def view_receivers(scene_gpu: SceneGPU, view_matrix, projection_matrix) -> dict:
    """The view PDF's receivers: positions, normals and diffuse reflectances (lum of base colour ×
    (1 − metallic), shading_inputs' Rd without its view-dependent albedo: a metal has no diffuse
    lobe) of at most VIEW_PDF_RECEIVERS covered pixels of a small G-buffer of the view, and the pole
    radius."""
    from .passes import gbuffer as gbuffer_pass

    gbuffer = gbuffer_pass.PASS.run(scene_gpu, view_matrix, projection_matrix,
                                    (VIEW_PDF_GBUFFER, VIEW_PDF_GBUFFER * 3 // 4))
    try:
        arrays = gbuffer.to_numpy()
    finally:
        gbuffer.free()
    covered = arrays["position"][..., 3].reshape(-1) > 0.5
    index = np.flatnonzero(covered)
    index = index[np.linspace(0, len(index) - 1, min(len(index), VIEW_PDF_RECEIVERS)).astype(np.int64)] \
        if len(index) else index
    base = arrays["base_color"].reshape(-1, 4)[index]
    lo, hi = scene_gpu.bounds if scene_gpu.bounds is not None else (np.zeros(3), np.ones(3))
    return {"position": arrays["position"].reshape(-1, 4)[index, :3].astype(np.float64),
            "normal": arrays["normal"].reshape(-1, 4)[index, :3].astype(np.float64),
            "weight": (np.clip(base[:, :3], 0.0, 1.0).astype(np.float64) @ LUMINANCE_WEIGHTS)
            * (1.0 - np.clip(base[:, 3], 0.0, 1.0).astype(np.float64)),
            "radius": VIEW_PDF_RADIUS * float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))}


def view_pdf_serves(receiver_set: str, receiver_sets) -> bool:
    """Whether VSGL set ``receiver_set`` of a frame with ``receiver_sets`` (FramePlan.receiver_sets)
    lights some receiver's diffuse lobe, so its kernels follow the view PDF (reference/brsm.py; the
    others keep the light PDF). renderer.SceneLights.build: the "glossy" set lights specular lobes,
    and so does the whole ("all") set when it is the third; the first set lights the diffuse lobes."""
    return receiver_set != "glossy" and not (receiver_set == "all" and len(receiver_sets) > 2)


def _view_pdf_texture(view, receivers):
    """The defensive mixture of the view PDF and the light PDF for one RSM view, on the GPU
    (passes/brsm.py, twin reference/brsm.py; ``receivers``: brsm.upload_receivers's)."""
    from .passes import brsm

    return brsm.PASS.run(view.rsm_textures(), receivers)


def _power_reader(result: "SceneVSGLs", light_index: int):
    """The per-view powers of light ``light_index``'s views in ``result``, read back from their
    tables when called; None once the tables were freed unread."""
    def read():
        if light_index not in result.deferred_totals:  # freed
            return None
        return [view_power(g.read_table()["rsm_total_power"]) for index, _, g in result.generations
                if index == light_index]
    return read


def render_scene_vsgls(scene_gpu: SceneGPU, settings: VSGLSettings, receiver_lobe: str = "all",
                       proxies=(), sharp_alpha: float = 0.0, plan=None, receivers=None) -> SceneVSGLs:
    """RSM views of the lights the frame plan gives them, then the frame's VSGLs (tables stay on the GPU).

    ``receiver_lobe`` (scene_description.RECEIVER_LOBES): the VSGLs of every reflector ("all"), or
    only of those seen by diffuse or by glossy rays, for a scene where some object is hidden from one
    ray type (Blender's ray visibility): the receivers' two lobes then see different reflectors.
    ``proxies`` (with "glossy"): the rectangle proxies whose specular flux MRP-ASG carries to the
    receivers' glossy lobes instead (light-paths.md; passes/rsm.py), each a RectangleProxy (for
    every light) or a (proxy, lit-by mask) pair of planner.kept_proxies (for the lights of its mask:
    MRP-ASG shades a proxy with those alone, so another light's reflection off it stays in these
    VSGLs instead of being in neither). ``sharp_alpha`` > 0: no texel
    with GGX α below it keeps specular flux, which the glossy VPLs carry to diffuse receivers.
    ``plan``: the frame's planner.FramePlan (made here when None); the views' measured powers share
    its N (FramePlan.allocate, recorded in the plan under ``receiver_lobe``). ``receivers``
    (view_receivers): with the plan's view PDF, each view's kernels follow the view PDF (000 §5).
    """
    light_count = len(scene_gpu.scene.lights)
    if plan is None:
        plan = plan_frame(scene_gpu.scene, settings)
    result = SceneVSGLs({}, [], np.zeros((light_count, 3)), settings.rsm_size)
    two_vsgl = settings.kernel == "two-vsgl"
    pending = []  # (light index, view index, generation) with the view's mip atlas, not yet sampled
    view_pdf = receivers is not None and plan.runs("view_pdf") and view_pdf_serves(receiver_lobe, plan.receiver_sets)
    uploaded = None
    try:
        if view_pdf:
            from .passes.brsm import upload_receivers

            uploaded = upload_receivers(receivers)
        for light_index in plan.rsm_lights():
            light_plan = plan.lights[light_index]
            # The views the planner culled already (light_reach): not tested a second time per frame.
            specs = light_plan.view_specs if len(light_plan.view_specs) == light_plan.rsm_views else None
            light_proxies = [proxy[0] if isinstance(proxy, tuple) else proxy for proxy in proxies
                             if not isinstance(proxy, tuple) or proxy[1][light_index]]
            views = render_rsm_views(scene_gpu, light_index, light_plan.rsm_size, receiver_lobe,
                                     light_proxies, sharp_alpha, specs)
            result.views_by_light[light_index] = views
            for view_index, view in enumerate(views):
                generation = VSGLGeneration()
                pending.append((light_index, view_index, generation))
                weighs = view_pdf and view_pdf_weighs(scene_gpu.scene.lights[light_index])
                pdf = _view_pdf_texture(view, uploaded) if weighs else None
                generation.build_mip_atlas(view.rsm_textures(), pdf,
                                           split_kernels_at_jumps(scene_gpu.scene.lights[light_index]))
        view_counts = {index: len(views) for index, views in result.views_by_light.items()}
        if plan.allocation_reads_powers(view_counts):
            totals = {index: [] for index in view_counts}
            for light_index, _, generation in pending:
                # One kernel is enough to read the view's total from the atlas's top level.
                generation.generate(1 if not two_vsgl else 2, settings.k, settings.kernel)
                totals[light_index].append(generation.read_table()["rsm_total_power"])
            view_powers = {}
            for light_index, light_totals in totals.items():
                if light_totals:
                    result.rsm_total_power[light_index] = np.sum(light_totals, axis=0)
                view_powers[light_index] = [view_power(total) for total in light_totals]
        else:
            # The shares do not depend on the powers: the totals are read back only when the
            # statistics, the report or the export ask (the tables hold them, row rsm_total_power).
            view_powers = {index: DeferredPowers(count, _power_reader(result, index))
                           for index, count in view_counts.items()}
            result.deferred_totals = set(view_counts)
        counts = plan.allocate(view_powers, receiver_lobe)
        while pending:
            light_index, view_index, generation = pending.pop(0)
            count = int(counts[light_index][view_index])
            if count == 0:
                generation.free()
                continue
            result.generations.append((light_index, view_index, generation))
            light = scene_gpu.scene.lights[light_index]
            generation.generate(count, settings.k, settings.kernel,
                                _rotation(settings.seed, light_index, view_index),
                                settings.positional_distribution, split_kernels_at_jumps(light),
                                split_planes(light))
        result.merge(normalize=view_pdf and NORMALIZE_VIEW_PDF_POWERS)
    except BaseException:
        for _, _, generation in pending:
            generation.free()
        result.free()
        raise
    finally:
        if uploaded is not None:
            uploaded.free()
    return result


#: The light types whose VSGL kernels descend off RSM depth discontinuities
#: (reference.vsgl.kernel_level_unstraddled; split_kernels_at_jumps). A sun's one orthographic RSM
#: spans the whole scene, so its kernels span metres and a wall's top joins the ground beyond it:
#: the courtyard's relative RMSE 0.653 -> 0.417 at N = 256, 0.616 -> 0.343 at N = 1024 (0.653 ->
#: 0.707 at N = 64, robust 0.586 -> 0.404); in the point-lit room the descended kernels' VPL-like
#: VSGLs light their neighbours in spikes (0.133 -> 0.196), in the 24-light room 0.194 -> 0.218,
#: so the other types keep 000's kernels (benchmarks/split_at_jumps.py). () : none descends.
SPLIT_LIGHT_TYPES = ("SUN",)


def split_kernels_at_jumps(light) -> bool:
    """Whether this light's VSGL kernels descend off depth discontinuities (SPLIT_LIGHT_TYPES)."""
    return light.type in SPLIT_LIGHT_TYPES


#: The light types whose VSGL clusters over several planes give each plane its own VSGL
#: (reference.vsgl.PLANE_SPLIT; split_planes). None by default: measured on the suite
#: (benchmarks/plane_split.py, results/plane_split.md), the point lights' split brings the 24-light
#: room's mean to 0.90 of Cycles (0.88 without) but with 2.2x the VSGLs, and at that count 000's
#: clusters give the same relative RMSE there (0.165) and a lower one in the closed room (0.112
#: against the split's 0.132): N counts kernels, so the split would also break N as the frame's
#: VSGL budget (planner.FramePlan.allocate).
PLANE_SPLIT_LIGHT_TYPES = ()


def split_planes(light) -> bool:
    """Whether this light's VSGL clusters split by plane (PLANE_SPLIT_LIGHT_TYPES)."""
    return light.type in PLANE_SPLIT_LIGHT_TYPES


#: Point sets the imperfect shadow maps draw from: map m splats set m mod POINT_SETS (Ritschel et
#: al. 2008 give each map its own subset; 64 keep neighbouring maps' holes apart at a small memory).
POINT_SETS = 64
#: Points within this many σ_v of a map's origin are its own reflector, not an occluder of its light
#: (0.5 and 2 give the occluder scene the same light, benchmarks/visibility_diagnosis.py): the VPL
#: clusters' maps (passes/vpl_culling.py), whose half-space leaves out their reflector's plane too.
OWN_REFLECTOR_SIGMAS = 1.0
#: The same for the VSGLs' maps. A flat cluster's shadow origin sits SHADOW_ORIGIN_SIGMAS = 0.5 σ_v
#: off its surface (reference/ism.py shadow_origin), so with 0.3 σ_v its own surface stays in its
#: map and hides what lies behind it (the sunlit back of a thin wall no longer lights the wall's
#: shaded front through the hole a 1 σ_v ball cut around the origin), which the diffuse lobe's
#: own-reflector side (reference/vsgl_shading.py vsgl_reflector_side) did by a model that assumes
#: a bent cluster convex: it also took the light a room corner's cluster gives the receivers
#: between its walls. Float64 maps of the same VSGLs (benchmarks/visibility_diagnosis.py, stride 6,
#: N = 256): the 24-light room 0.834 -> 0.863 of Cycles, the courtyard 1.488 -> 1.451, the Cornell
#: box 0.898 -> 0.905 (1 σ_v with the side -> 0.3 σ_v without; 0.5 σ_v without gives the courtyard
#: 1.499, 0.1 σ_v the room 0.855).
VSGL_OWN_REFLECTOR_SIGMAS = 0.3


#: Imperfect shadow maps per VSGL: 1, at its diffuse lobe's positional Gaussian for both lobes (000
#: app. B.2 gives a VSGL one position so as not to multiply its visibility tests; with the shared
#: positional distribution that is it, with per-lobe positions the diffuse lobe's, Φ·Rd-weighted,
#: which the shading pass has loaded already: the shared position would be one more texel fetch per
#: VSGL and pixel, a sixth of the lookups' cost on llvmpipe), or 2, one per lobe position. The lobes
#: come from one cluster, so their positions lie within its spread; one map halves the maps and the
#: lookups (benchmarks/visibility_cost.py).
MAPS_PER_VSGL = 1


#: The lights whose VSGLs' maps keep their surfaces' depth (reference/ism.py: oriented splats
#: capped at SURFACE_SPLAT_MAX_RADIUS, gap sides continued as planes). Point maps close a room's
#: concave folds as gaps and grow every outline by their rounded-up square splats, and hide about
#: twice the light exact visibility from the same origins hides (many_lights 0.860 of Cycles' light,
#: exact 0.903). Whole frames, seeds 0-1 (benchmarks/results/ism_surfaces_cap12.md): many_lights
#: 0.860 -> 0.881 (relative RMSE 0.193 -> 0.179), the Cornell box's and the closed room's RMSE
#: 0.210 -> 0.197 and 0.134 -> 0.123, the occluder's 0.836 -> 0.834, the demo's 0.374 -> 0.375.
SURFACE_LIGHT_TYPES = LIGHT_TYPES
#: The lights whose maps' lookups take the normal offset (reference/ism.py lookup_offsets
#: ``surfaces``) instead of the slope-scaled depth bias. A sun's RSM spans open ground whose VSGLs
#: light the far faces of thin walls at grazing incidence, where the slope-scaled depth bias reaches
#: through the wall (the sun courtyard: 1.19 of Cycles' light, 1.10 with these maps, exact ray-cast
#: visibility from the same origins 1.08; benchmarks/ism_holes.py). In the closed scenes the normal
#: offset shadows receivers at concave corners and on the demo's glossy floor (the demo's relative
#: RMSE 0.374 to 0.438; benchmarks/results/ism_surfaces.md).
NORMAL_OFFSET_LIGHT_TYPES = ("SUN",)


def maps_keep_surfaces(lights) -> bool:
    """Whether a shading table's maps keep their surfaces (SURFACE_LIGHT_TYPES): every light whose
    VSGLs it holds is of those types."""
    lights = list(lights)
    return bool(lights) and all(light.type in SURFACE_LIGHT_TYPES for light in lights)


def maps_take_normal_offset(lights) -> bool:
    """Whether a shading table's lookups take the normal offset: its maps keep their surfaces and
    every light whose VSGLs it holds is of NORMAL_OFFSET_LIGHT_TYPES."""
    lights = list(lights)
    return maps_keep_surfaces(lights) and all(light.type in NORMAL_OFFSET_LIGHT_TYPES for light in lights)


def build_visibility(scene_gpu: SceneGPU, vsgls: SceneVSGLs, settings: VSGLSettings, first_map: int = 0,
                     timed: bool = False) -> int:
    """:func:`build_visibility_stages` at once."""
    from .passes.contract import run_stages

    return run_stages(build_visibility_stages(scene_gpu, vsgls, settings, first_map, timed))


def build_visibility_stages(scene_gpu: SceneGPU, vsgls: SceneVSGLs, settings: VSGLSettings, first_map: int = 0,
                            timed: bool = False):
    """A generator yielding between the maps' stages (passes/ism.py build_ism_atlas_stages) that
    returns what build_visibility does. The imperfect shadow maps of every VSGL of ``vsgls`` (000 §5), one per lobe position (two
    per VSGL with per-lobe positions), into ``vsgls.isms``; returns the next map's number, so
    another table set draws other point sets. ``timed``: each atlas's ``seconds`` holds its
    stages' times (passes/ism.py build_ism_atlas; benchmarks)."""
    from .passes import ism as ism_pass

    points = scene_gpu.scene_points(settings.ism_points, POINT_SETS, settings.seed)
    point_area = float(triangle_areas(scene_gpu.scene.geometry.positions).sum()) / settings.ism_points
    # Uploaded once for every table and every VSGL set of the frame.
    textures = scene_gpu.point_textures(settings.ism_points, POINT_SETS, settings.seed) if vsgls.generations else None
    if textures is not None:
        yield  # a new seed's point sets are drawn on the CPU (tens of ms): a stage of their own
    lights = scene_gpu.scene.lights
    if vsgls.merged is not None:
        table_lights = [[lights[index] for index, _, _ in vsgls.generations]]
    else:
        table_lights = [[lights[index]] for index, _, _ in vsgls.generations]
    for table, its_lights in zip(vsgls.tables(), table_lights):
        # Each map's origin, point set and own-reflector distance made from the table texture on
        # the GPU (passes/ism.py vsgl_map_origins): the tables stay on the GPU.
        origins = ism_pass.vsgl_map_origins(table.texture, table.count, MAPS_PER_VSGL, first_map, POINT_SETS,
                                            VSGL_OWN_REFLECTOR_SIGMAS)
        size = ism_pass.fitting_size(origins.count, settings.ism_size)
        vsgls.isms.append((yield from ism_pass.build_ism_atlas_stages(
            points, origins, None, size, point_area=point_area, timed=timed, point_textures=textures,
            surfaces=maps_keep_surfaces(its_lights), normal_offset=maps_take_normal_offset(its_lights))))
        first_map += origins.count
    return first_map


def generate_scene_vsgls(scene, settings: VSGLSettings) -> dict[str, np.ndarray]:
    """The VSGLs of every light of `scene` (a SceneDescription) as the export table.

    One row per VSGL: VSGL_FIELDS plus `light_index` and `view_index`; one row per light:
    `rsm_total_power` (L, 3) = Σ Φ(Rd + Rs) over all its RSM texels, `rsm_size` (L) and
    `rsm_view_count` (L). A light that hits nothing has no RSM view and no VSGL.
    """
    scene_gpu = SceneGPU(scene)
    try:
        vsgls = render_scene_vsgls(scene_gpu, settings)
        try:
            return vsgls.read()
        finally:
            vsgls.free()
    finally:
        scene_gpu.free()
