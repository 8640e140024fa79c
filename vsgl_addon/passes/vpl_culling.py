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

``vpls`` is the dict of :func:`vsgl_addon.reference.vpl_culling.glossy_vpls_from_rsm`. Receivers:
world position (w = coverage > 0), world normal and diffuse reflectance textures of one size.
Output RGBA32F radiance, W/(m^2 sr), unshadowed. Needs a GPU context, main thread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..shaders import ShaderInterface
from .contract import GPUPass, ShaderSpec, Step
from .gpu_util import read_texture, texture_from_array

TILE = 16
#: VPL records per table row (the table is TABLE_WIDTH wide, four rows per record row).
TABLE_WIDTH = 1024
#: Listed indices kept per tile in the R32UI list image (shading is exact beyond it: chunked).
LIST_CAPACITY = 1024


def _interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("VEC4", "vpl_params"), ("IVEC4", "vpl_sizes"), ("IVEC4", "vpl_interleave")],
        samplers=[("FLOAT_2D", "gbuffer_position"), ("FLOAT_2D", "gbuffer_normal"),
                  ("FLOAT_2D", "receiver_albedo"), ("FLOAT_2D", "vpl_table"), ("FLOAT_2D", "vpl_camera")],
        images=[("RGBA32F", "FLOAT_2D", "vpl_radiance"), ("R32UI", "UINT_2D", "vpl_tile_lists"),
                ("R32UI", "UINT_2D", "vpl_tile_counts")],
        local_group_size=(TILE, TILE, 1),
        shared="shared uint tile_depth_min; shared uint tile_depth_max; shared uint tile_covered; "
               "shared uint tile_total; shared uint chunk_count; shared uint chunk_list[256];",
    )


def _denoise_interface() -> ShaderInterface:
    return ShaderInterface(
        push_constants=[("IVEC4", "denoise_params"), ("VEC4", "denoise_eye")],
        samplers=[("FLOAT_2D", "vpl_noisy"), ("FLOAT_2D", "gbuffer_position"), ("FLOAT_2D", "gbuffer_normal")],
        images=[("RGBA32F", "FLOAT_2D", "vpl_denoised")],
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
    shader.uniform_sampler("vpl_noisy", radiance)
    shader.uniform_sampler("gbuffer_position", position)
    shader.uniform_sampler("gbuffer_normal", normal)
    shader.image("vpl_denoised", out)
    gpu.compute.dispatch(shader, math.ceil(radiance.width / 8), math.ceil(radiance.height / 8), 1)
    return out


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
    # Record k of row block b lands in texture row 4 b + k.
    return records.reshape(4, rows, TABLE_WIDTH, 4).transpose(1, 0, 2, 3).reshape(4 * rows, TABLE_WIDTH, 4)


@dataclass
class VPLCullingResult:
    radiance: object
    lists: object
    counts: object
    size: tuple[int, int]
    tiles: tuple[int, int]
    vpl_count: int

    def read(self) -> np.ndarray:
        return read_texture(self.radiance, *self.size)

    def read_counts(self) -> np.ndarray:
        return _read_uint(self.counts, *self.tiles)

    def read_lists(self) -> np.ndarray:
        """(tiles, capacity) listed indices; entries past a tile's count are undefined."""
        return _read_uint(self.lists, LIST_CAPACITY, self.tiles[0] * self.tiles[1])

    def free(self) -> None:
        self.radiance = self.lists = self.counts = None


def _read_uint(texture, width: int, height: int) -> np.ndarray:
    buffer = texture.read()
    buffer.dimensions = width * height
    return np.array(buffer, dtype=np.uint32).reshape(height, width)


#: Interleaved sampling factors N (N x N sub-images, 004 section 6).
INTERLEAVE_FACTORS = (1, 2, 4, 8)


def run(position, normal, albedo, vpls, world_to_view, projection, delta: float, seed: int = 0,
        frame: int = 0, interleave: int = 1, interleave_offset: int = 0) -> VPLCullingResult:
    """Cull and shade ``vpls`` for the receivers in the three (width, height) textures; ``seed`` and
    ``frame`` draw the VPLs' xi, ``interleave`` N and ``interleave_offset`` choose each pixel's
    subset (progressive rendering steps both)."""
    if interleave not in INTERLEAVE_FACTORS:
        raise ValueError(f"interleave must be one of {INTERLEAVE_FACTORS}, got {interleave}")
    import gpu

    width, height = position.width, position.height
    tiles = (math.ceil(width / TILE), math.ceil(height / TILE))
    count = len(vpls["roughness"])
    camera = np.zeros((8, 1, 4), np.float32)
    camera[:4, 0] = np.asarray(world_to_view, np.float64)
    camera[4:, 0] = np.linalg.inv(np.asarray(projection, np.float64))
    table = texture_from_array(vpl_table(vpls))
    camera_texture = texture_from_array(camera)
    radiance = gpu.types.GPUTexture((width, height), format="RGBA32F")
    lists = gpu.types.GPUTexture((LIST_CAPACITY, tiles[0] * tiles[1]), format="R32UI")
    lists.clear(format="UINT", value=(-1,))
    counts = gpu.types.GPUTexture(tiles, format="R32UI")
    shader = PASS.shader("vpl_culling")
    shader.bind()
    shader.uniform_float("vpl_params", (float(delta), float(count), float(seed), float(frame)))
    shader.uniform_int("vpl_sizes", (TABLE_WIDTH, LIST_CAPACITY, tiles[0], tiles[1]))
    shader.uniform_int("vpl_interleave", (int(interleave), int(interleave_offset), 0, 0))
    shader.uniform_sampler("gbuffer_position", position)
    shader.uniform_sampler("gbuffer_normal", normal)
    shader.uniform_sampler("receiver_albedo", albedo)
    shader.uniform_sampler("vpl_table", table)
    shader.uniform_sampler("vpl_camera", camera_texture)
    shader.image("vpl_radiance", radiance)
    shader.image("vpl_tile_lists", lists)
    shader.image("vpl_tile_counts", counts)
    gpu.compute.dispatch(shader, tiles[0], tiles[1], 1)
    return VPLCullingResult(radiance, lists, counts, (width, height), tiles, count)


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


PASS = GPUPass(
    name="vpl_culling",
    label="Caustics (VPL)",
    step=Step("vpl_culling", "Caustics (VPL)", {"vpls": "VPLs", "vpls_per_pixel": "VPLs per Pixel"}),
    shaders={"vpl_culling": ShaderSpec(_interface, {"compute": "vpl_culling/vpl_cull_shade.comp.glsl"}),
             "denoise": ShaderSpec(_denoise_interface, {"compute": "vpl_culling/vpl_denoise.comp.glsl"})},
    reads=(),
    writes=(),
    run=run,
)
