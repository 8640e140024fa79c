# SPDX-License-Identifier: GPL-3.0-or-later
"""Glossy VPLs with stochastic light culling on the GPU (004; formulas.md section 7). Twin of
``vsgl_addon/reference/vpl_culling.py`` through ``glsl/lib/vpl_culling.glsl``; one compute stage,
``glsl/vpl_culling/vpl_cull_shade.comp.glsl`` (one work group per 16x16 tile: depth range, the
ellipsoid-frustum test of every VPL's spheroid, per-tile index lists in an R32UI image, shading of
the tile's list with the exact GGX BRDF at the VPL and the receiver's diffuse lobe).

    result = run(position, normal, albedo, vpls, world_to_view, projection, delta, seed, frame)
    image = result.read()            # (h, w, 4) float32, row 0 = bottom
    counts = result.read_counts()    # (tiles_y, tiles_x) VPLs listed per tile
    result.free()

``vpls`` is a :class:`VPLSet` (:func:`extract_vpls`: the VPLs made from the RSM on the GPU, or
:func:`upload_vpls` of a dict as :func:`scene_vpls` reads them back). Receivers:
world position (w = coverage > 0), world normal and diffuse reflectance textures of one size.
Output RGBA32F radiance, W/(m^2 sr), unshadowed. Needs a GPU context, main thread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..layouts import GBUFFER, RSM, SHADING_INPUTS
from ..reference import vpl_clusters as _clusters
from ..reference.vpl_culling import VPL_ALPHA_MIN
from ..shaders import ShaderInterface
from .contract import GPUPass, ShaderSpec, Step
from .gpu_util import RoundTrips, read_texture, set_uniform, texture_from_array

TILE = 16
#: VPL records per table row (the table is TABLE_WIDTH wide, four rows per record row).
TABLE_WIDTH = 1024
#: Listed indices kept per tile in the R32UI list image (shading is exact beyond it: chunked).
LIST_CAPACITY = 1024


def _interface(visibility: bool = False) -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("VEC4", "vpl_params"), ("IVEC4", "vpl_sizes"), ("IVEC4", "vpl_interleave")]
        + ([("IVEC4", "ism_params")] if visibility else []),
        # What is read texel by texel per VPL or per pixel is bound as images: on llvmpipe an
        # imageLoad costs a fraction of a texelFetch (benchmarks/results/view_passes_profile.md),
        # the same texels either way. Blender binds at most 8 images per shader: the camera rows and
        # the count, read once per invocation, stay samplers, and so does the ISM atlas, whose
        # lookup is one textureGather.
        samplers=[("FLOAT_2D", "vpl_camera"), ("UINT_2D", "vpl_count")]
        + ([("FLOAT_2D", "ism_atlas")] if visibility else []),
        images=[("RGBA32F", "FLOAT_2D", "vpl_radiance"), ("R32UI", "UINT_2D", "vpl_tile_lists"),
                ("R32UI", "UINT_2D", "vpl_tile_counts"), ("RGBA32F", "FLOAT_2D", "gbuffer_position"),
                ("RGBA32F", "FLOAT_2D", "gbuffer_normal"), ("RGBA32F", "FLOAT_2D", "receiver_albedo"),
                ("RGBA32F", "FLOAT_2D", "vpl_table")]
        + ([("RGBA32F", "FLOAT_2D", "vpl_map_origins")] if visibility else []),
        local_group_size=(TILE, TILE, 1),
        shared="shared uint tile_depth_min; shared uint tile_depth_max; shared uint tile_covered; "
               "shared uint tile_total; shared uint tile_x_min; shared uint tile_y_min; "
               "shared uint tile_x_max; shared uint tile_y_max; "
               # A chunk's listed VPLs, partitioned by interleave subset (at most 8 x 8 of them).
               "shared uint subset_count[64]; shared uint chunk_list[256];",
    )


def _denoise_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("IVEC4", "denoise_params"), ("VEC4", "denoise_eye")],
        # (2 radius + 1)^2 texels of each input per pixel, read as images (see _interface).
        images=[("RGBA32F", "FLOAT_2D", "vpl_denoised"), ("RGBA32F", "FLOAT_2D", "vpl_noisy"),
                ("RGBA32F", "FLOAT_2D", "gbuffer_position"), ("RGBA32F", "FLOAT_2D", "gbuffer_normal")],
        local_group_size=(8, 8, 1),
    )


#: The filter's guide: off the centre's tangent plane by this fraction of its depth weighs e^-1;
#: normals weigh (n_p . n_q)^NORMAL_POWER.
DENOISE_SIGMA_PLANE = 0.02
DENOISE_NORMAL_POWER = 16


def denoise(radiance, position, normal, radius: int, eye):
    """The cross-bilateral filtered copy of ``radiance`` (radius 0: ``radiance`` itself)."""
    import gpu

    if radius <= 0:
        return radiance
    out = gpu.types.GPUTexture((radiance.width, radiance.height), format="RGBA32F")
    shader = PASS.shader("denoise")
    shader.bind()
    shader.uniform_int("denoise_params", (int(radius), DENOISE_NORMAL_POWER, 0, 0))
    shader.uniform_float("denoise_eye", (*(float(v) for v in eye), DENOISE_SIGMA_PLANE))
    shader.image("vpl_noisy", radiance)
    shader.image("gbuffer_position", position)
    shader.image("gbuffer_normal", normal)
    shader.image("vpl_denoised", out)
    gpu.compute.dispatch(shader, math.ceil(radiance.width / 8), math.ceil(radiance.height / 8), 1)
    return out


def _add_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("VEC4", "add_weights")],
        images=[("RGBA32F", "FLOAT_2D", "add_out"), ("RGBA32F", "FLOAT_2D", "add_a"), ("RGBA32F", "FLOAT_2D", "add_b")],
        local_group_size=(8, 8, 1),
    )


def add_textures(a, b, weight_a: float, weight_b: float, out=None):
    """``out`` (a new texture when None) = weight_a a + weight_b b in RGB, a's alpha
    (glsl/vpl_culling/vpl_add.comp.glsl): the progressive mean and the diffuse composite, on the GPU."""
    import gpu

    if out is None:
        out = gpu.types.GPUTexture((a.width, a.height), format="RGBA32F")
    shader = PASS.shader("add")
    shader.bind()
    shader.uniform_float("add_weights", (float(weight_a), float(weight_b), 0.0, 0.0))
    shader.image("add_a", a)
    shader.image("add_b", b)
    shader.image("add_out", out)
    gpu.compute.dispatch(shader, math.ceil(a.width / 8), math.ceil(a.height / 8), 1)
    return out


class VPLSet:
    """The glossy VPLs of a scene state on the GPU (view-independent, made once): the record table
    of :func:`vpl_table` (``capacity`` records), the number of VPLs in it as a 1x1 R32UI texture
    (``count_texture``: the culling reads it there, so the GPU extraction needs no read-back), and
    with visibility the imperfect shadow maps of the VPLs' clusters (passes/ism.py ISMAtlas) and each
    map's origin (a (maps, 1) RGBA32F texture). ``count`` is known when the set was uploaded, else read
    back once (4 bytes) when first asked: the statistics and the report. ``free()`` drops the textures."""

    def __init__(self, table, count: int | None = None, isms=None, map_origins=None, count_texture=None,
                 capacity: int | None = None):
        self.table, self.isms, self.map_origins = table, isms, map_origins
        self._count = None if count is None else int(count)
        self.capacity = int(capacity if capacity is not None else count)
        self.count_texture = _count_texture(self._count) if count_texture is None else count_texture

    @property
    def count(self) -> int:
        if self._count is None:
            self._count = min(_read_count(self.count_texture), self.capacity)
        return self._count

    @property
    def known_count(self) -> int | None:
        """The count when known without a read-back (uploaded, or read before), else None."""
        return self._count

    def free(self) -> None:
        if self.isms is not None:
            self.isms.free()
        self.table = self.isms = self.map_origins = self.count_texture = None


def _count_texture(count: int):
    """A 1x1 R32UI texture holding ``count`` (integer textures take no Python data: cleared to it)."""
    import gpu

    texture = gpu.types.GPUTexture((1, 1), format="R32UI")
    texture.clear(format="UINT", value=(int(count),))
    return texture


def _read_count(texture) -> int:
    """The one uint of a 1x1 R32UI texture, read back (counted as a read-back of 4 bytes)."""
    RoundTrips.read_backs += 1
    RoundTrips.read_back_bytes += 4
    return int(_read_uint(texture, 1, 1)[0, 0])


def upload_vpls(vpls) -> VPLSet:
    return VPLSet(texture_from_array(vpl_table(vpls)), int(len(vpls["roughness"])))


#: VPL visibility (light-paths.md: every technique's light is shadowed). 004 §7 omits it; we give
#: each cluster of VPLs, the texels of one CLUSTER_TEXELS² block of one RSM view, one imperfect shadow
#: map (000 §5's ISMs, passes/ism.py) at the cluster's flux-weighted mean moved off its surface
#: (reference.ism.shadow_origin, as a VSGL's), leaving out its own reflector's points (within
#: pipeline.OWN_REFLECTOR_SIGMAS σ, and the half-space of cluster_planes; the maths:
#: reference/vpl_clusters.py). Why not the maps of the VSGLs: the diffuse receivers' VSGLs hold no
#: sharp reflector's specular flux, so a metal panel has no VSGL of its own there; and a map per VPL
#: (tens of thousands) is too many. A block is a few centimetres of reflector at the suite's sizes, so
#: its map's origin is near each VPL; benchmarks/vpl_visibility.py measures the error against
#: ray-cast visibility (its occluded caustic: relative RMSE 1.05 against the unshadowed image's 1.97;
#: polished_metal_floor, where nearly nothing is occluded: 0.33 against 0.01).
CLUSTER_TEXELS = _clusters.CLUSTER_TEXELS
CLUSTER_PLANE_SLACK = _clusters.CLUSTER_PLANE_SLACK
cluster_planes = _clusters.cluster_planes


def vpl_clusters(vpls, view_size: int):
    """(cluster per VPL, origins (C, 3), σ (C,), half-spaces (C, 4)) of the occupied clusters of the
    VPLs of scene_vpls, in map order (the float64 reference of the GPU's cluster table,
    reference.vpl_clusters.vpl_cluster_origins, without its empty maps): the texels of one
    CLUSTER_TEXELS² block of one view form a cluster; its origin is the Φ-weighted mean position
    moved off the surface along the mean normal (reference.ism.shadow_origin), its map's half-space
    that of :func:`cluster_planes`."""
    from ..reference.ism import shadow_origin

    keys, cluster = np.unique(_clusters.vpl_cluster_map(vpls["texel"], vpls["view"], view_size),
                              return_inverse=True)
    mean, variance, axis, _ = _clusters.cluster_statistics(vpls, cluster, len(keys))
    origins = shadow_origin(mean, variance, axis)
    return cluster, origins, np.sqrt(variance), cluster_planes(vpls["position"], cluster, origins, axis)


def upload_visible_vpls(vpls, scene_gpu, settings, view_size: int, first_map: int = 0) -> VPLSet:
    """:func:`upload_vpls` with the clusters' imperfect shadow maps (settings.ism_size, ism_points),
    made on the CPU from VPLs read back (tests, benchmarks/vpl_visibility.py; the renderer makes them
    on the GPU, :func:`extract_vpls` with ``shadows``)."""
    from ..pipeline import OWN_REFLECTOR_SIGMAS, POINT_SETS
    from ..scene_points import triangle_areas
    from . import ism

    if len(vpls["roughness"]) == 0:
        return upload_vpls(vpls)
    cluster, origins, sigma, planes = vpl_clusters(vpls, view_size)
    vpls = dict(vpls, map=cluster.astype(np.float64))
    points = scene_gpu.scene_points(settings.ism_points, POINT_SETS, settings.seed)
    point_area = float(triangle_areas(scene_gpu.scene.geometry.positions).sum()) / settings.ism_points
    maps = np.arange(first_map, first_map + len(origins))
    # The VSGL maps' point sets on the GPU (kept across the viewport's builds), not a second upload.
    textures = scene_gpu.point_textures(settings.ism_points, POINT_SETS, settings.seed)
    atlas = ism.PASS.run(points, origins, maps % POINT_SETS, ism.fitting_size(len(origins), settings.ism_size),
                         min_distance=OWN_REFLECTOR_SIGMAS * sigma, point_area=point_area, planes=planes,
                         point_textures=textures)
    # One row, map m in column m (the shader's texelFetch(vpl_map_origins, ivec2(m, 0))).
    table = np.zeros((1, len(origins), 4), np.float32)
    table[0, :, :3] = origins
    return VPLSet(texture_from_array(vpl_table(vpls)), int(len(vpls["roughness"])), atlas, texture_from_array(table))


def scene_vpls(scene_gpu, rsm_size: int, caustic_roughness: float) -> dict:
    """The glossy VPLs of every light read back to the CPU (004 §3; the float64 twin
    reference.vpl_culling.extract_glossy_vpls of :func:`extract_vpls`): each RSM texel of a sharp
    reflector (GGX α < α_c, reference.principled.principled_alpha as the RSM's split tests it) seen
    by diffuse rays, with its Φ Rs and ω_i towards the light, and its texel and view (the VPLs'
    shadow-map clusters, the command line's export). The RSM views are read back and dropped;
    nothing is resampled, so the set is as stable as the RSM."""
    from ..reference import vpl_culling as reference
    from .rsm import render_rsm_views

    parts = []
    views_done = 0
    for index, light in enumerate(scene_gpu.scene.lights):
        for view in render_rsm_views(scene_gpu, index, rsm_size, "diffuse"):
            slots = [read_texture(view.textures[name], rsm_size, rsm_size) for name in EXTRACTION_SLOTS]
            view.free()
            records, texels = reference.extract_glossy_vpls(*slots, reference.light_vector(light), caustic_roughness)
            parts.append(dict(_records_to_vpls(records), texel=texels, view=np.full(len(texels), views_done)))
            views_done += 1
    merged = {key: np.concatenate([part[key] for part in parts]) if parts else np.zeros((0, 3))
              for key in ("position", "normal", "incoming", "flux", "rs")}
    for key in ("roughness", "texel", "view"):
        merged[key] = np.concatenate([part[key] for part in parts]) if parts else np.zeros(0, np.int64)
    return merged


#: The RSM slots a VPL is made from (layouts.RSM): q, n + Principled roughness, Φ Rs.
EXTRACTION_SLOTS = ("position", "normal", "flux_specular")


def _records_to_vpls(records) -> dict:
    """The VPL dict (scene_vpls' fields; rs = 1, Φ Rs in flux) of (K, 4, 4) table records."""
    records = np.asarray(records, np.float64)
    return {"position": records[:, 0, :3], "roughness": records[:, 0, 3], "normal": records[:, 1, :3],
            "incoming": records[:, 2, :3], "flux": records[:, 3, :3], "rs": np.ones_like(records[:, 3, :3])}


def read_vpls(vpl_set: VPLSet) -> dict:
    """The VPLs of a set read back (tests, benchmarks): scene_vpls' fields without texel and view."""
    count = vpl_set.count
    rows = vpl_set.table.height
    table = read_texture(vpl_set.table, TABLE_WIDTH, rows).astype(np.float64)
    records = table.reshape(rows // 4, 4, TABLE_WIDTH, 4).transpose(0, 2, 1, 3).reshape(-1, 4, 4)[:count]
    return _records_to_vpls(records)


#: Texels one invocation of the GPU extraction walks (a run, in row-major order), the work group
#: of its scan, and the width of its run tables.
EXTRACT_RUN = 16
SCAN_GROUP = 256
RUN_TABLE_WIDTH = 1024


def _extract_interface(write: bool) -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("IVEC4", "extract_sizes"), ("VEC4", "extract_light"), ("VEC4", "extract_params")],
        samplers=[("FLOAT_2D", "rsm_position"), ("FLOAT_2D", "rsm_normal"), ("FLOAT_2D", "rsm_flux_specular")],
        images=([("R32UI", "UINT_2D", "vpl_run_offsets"), ("RGBA32F", "FLOAT_2D", "vpl_table_out")] if write
                else [("R32UI", "UINT_2D", "vpl_run_counts")]),
        local_group_size=(64, 1, 1),
    )


def _scan_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("IVEC4", "scan_sizes")],
        images=[("R32UI", "UINT_2D", "vpl_run_counts"), ("R32UI", "UINT_2D", "vpl_run_offsets"),
                ("R32UI", "UINT_2D", "vpl_count")],
        local_group_size=(SCAN_GROUP, 1, 1),
        shared=f"shared uint prefix_sum_values[{SCAN_GROUP}];",
    )


def empty_vpl_set(capacity: int) -> VPLSet:
    """A VPL set of no VPLs with room for ``capacity`` (the table's contents undefined past the count)."""
    import gpu

    rows = max(1, math.ceil(int(capacity) / TABLE_WIDTH))
    table = gpu.types.GPUTexture((TABLE_WIDTH, 4 * rows), format="RGBA32F")
    return VPLSet(table, None, count_texture=_count_texture(0), capacity=int(capacity))


def extract_view(vpl_set: VPLSet, textures, size: int, light, caustic_roughness: float, view_index: int = -1) -> None:
    """Append the glossy VPLs of one RSM view to ``vpl_set`` on the GPU, in row-major texel order
    after the VPLs already in it (glsl/vpl_culling/vpl_extract.comp.glsl: the kept texels per run, the
    scan of vpl_extract_scan.comp.glsl, then the records). ``textures``: the view's RSM slots by name
    (EXTRACTION_SLOTS), ``size`` its side; ``light`` (x, y, z, w) of reference light_vector.
    ``view_index`` ≥ 0 (the view's place among the frame's VPL views): each record gets its VPL's
    shadow map (reference.vpl_clusters.vpl_cluster_map). Nothing is read back; the set's count stays
    on the GPU."""
    import gpu

    size = int(size)
    runs = math.ceil(size * size / EXTRACT_RUN)
    run_table = (min(runs, RUN_TABLE_WIDTH), math.ceil(runs / RUN_TABLE_WIDTH))
    counts = gpu.types.GPUTexture(run_table, format="R32UI")
    offsets = gpu.types.GPUTexture(run_table, format="R32UI")
    groups = math.ceil(runs / 64)
    for key in ("extract_count", "extract_write"):
        shader = PASS.shader(key)
        shader.bind()
        shader.uniform_int("extract_sizes", (size, vpl_set.capacity, TABLE_WIDTH, RUN_TABLE_WIDTH))
        # The count stage keeps no record: the compiler drops the light, whose only use is w_i.
        set_uniform(shader.uniform_float, "extract_light", tuple(float(v) for v in light))
        shader.uniform_float("extract_params", (float(caustic_roughness), float(view_index), 0.0, 0.0))
        for name in EXTRACTION_SLOTS:
            shader.uniform_sampler(f"rsm_{name}", textures[name])
        if key == "extract_count":
            shader.image("vpl_run_counts", counts)
            gpu.compute.dispatch(shader, groups, 1, 1)
            scan = PASS.shader("extract_scan")
            scan.bind()
            scan.uniform_int("scan_sizes", (runs, RUN_TABLE_WIDTH, 0, 0))
            scan.image("vpl_run_counts", counts)
            scan.image("vpl_run_offsets", offsets)
            scan.image("vpl_count", vpl_set.count_texture)
            gpu.compute.dispatch(scan, 1, 1, 1)
        else:
            shader.image("vpl_run_offsets", offsets)
            shader.image("vpl_table_out", vpl_set.table)
            gpu.compute.dispatch(shader, groups, 1, 1)


def _cluster_interface() -> ShaderInterface:
    side = CLUSTER_TEXELS * CLUSTER_TEXELS
    return ShaderInterface(
        push_constants=[("IVEC4", "cluster_sizes"), ("VEC4", "cluster_light"), ("VEC4", "cluster_params")],
        samplers=[("FLOAT_2D", "rsm_position"), ("FLOAT_2D", "rsm_normal"), ("FLOAT_2D", "rsm_flux_specular")],
        images=[("RGBA32F", "FLOAT_2D", "ism_origins")],
        local_group_size=(CLUSTER_TEXELS, CLUSTER_TEXELS, 1),
        shared=f"shared vec4 cluster_sums_a[{side}]; shared vec4 cluster_sums_b[{side}];",
    )


def _cluster_sets_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("IVEC4", "cluster_set_params")],
        images=[("RGBA32F", "FLOAT_2D", "ism_origins")],
        local_group_size=(SCAN_GROUP, 1, 1),
        shared=f"shared uint prefix_sum_values[{SCAN_GROUP}];",
    )


def _cluster_defines() -> dict:
    return {"VPL_CLUSTER_TEXELS": CLUSTER_TEXELS,
            "VPL_CLUSTER_WEIGHT_FLOOR": repr(float(_clusters.CLUSTER_WEIGHT_FLOOR)),
            "VPL_EMPTY_CLUSTER_DISTANCE": repr(float(_clusters.EMPTY_CLUSTER_DISTANCE))}


def cluster_view(origins, textures, size: int, light, caustic_roughness: float, view_index: int,
                 own_reflector_sigmas: float) -> None:
    """Write the splat's table of the maps of one RSM view's VPL clusters into ``origins`` (a
    passes/ism.py MapOrigins; columns vpl_cluster_map of ``view_index``), on the GPU
    (glsl/vpl_culling/vpl_clusters.comp.glsl: a work group per block; twin
    reference.vpl_clusters.vpl_cluster_origins). The point sets follow in :func:`cluster_sets`."""
    import gpu

    blocks = _clusters.cluster_blocks(size)
    shader = PASS.shader("clusters")
    shader.bind()
    shader.uniform_int("cluster_sizes", (int(size), int(view_index), 0, 0))
    # The clusters use no w_i: the compiler drops the light, its only use.
    set_uniform(shader.uniform_float, "cluster_light", tuple(float(v) for v in light))
    shader.uniform_float("cluster_params", (float(caustic_roughness), float(own_reflector_sigmas),
                                            float(CLUSTER_PLANE_SLACK), 0.0))
    for name in EXTRACTION_SLOTS:
        shader.uniform_sampler(f"rsm_{name}", textures[name])
    shader.image("ism_origins", origins.texture)
    gpu.compute.dispatch(shader, blocks, blocks, 1)


def cluster_sets(origins, first_map: int, point_sets: int) -> None:
    """Give every map of ``origins`` its point set, (first map + occupied maps before it) mod
    ``point_sets`` (glsl/vpl_culling/vpl_cluster_sets.comp.glsl, one work group), once every view's
    :func:`cluster_view` ran."""
    import gpu

    if origins.count:
        shader = PASS.shader("cluster_sets")
        shader.bind()
        shader.uniform_int("cluster_set_params", (int(origins.count), int(first_map), int(point_sets), 0))
        shader.image("ism_origins", origins.texture)
        gpu.compute.dispatch(shader, 1, 1, 1)


def extract_vpls(scene_gpu, rsm_size: int, caustic_roughness: float, shadows=None, first_map: int = 0) -> VPLSet:
    """:func:`extract_vpls_stages` at once."""
    from .contract import run_stages

    return run_stages(extract_vpls_stages(scene_gpu, rsm_size, caustic_roughness, shadows, first_map))


def extract_vpls_stages(scene_gpu, rsm_size: int, caustic_roughness: float, shadows=None, first_map: int = 0):
    """A generator that yields after each RSM view's VPLs and between the clusters' shadow maps'
    stages (passes/ism.py build_ism_atlas_stages) and returns the VPLSet: the viewport spreads a light
    build over steps of its time budget. The glossy VPLs of every light made on the GPU (004 §3): :func:`scene_vpls`' set, in its
    order, without a read-back. Each light's RSM views (seen by diffuse rays) are rendered, turned
    into VPLs by :func:`extract_view` and dropped. The table has room for every texel of the views
    (64 bytes a texel, 4/5 of the RSM's colour attachments), since the count stays on the GPU.
    ``shadows`` (a VSGLSettings: ism_size, ism_points, seed): with the clusters' imperfect shadow
    maps, their table made on the GPU from each view (:func:`cluster_view`, :func:`cluster_sets`;
    the twin of :func:`upload_visible_vpls`' maps, point sets from ``first_map``), so nothing is read
    back either. The atlas holds a map per block of every view (blocks² a view), empty where a block
    has no VPL: sized so, it needs no count from the GPU."""
    from ..reference.vpl_culling import light_vector
    from .rsm import render_rsm_views, visible_view_specs

    lights = scene_gpu.scene.lights
    specs = [visible_view_specs(scene_gpu, light) for light in lights]
    views = sum(map(len, specs))
    vpl_set = empty_vpl_set(views * int(rsm_size) ** 2)
    origins = None
    if shadows is not None:
        import gpu

        from ..pipeline import OWN_REFLECTOR_SIGMAS
        from .ism import MapOrigins

        maps = views * _clusters.cluster_blocks(rsm_size) ** 2
        origins = MapOrigins(gpu.types.GPUTexture((max(maps, 1), 3), format="RGBA32F"), maps)
    view_index = 0
    try:
        for index, light in enumerate(lights):
            for view in render_rsm_views(scene_gpu, index, rsm_size, "diffuse", specs=specs[index]):
                if view_index:
                    yield
                extract_view(vpl_set, view.textures, rsm_size, light_vector(light), caustic_roughness,
                             view_index if origins is not None else -1)
                if origins is not None:
                    cluster_view(origins, view.textures, rsm_size, light_vector(light), caustic_roughness,
                                 view_index, OWN_REFLECTOR_SIGMAS)
                view.free()
                view_index += 1
        if origins is not None and origins.count:
            yield
            vpl_set.isms = yield from _cluster_maps_stages(scene_gpu, shadows, origins, first_map)
            vpl_set.map_origins = origins.texture
    except BaseException:
        vpl_set.free()
        raise
    return vpl_set


def _cluster_maps_stages(scene_gpu, settings, origins, first_map: int):
    """The ISM atlas of the clusters' maps of ``origins`` (settings.ism_size, ism_points), in the
    stages of passes/ism.py build_ism_atlas_stages."""
    from ..pipeline import POINT_SETS
    from ..scene_points import triangle_areas
    from . import ism

    cluster_sets(origins, first_map, POINT_SETS)
    points = scene_gpu.scene_points(settings.ism_points, POINT_SETS, settings.seed)
    point_area = float(triangle_areas(scene_gpu.scene.geometry.positions).sum()) / settings.ism_points
    # The VSGL maps' point sets on the GPU (kept across the viewport's builds), not a second upload.
    textures = scene_gpu.point_textures(settings.ism_points, POINT_SETS, settings.seed)
    return (yield from ism.build_ism_atlas_stages(points, origins, None, ism.fitting_size(origins.count, settings.ism_size),
                                                  point_area=point_area, point_textures=textures))


def vpl_table(vpls) -> np.ndarray:
    """The (4 ceil(n / W), W, 4) float32 table of the VPL records (see the stage's header)."""
    count = len(vpls["roughness"])
    rows = max(1, math.ceil(count / TABLE_WIDTH))
    records = np.zeros((4, rows * TABLE_WIDTH, 4), np.float32)
    scalar_flux = np.max(vpls["flux"] * vpls["rs"], axis=-1)
    records[0, :count, :3], records[0, :count, 3] = vpls["position"], vpls["roughness"]
    records[1, :count, :3], records[1, :count, 3] = vpls["normal"], scalar_flux
    records[2, :count, :3] = vpls["incoming"]
    records[3, :count, :3] = vpls["flux"] * vpls["rs"]
    if "map" in vpls:
        records[3, :count, 3] = vpls["map"]
    # Record k of row block b lands in texture row 4 b + k.
    return records.reshape(4, rows, TABLE_WIDTH, 4).transpose(1, 0, 2, 3).reshape(4 * rows, TABLE_WIDTH, 4)


@dataclass
class VPLCullingResult:
    radiance: object
    lists: object
    counts: object
    size: tuple[int, int]
    tiles: tuple[int, int]
    vpls: VPLSet

    @property
    def vpl_count(self) -> int:
        return self.vpls.count

    def read(self) -> np.ndarray:
        return read_texture(self.radiance, *self.size)

    def read_counts(self) -> np.ndarray:
        return _read_uint(self.counts, *self.tiles)

    def read_lists(self) -> np.ndarray:
        """(tiles, capacity) listed indices; entries past a tile's count are undefined."""
        return _read_uint(self.lists, LIST_CAPACITY, self.tiles[0] * self.tiles[1])

    def free(self) -> None:
        self.radiance = self.lists = self.counts = self.vpls = None


def _read_uint(texture, width: int, height: int) -> np.ndarray:
    buffer = texture.read()
    buffer.dimensions = width * height
    return np.array(buffer, dtype=np.uint32).reshape(height, width)


#: Interleaved sampling factors N (N x N sub-images, 004 section 6).
INTERLEAVE_FACTORS = (1, 2, 4, 8)


def run(position, normal, albedo, vpls, world_to_view, projection, delta: float, seed: int = 0,
        frame: int = 0, interleave: int = 1, interleave_offset: int = 0, stride: int = 1) -> VPLCullingResult:
    """Cull and shade ``vpls`` for the receivers in the three (width, height) textures; ``seed`` and
    ``frame`` draw the VPLs' xi, ``interleave`` N and ``interleave_offset`` choose each pixel's
    subset (progressive rendering steps both). ``stride`` S > 1: only every S-th VPL, weighted S
    (reference.vpl_culling.strided_vpls; the viewport's coarse preview)."""
    if interleave not in INTERLEAVE_FACTORS:
        raise ValueError(f"interleave must be one of {INTERLEAVE_FACTORS}, got {interleave}")
    import gpu

    width, height = position.width, position.height
    tiles = (math.ceil(width / TILE), math.ceil(height / TILE))
    vpl_set = vpls if isinstance(vpls, VPLSet) else upload_vpls(vpls)
    # Rows: world-to-view, inverse projection (the tile frustum's corners), projection (its side
    # planes, reference.vpl_culling.tile_frustum_planes).
    camera = np.zeros((12, 1, 4), np.float32)
    camera[:4, 0] = np.asarray(world_to_view, np.float64)
    camera[4:8, 0] = np.linalg.inv(np.asarray(projection, np.float64))
    camera[8:, 0] = np.asarray(projection, np.float64)
    table = vpl_set.table
    camera_texture = texture_from_array(camera)
    radiance = gpu.types.GPUTexture((width, height), format="RGBA32F")
    lists = gpu.types.GPUTexture((LIST_CAPACITY, tiles[0] * tiles[1]), format="R32UI")
    lists.clear(format="UINT", value=(-1,))
    counts = gpu.types.GPUTexture(tiles, format="R32UI")
    visible = vpl_set.isms is not None
    shader = PASS.shader("vpl_culling_visible" if visible else "vpl_culling")
    shader.bind()
    if visible:
        shader.uniform_int("ism_params", (vpl_set.isms.size, vpl_set.isms.columns, 0, 0))
        shader.uniform_sampler("ism_atlas", vpl_set.isms.texture)
        shader.image("vpl_map_origins", vpl_set.map_origins)
    shader.uniform_float("vpl_params", (float(delta), 0.0, float(seed), float(frame)))
    shader.uniform_int("vpl_sizes", (TABLE_WIDTH, LIST_CAPACITY, tiles[0], tiles[1]))
    shader.uniform_int("vpl_interleave", (int(interleave), int(interleave_offset), vpl_set.capacity,
                                          max(int(stride), 1)))
    shader.uniform_sampler("vpl_count", vpl_set.count_texture)
    shader.image("gbuffer_position", position)
    shader.image("gbuffer_normal", normal)
    shader.image("receiver_albedo", albedo)
    shader.image("vpl_table", table)
    shader.uniform_sampler("vpl_camera", camera_texture)
    shader.image("vpl_radiance", radiance)
    shader.image("vpl_tile_lists", lists)
    shader.image("vpl_tile_counts", counts)
    gpu.compute.dispatch(shader, tiles[0], tiles[1], 1)
    return VPLCullingResult(radiance, lists, counts, (width, height), tiles, vpl_set)


def render_caustics(position, normal, albedo, vpls, world_to_view, projection, delta: float, *, samples: int = 1,
                    interleave: int = 1, radius: int = 0, seed: int = 0, frame: int = 0) -> np.ndarray:
    """The progressive VPL image, read back (h, w, 4): the mean of ``samples`` culled frames (each its
    own xi draw and interleave offset; noise falls as 1/sqrt(S) towards the unbiased result), then
    the cross-bilateral filter of ``radius`` (0: none)."""
    total = None
    eye = np.linalg.inv(np.asarray(world_to_view, np.float64))[:3, 3]
    for step in range(max(int(samples), 1)):
        result = run(position, normal, albedo, vpls, world_to_view, projection, delta, seed,
                     frame * max(int(samples), 1) + step, interleave, step % (interleave * interleave))
        image = read_texture(denoise(result.radiance, position, normal, radius, eye), *result.size)
        result.free()
        total = image.astype(np.float64) if total is None else total + image
    return (total / max(int(samples), 1)).astype(np.float32)


#: The VPLs' extraction from the RSM (extract_vpls, once per scene state, a light pass rather than a
#: pass of the frame's list; the renderer's SceneLights.build times it), and the count it is the source of.
EXTRACTION = Step("vpl_extraction", "VPL Extraction + Shadow Maps", {"vpls": "VPLs"})


class VPLCaustics:
    """The pass in a frame (renderer.py): its caustics image and the indirect diffuse image with it
    added, kept between views (the next view overwrites them)."""

    def __init__(self):
        self.caustics = None
        self.diffuse = None

    def free(self) -> None:
        self.caustics = self.diffuse = None

    def render(self, inputs, vpl_set: VPLSet, world_to_view, projection, settings, vsgl_diffuse,
               count: bool = False, stride: int = 1) -> float | None:
        """Cull and shade ``vpl_set`` for ``inputs`` (a vsgl_shading.ShadingGBuffer): the mean of
        ``settings.vpl_samples`` draws (xi from the seed and the sample's number, the interleave
        offset stepping with them), then the cross-bilateral filter, into ``self.caustics``; and
        ``vsgl_diffuse`` + caustics into ``self.diffuse``, all on the GPU. ``count``: returns the VPLs
        each pixel shaded after culling (tile lists read back, divided by N²), else None. ``stride``:
        every stride-th VPL alone, weighted stride (the viewport's coarse preview, run())."""
        from ..settings import interleave_factor

        width, height = inputs.width, inputs.height
        factor = interleave_factor(settings.vpl_interleave, width, height)
        samples = max(int(settings.vpl_samples), 1)
        total = None
        listed = 0.0
        for step in range(samples):
            result = run(inputs.position, inputs.normal, inputs.diffuse_reflectance, vpl_set, world_to_view,
                         projection, settings.delta, settings.seed, step, factor,
                         (settings.seed * samples + step) % (factor * factor), stride)
            if count:
                listed += float((result.read_counts() * _tile_pixels(width, height)).sum()) / (width * height)
            total = (result.radiance if samples == 1 else
                     add_textures(result.radiance, result.radiance, 1.0 / samples, 0.0) if total is None else
                     add_textures(total, result.radiance, 1.0, 1.0 / samples))
            result.free()
        eye = np.linalg.inv(np.asarray(world_to_view, np.float64))[:3, 3]
        self.caustics = denoise(total, inputs.position, inputs.normal, settings.vpl_filter_radius, eye)
        self.diffuse = add_textures(vsgl_diffuse, self.caustics, 1.0, 1.0)
        return listed / samples / (factor * factor) if count else None


def _tile_pixels(width: int, height: int) -> np.ndarray:
    """(tiles_y, tiles_x) pixels of each tile inside the image."""
    columns = np.minimum(TILE, width - TILE * np.arange(math.ceil(width / TILE)))
    rows = np.minimum(TILE, height - TILE * np.arange(math.ceil(height / TILE)))
    return rows[:, None] * columns[None, :]


PASS = GPUPass(
    name="vpl_culling",
    label="Caustics (VPL)",
    step=Step("vpl_culling", "Caustics (VPL)", {"vpls_per_pixel": "VPLs per Pixel"}),
    shaders={"vpl_culling": ShaderSpec(_interface, {"compute": "vpl_culling/vpl_cull_shade.comp.glsl"},
                                       defines=lambda: {"VPL_VISIBILITY": 0}),
             "vpl_culling_visible": ShaderSpec(lambda: _interface(True),
                                               {"compute": "vpl_culling/vpl_cull_shade.comp.glsl"},
                                               defines=lambda: {"VPL_VISIBILITY": 1}),
             "denoise": ShaderSpec(_denoise_interface, {"compute": "vpl_culling/vpl_denoise.comp.glsl"}),
             "add": ShaderSpec(_add_interface, {"compute": "vpl_culling/vpl_add.comp.glsl"}),
             "extract_count": ShaderSpec(lambda: _extract_interface(False), {"compute": "vpl_culling/vpl_extract.comp.glsl"},
                                         defines=lambda: {"VPL_EXTRACT_WRITE": 0, "VPL_EXTRACT_RUN": EXTRACT_RUN,
                                                          **_cluster_defines()}),
             "extract_write": ShaderSpec(lambda: _extract_interface(True), {"compute": "vpl_culling/vpl_extract.comp.glsl"},
                                         defines=lambda: {"VPL_EXTRACT_WRITE": 1, "VPL_EXTRACT_RUN": EXTRACT_RUN,
                                                          **_cluster_defines()}),
             "clusters": ShaderSpec(_cluster_interface, {"compute": "vpl_culling/vpl_clusters.comp.glsl"},
                                    defines=_cluster_defines),
             "cluster_sets": ShaderSpec(_cluster_sets_interface, {"compute": "vpl_culling/vpl_cluster_sets.comp.glsl"},
                                        defines=lambda: {"PREFIX_SUM_SIZE": SCAN_GROUP}),
             "extract_scan": ShaderSpec(_scan_interface, {"compute": "vpl_culling/vpl_extract_scan.comp.glsl"},
                                        defines=lambda: {"PREFIX_SUM_SIZE": SCAN_GROUP})},
    reads=(GBUFFER.name, SHADING_INPUTS.name, RSM.name),
    writes=("indirect_caustics",),
    run=run,
)
