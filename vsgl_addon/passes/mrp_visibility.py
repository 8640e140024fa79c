# SPDX-License-Identifier: GPL-3.0-or-later
"""Proxy-to-receiver visibility of MRP-ASG (001 assumes none): mirror shadow maps.

The light that MRP-ASG gathers at a receiver x travels light → specular peak p_y on the proxy →
x (001 Eq. 12). The light's own shadow map decides the first segment (the RSM depth at p_y, in
``mrp_asg.frag.glsl``). For the second one, the rectangle is a mirror: the ray from the light's
mirror image L' = L − 2 ((L − c)·n) n (a sun: its direction reflected) to x crosses the plane
exactly at p_y. So one depth map per light and lit proxy side, seen from L' through the rectangle
(an off-axis frustum around it, widened by the disk radius) and keeping only the geometry in front
of the plane (the fragment stage discards the rest), stores on that ray the first surface after
p_y: x is visible from p_y when the map's depth there is x's own (a shadow-map test of x, the
direct light's normal offset and slope-scaled bias, ``lib/shadow.glsl``).

What is shadowed, and what is not (docs/accuracy.md):
* shadowed: light → p_y (the light's RSM depth) and p_y → x (this map), for the peak ray only;
* not: the rest of the disk around p_y (its light is shadowed as its centre is), the shadow of an
  area light's extent (a point at its centre, as the RSM), geometry within ``PLANE_TOLERANCE`` of the
  scene's size above the plane (dropped with the plane itself), and shadow linking (every object
  blocks); a receiver whose peak lies outside the widened rectangle is not tested (its area ratio,
  001 Eq. 36, is 0 or nearly).

One atlas per light: a depth texture of (count × size) × size, tile i the i-th proxy the light
reaches (the order of the MRP-ASG pass's proxy table), and a constants texture of five RGBA texels
per tile (view-projection rows, then (perspective, P00, P22, P23) as ``direct_light.light_constants``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..views import box_corners, view_from_frame
from .contract import GPUPass, ShaderSpec, Step
from .gpu_util import matrix, texture_from_array
from .scene_gpu import VERTEX_STAGE, scene_shader_interface

#: Geometry closer to the proxy's plane than this fraction of the scene's bounding diagonal is not
#: drawn (the proxy's own triangles, coplanar to 1e-5 of it, proxies.PLANE_TOLERANCE).
PLANE_TOLERANCE = 1e-3


@dataclass(frozen=True)
class MirrorView:
    """One mirror view: world -> view, OpenGL projection (off-axis), perspective or orthographic."""

    view_matrix: np.ndarray
    projection_matrix: np.ndarray
    perspective: bool

    @property
    def view_projection(self) -> np.ndarray:
        return self.projection_matrix @ self.view_matrix


def off_axis_perspective(left, right, bottom, top, near, far) -> np.ndarray:
    """OpenGL frustum: the image plane at distance ``near`` spans [left, right] × [bottom, top]."""
    p = np.zeros((4, 4))
    p[0, 0] = 2.0 * near / (right - left)
    p[1, 1] = 2.0 * near / (top - bottom)
    p[0, 2] = (right + left) / (right - left)
    p[1, 2] = (top + bottom) / (top - bottom)
    p[2, 2] = -(far + near) / (far - near)
    p[2, 3] = -2.0 * far * near / (far - near)
    p[3, 2] = -1.0
    return p


def off_axis_orthographic(left, right, bottom, top, near, far) -> np.ndarray:
    p = np.eye(4)
    p[0, 0] = 2.0 / (right - left)
    p[1, 1] = 2.0 / (top - bottom)
    p[2, 2] = -2.0 / (far - near)
    p[0, 3] = -(right + left) / (right - left)
    p[1, 3] = -(top + bottom) / (top - bottom)
    p[2, 3] = -(far + near) / (far - near)
    return p


def mirror_view(proxy, light, bounds, margin: float = 0.0) -> MirrorView | None:
    """The view from ``light``'s mirror image in ``proxy``'s plane through the rectangle widened by
    ``margin`` metres on every side; ``bounds`` (lo, hi) of the scene set the far plane. None when
    the light is not in front of the lit side."""
    n = np.asarray(proxy.normal, np.float64)
    c = np.asarray(proxy.center, np.float64)
    u, v = np.asarray(proxy.axis_u, np.float64), np.asarray(proxy.axis_v, np.float64)
    hu, hv = proxy.half_u + margin, proxy.half_v + margin
    corners = np.array([c + a * hu * u + b * hv * v for a in (-1, 1) for b in (-1, 1)])
    scene = box_corners(*bounds)
    diagonal = max(float(np.linalg.norm(np.asarray(bounds[1]) - np.asarray(bounds[0]))), 1e-6)
    if light.type == "SUN":
        d = np.asarray(light.direction, np.float64)
        d /= np.linalg.norm(d)
        if not d @ n < 0.0:
            return None
        forward = d - 2.0 * (d @ n) * n  # the reflected travel direction, away from the plane
        helper = u if abs(u @ forward) < 0.9 else v
        x = helper - (helper @ forward) * forward
        x /= np.linalg.norm(x)
        rotation = np.stack([x, np.cross(-forward, x), -forward], axis=1)  # X, Y, Z = -forward
        view = view_from_frame(rotation, c)
        local = (np.c_[corners, np.ones(4)] @ view.T)[:, :3]
        depth = -(np.c_[scene, np.ones(len(scene))] @ view.T)[:, 2]
        near = float(-local[:, 2].max()) - 1e-3 * diagonal
        far = max(float(depth.max()), near + 1e-3 * diagonal) * 1.01 + 1e-3 * diagonal
        projection = off_axis_orthographic(local[:, 0].min(), local[:, 0].max(), local[:, 1].min(),
                                           local[:, 1].max(), near, far)
        return MirrorView(view, projection, False)
    light_position = np.asarray(light.position, np.float64)
    height = float((light_position - c) @ n)
    if not height > 0.0:
        return None
    mirror = light_position - 2.0 * height * n
    rotation = np.stack([u, -v, -n], axis=1)  # looking along +n: depth planes parallel to the proxy
    view = view_from_frame(rotation, mirror)
    local = (np.c_[corners, np.ones(4)] @ view.T)[:, :3]  # all at z = -height
    depth = -(np.c_[scene, np.ones(len(scene))] @ view.T)[:, 2]
    # Near just short of the plane (the fragment stage drops what lies behind it); far: the scene.
    near = height * (1.0 - 1e-3)
    far = max(float(depth.max()), height * 1.01) * 1.01
    scale = near / height
    projection = off_axis_perspective(local[:, 0].min() * scale, local[:, 0].max() * scale,
                                      local[:, 1].min() * scale, local[:, 1].max() * scale, near, far)
    return MirrorView(view, projection, True)


def mirror_constants(views) -> np.ndarray:
    """(1, 5 × count (at least 1), 4) float32: per view its view-projection rows and (perspective,
    P00, P22, P23); a view that is None gets a zero matrix (no receiver falls in it)."""
    constants = np.zeros((1, 5 * max(len(views), 1), 4), np.float32)
    for i, view in enumerate(views):
        if view is None:
            continue
        p = np.asarray(view.projection_matrix, np.float64)
        constants[0, 5 * i:5 * i + 4] = view.view_projection
        constants[0, 5 * i + 4] = (1.0 if view.perspective else 0.0, p[0, 0], p[2, 2], p[2, 3])
    return constants


def _interface():
    return scene_shader_interface(push_constants=[("VEC4", "plane")], samplers=[],
                                  fragment_outputs=[("VEC4", "mirror_unused")])


@dataclass
class MirrorMaps:
    """Per light index: the atlas (depth texture), its constants texture and the tile size."""

    size: int
    atlases: dict = field(default_factory=dict)  # light index -> (depth texture, constants texture)

    def free(self) -> None:
        self.atlases.clear()


def render_mirror_maps(scene_gpu, lit, size: int, margin: float) -> MirrorMaps:
    """The mirror shadow maps of every light and the proxies of ``lit`` ((proxy, mask) pairs) it
    reaches, in the order the MRP-ASG pass lists them (``[p for p, m in lit if m[light]]``)."""
    import gpu

    maps = MirrorMaps(int(size))
    scene = scene_gpu.scene
    if scene_gpu.batch is None or scene_gpu.bounds is None:
        return maps
    bounds = scene_gpu.bounds
    diagonal = max(float(np.linalg.norm(np.asarray(bounds[1]) - np.asarray(bounds[0]))), 1e-6)
    program = PASS.shader("mirror_depth")
    for index, light in enumerate(scene.lights):
        proxies = [proxy for proxy, mask in lit if mask[index]]
        if not proxies:
            continue
        views = [mirror_view(proxy, light, bounds, margin) for proxy in proxies]
        depth = gpu.types.GPUTexture((maps.size * len(proxies), maps.size), format="DEPTH_COMPONENT32F")
        colour = gpu.types.GPUTexture((maps.size * len(proxies), maps.size), format="R32F")
        framebuffer = gpu.types.GPUFrameBuffer(depth_slot=depth, color_slots=[colour])
        saved = (gpu.state.depth_test_get(), gpu.state.depth_mask_get(), tuple(gpu.state.viewport_get()),
                 gpu.state.blend_get())
        try:
            with framebuffer.bind():
                framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
                gpu.state.blend_set("NONE")
                gpu.state.depth_test_set("LESS")
                gpu.state.depth_mask_set(True)
                gpu.state.face_culling_set("NONE")
                program.bind()
                for i, (proxy, view) in enumerate(zip(proxies, views)):
                    if view is None:
                        continue
                    gpu.state.viewport_set(i * maps.size, 0, maps.size, maps.size)
                    n = np.asarray(proxy.normal, np.float64)
                    offset = float(n @ np.asarray(proxy.center, np.float64)) + PLANE_TOLERANCE * diagonal
                    program.uniform_float("view_projection", matrix(view.view_projection))
                    program.uniform_float("plane", (*n, offset))
                    scene_gpu.batch.draw(program)  # depth only: every material at once
        finally:
            gpu.state.depth_test_set(saved[0])
            gpu.state.depth_mask_set(saved[1])
            gpu.state.viewport_set(*saved[2])
            gpu.state.blend_set(saved[3])
        maps.atlases[index] = (depth, texture_from_array(mirror_constants(views)))
    return maps


PASS = GPUPass(
    name="mrp_visibility",
    label="Glossy Reflector Shadows",
    step=Step("mrp_visibility", "Glossy Reflector Shadows"),
    shaders={"mirror_depth": ShaderSpec(_interface, {"vertex": VERTEX_STAGE,
                                                     "fragment": "mrp_visibility/mirror_depth.frag.glsl"})},
    reads=("scene",),
    writes=("mirror_depth",),
    run=render_mirror_maps,
)
