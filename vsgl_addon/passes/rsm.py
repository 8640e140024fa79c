# SPDX-License-Identifier: GPL-3.0-or-later
"""Reflective shadow maps (RSMs) on the GPU: one VPL per texel (formulas.md §4; 000 §4; issue 3
item 2). Never touches ``bpy.context``: takes the plain :class:`SceneDescription`.

    scene_gpu = SceneGPU(scene)                       # triangles uploaded once per scene
    views = render_rsm_views(scene_gpu, light_index, size=256)
    arrays = views[0].to_numpy()                       # RSMArrays: .rsm is reference.vsgl.RSM
    for view in views: view.free()
    scene_gpu.free()

**Views per light** (:func:`light_view_specs`, pure numpy):

* spot: one perspective view along the spot axis covering the cone (the light's local frame, the
  object scale's ellipse included) when the half angle is at most ``SPOT_SINGLE_VIEW_MAX_HALF_ANGLE``
  (60°), else the faces of a cube in the light's frame (the back face only beyond 90°);
* point: the six 90° faces of a world-aligned cube;
* area: a Lambertian emitter; the five faces of a cube in the light's frame that can receive flux
  (the back face, behind the emitter, is skipped);
* sun: one orthographic view along the sun, fitted to the part of the scene the camera and the sun
  both see: the rectangle (in the light's X/Y) bounding the intersection of the scene's bounding box
  with the camera frustum (exact convex-polytope intersection); its depth range spans the whole
  scene so that occluders outside the camera's view still cast shadows. No camera: the scene box.

A view whose frustum contains no triangle (CPU test: every triangle lies outside one frustum plane)
is not rendered at all: a light that hits nothing costs a numpy test and yields no views (zero flux).

**Per texel** (RGBA32F, at most 6 colour attachments; the layout
:class:`~vsgl_addon.passes.vsgl_generation.RSMTextures` reads, so the textures feed VSGL generation
directly): ``position`` (y, λs), ``normal`` (n facing the light, Principled roughness),
``flux_diffuse`` (Φ·Rd, Φ₁), ``flux_specular`` (Φ·Rs, dω), ``specular_axis`` (ξs, coverage), and a
32-bit float depth attachment (for shadows later). Φ₁ is the texel flux of a white light, Φ = Φ₁ ×
light colour; dω is the texel's solid angle (sr), or its area on the sun's plane (m²) for a sun.
Texels that see nothing are all zero. Texture rows start at the bottom of the view (row 0 =
NDC y = −1), as ``GPUTexture.read`` returns them; ``to_numpy`` keeps that order.

**Model** (documented in, and tested against, :mod:`vsgl_addon.reference.rsm`). The lights are
Blender's emission model shared with the direct light (``glsl/lib/lights.glsl``,
:mod:`vsgl_addon.reference.lights`). The reflectances are the Principled BSDF base layer the
direct light uses (``glsl/lib/principled.glsl``, :mod:`vsgl_addon.reference.principled`, calibrated
against Cycles) for the texel's incidence ω' (towards the light): Rd = base × (1 − metallic) ×
(1 − E_spec(n·ω')), the flux the dielectric layer lets through to the diffuse base, and Rs the
specular lobes' directional albedo for ω' (real dielectric Fresnel, metallic Schlick, multiple
scattering), so Φ·Rd and Φ·Rs are the powers the texel's diffuse and (normalized, 000 Eq. 7)
specular lobes reflect. The base colour image is sampled as Blender's Linear/Repeat Image Texture
(``glsl/lib/image.glsl``), as in the G-buffer.

Accuracy. A texel's flux is exact up to float32 (the texel solid angle is integrated, not the
midpoint cos³ rule: see ``glsl/rsm/rsm.frag.glsl``); a total over a surface errs only by coverage
at the surface's silhouette (texel centres decide), which is O(1/size): for a 6 m plane 1 m under
a point light (edges seen at 18° by the cube's side faces) +2.3 % at 32², −1.1 % at 64²,
+0.58 % at 128², −0.29 % at 256², +0.14 % at 512²; a spot's cone inside a plane: below 0.01 %
from 64² on (tests/test_rsm.py).

Not modelled (documented approximations): the size and shape of area lights and their spread (a
Lambertian point emitter), the radius of point and spot lights, the sun's angle; geometry closer
to a point, spot or area light than ``NEAR_FRACTION`` of its view's far plane is clipped.

Each :class:`RSMView` keeps its light's ``view_matrix`` (world → light view, rotation and
translation) and ``projection_matrix`` (OpenGL clip space) for shadow lookups.

Needs a GPU context (:func:`vsgl_addon.gpu_context.ensure_gpu_context`), main thread. The shader is
compiled once per process (:func:`shader`, :func:`free_shaders`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..layouts import RSM as RSM_LAYOUT, RSM_VIEW
from ..reference.lights import light_params
from ..reference.vsgl import RSM
from .contract import LIGHT_PASSES, GPUPass, ShaderSpec
from .gpu_util import matrix, read_texture, texture_from_array
from .scene_gpu import VERTEX_STAGE, SceneGPU, scene_shader_interface

#: Largest spot half angle covered by one perspective view; wider cones use cube faces (a single
#: view's corner texels would shrink to cos³ of the field of view, wasting resolution).
SPOT_SINGLE_VIEW_MAX_HALF_ANGLE = math.radians(60.0)

#: Near plane of perspective views as a fraction of the far plane (geometry closer than that to the
#: light is clipped); depth is 32-bit float.
NEAR_FRACTION = 1e-4

#: Largest RSM side (a 2048² view holds five 64 MB colour textures).
MAX_RSM_SIZE = 4096

#: The colour attachments, in the order of :data:`vsgl_addon.layouts.RSM`.
ATTACHMENTS = RSM_LAYOUT.slot_names


# --- Shader ------------------------------------------------------------------------------------


def _interface():
    return scene_shader_interface(
        # (perspective 1 / ortho 0, half extent x, y, size)
        push_constants=[("VEC4", "view_params")],
        # view_constants: a one-column RGBA32F table, vsgl_addon.layouts.RSM_VIEW (_view_constants).
        samplers=[("FLOAT_2D", "view_constants")],
        fragment_outputs=[("VEC4", f"rsm_{name}") for name in RSM_LAYOUT.slot_names],
    )


def shader():
    """The RSM shader (glsl/rsm/rsm.frag.glsl after the scene's vertex stage), compiled on first use
    and cached for the process."""
    return PASS.shader()


def free_shaders() -> None:
    PASS.free_shaders()


# --- Views (pure numpy) ------------------------------------------------------------------------


@dataclass(frozen=True)
class RSMViewSpec:
    """Where one RSM view looks: matrices and the extent of its image plane."""

    name: str  # "spot", "sun", "+X", "-Z", ...
    perspective: bool
    view_matrix: np.ndarray  # (4, 4) world -> view (camera looks down -Z, +Y up)
    projection_matrix: np.ndarray  # (4, 4) OpenGL clip space
    half_extent: tuple[float, float]  # image plane at distance 1 (tan) or metres (ortho)
    near: float
    far: float

    @property
    def view_to_world(self) -> np.ndarray:
        return np.linalg.inv(self.view_matrix)

    @property
    def view_projection(self) -> np.ndarray:
        return self.projection_matrix @ self.view_matrix


def _orthonormal_frame(matrix_world) -> np.ndarray:
    """(3, 3) rotation with the columns of the light's frame, normalized (Gram-Schmidt from Z)."""
    m = np.asarray(matrix_world, np.float64)[:3, :3]
    z = m[:, 2] / np.linalg.norm(m[:, 2])
    x = m[:, 0] - (m[:, 0] @ z) * z
    if np.linalg.norm(x) < 1e-12:
        x = np.cross(np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.array([1.0, 0.0, 0.0]), z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


def _view_matrix(rotation: np.ndarray, origin) -> np.ndarray:
    """World -> view for a view whose world axes are the columns of ``rotation`` (X right, Y up,
    looking down -Z) at ``origin``."""
    view = np.eye(4)
    view[:3, :3] = rotation.T
    view[:3, 3] = -rotation.T @ np.asarray(origin, np.float64)
    return view


def _perspective(hx: float, hy: float, near: float, far: float) -> np.ndarray:
    p = np.zeros((4, 4))
    p[0, 0] = 1.0 / hx
    p[1, 1] = 1.0 / hy
    p[2, 2] = -(far + near) / (far - near)
    p[2, 3] = -2.0 * far * near / (far - near)
    p[3, 2] = -1.0
    return p


def _orthographic(hx: float, hy: float, near: float, far: float) -> np.ndarray:
    p = np.eye(4)
    p[0, 0] = 1.0 / hx
    p[1, 1] = 1.0 / hy
    p[2, 2] = -2.0 / (far - near)
    p[2, 3] = -(far + near) / (far - near)
    return p


def _box_corners(lo, hi) -> np.ndarray:
    """(8, 3) corners, index = bit0 x, bit1 y, bit2 z (the hexahedron layout of _HEX_*)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    return np.array([[(hi if (i >> a) & 1 else lo)[a] for a in range(3)] for i in range(8)])


# Hexahedron with corners indexed by bits (x, y, z): its 12 edges and 6 faces.
_HEX_EDGES = [(i, i | (1 << a)) for a in range(3) for i in range(8) if not (i >> a) & 1]
_HEX_FACES = [[i for i in range(8) if ((i >> a) & 1) == side] for a in range(3) for side in (0, 1)]


def _hex_planes(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inward unit normals (6, 3) and offsets (6,) of a convex hexahedron: inside <=> n.x >= d."""
    centre = corners.mean(axis=0)
    normals, offsets = [], []
    for face in _HEX_FACES:
        pts = corners[face]
        # Newell's method over the quad (robust to a degenerate corner).
        quad = pts[[0, 1, 3, 2]]
        n = np.zeros(3)
        for k in range(4):
            a, b = quad[k], quad[(k + 1) % 4]
            n += np.array([(a[1] - b[1]) * (a[2] + b[2]), (a[2] - b[2]) * (a[0] + b[0]),
                           (a[0] - b[0]) * (a[1] + b[1])])
        n /= max(np.linalg.norm(n), 1e-300)
        d = n @ pts.mean(axis=0)
        if n @ centre < d:
            n, d = -n, -d
        normals.append(n)
        offsets.append(d)
    return np.array(normals), np.array(offsets)


def convex_hex_intersection(a: np.ndarray, b: np.ndarray, tolerance: float = 1e-9) -> np.ndarray:
    """Vertices (k, 3) of the intersection of two convex hexahedra given by their 8 corners
    (``_box_corners`` layout): the corners of each inside the other, and the crossings of each one's
    edges with the other's faces. Empty (0, 3) when they do not meet."""
    points = []
    scale = max(np.ptp(a, axis=0).max(), np.ptp(b, axis=0).max(), 1e-30)
    eps = tolerance * scale
    planes = {0: _hex_planes(a), 1: _hex_planes(b)}
    for own, other in ((a, 1), (b, 0)):
        normals, offsets = planes[other]
        inside = np.all(own @ normals.T >= offsets - eps, axis=1)
        points.extend(own[inside])
        for i, j in _HEX_EDGES:
            p, q = own[i], own[j]
            for n, d in zip(normals, offsets):
                dp, dq = n @ p - d, n @ q - d
                if (dp < 0.0) != (dq < 0.0) and dp != dq:
                    x = p + (q - p) * (dp / (dp - dq))
                    if np.all(normals @ x >= offsets - eps):
                        points.append(x)
    return np.array(points).reshape(-1, 3)


def _camera_frustum_corners(camera) -> np.ndarray:
    inverse = np.linalg.inv(camera.projection_matrix() @ camera.view_matrix())
    ndc = _box_corners((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))
    h = np.c_[ndc, np.ones(8)] @ inverse.T
    return h[:, :3] / h[:, 3:4]


def _depth_range(view: np.ndarray, corners: np.ndarray) -> tuple[float, float]:
    depth = -(np.c_[corners, np.ones(len(corners))] @ view.T)[:, 2]
    far = float(depth.max())
    return float(depth.min()), far


def _padded_bounds(bounds) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = (np.asarray(v, np.float64) for v in bounds)
    # Only to keep a flat scene's box from degenerating (a face of zero area has no plane): the pad
    # widens a fitted sun view, so it must stay far below a texel (1e-7 of the extent: 2e-5 %).
    pad = 1e-7 * max(float(np.max(hi - lo)), 1e-3) + 1e-9
    return lo - pad, hi + pad


def _perspective_spec(name, rotation, origin, hx, hy, bounds) -> RSMViewSpec:
    view = _view_matrix(rotation, origin)
    _, far = _depth_range(view, _box_corners(*bounds))
    far = max(far * 1.01, 1e-3)
    near = far * NEAR_FRACTION
    return RSMViewSpec(name, True, view, _perspective(hx, hy, near, far), (hx, hy), near, far)


# Cube faces: (name, view rotation columns X, Y, Z(back)) in a frame's coordinates; each proper.
_CUBE_FACES = [
    ("+X", (0, 0, 1), (0, 1, 0), (-1, 0, 0)),
    ("-X", (0, 0, -1), (0, 1, 0), (1, 0, 0)),
    ("+Y", (1, 0, 0), (0, 0, 1), (0, -1, 0)),
    ("-Y", (-1, 0, 0), (0, 0, 1), (0, 1, 0)),
    ("+Z", (-1, 0, 0), (0, 1, 0), (0, 0, -1)),
    ("-Z", (1, 0, 0), (0, 1, 0), (0, 0, 1)),
]


def _cube_specs(frame, origin, bounds, skip=()) -> list[RSMViewSpec]:
    specs = []
    for name, x, y, z in _CUBE_FACES:
        if name in skip:
            continue
        rotation = frame @ np.array([x, y, z], np.float64).T
        specs.append(_perspective_spec(name, rotation, origin, 1.0, 1.0, bounds))
    return specs


def scene_bounds(scene) -> tuple[np.ndarray, np.ndarray] | None:
    """(lo, hi) of the scene's triangles, float64; None when there are none."""
    if scene.geometry.triangle_count == 0:
        return None
    positions = np.asarray(scene.geometry.positions).reshape(-1, 3)
    return positions.min(axis=0).astype(np.float64), positions.max(axis=0).astype(np.float64)


def light_view_specs(scene, light, bounds=None) -> list[RSMViewSpec]:
    """The RSM views of ``light`` before culling (see the module documentation); [] when the scene
    has no triangles (or, for a sun, when the camera sees none of the scene's bounding box).
    ``bounds``: the scene's (lo, hi) when already known (:func:`scene_bounds`)."""
    bounds = scene_bounds(scene) if bounds is None else bounds
    if bounds is None:
        return []
    bounds = _padded_bounds(bounds)
    origin = np.asarray(light.position, np.float64)
    if light.type == "POINT":
        return _cube_specs(np.eye(3), origin, bounds)
    frame = _orthonormal_frame(light.matrix_world)
    if light.type == "AREA":
        return _cube_specs(frame, origin, bounds, skip=("+Z",))  # +Z = behind the emitter
    if light.type == "SPOT":
        half = 0.5 * float(light.spot_size)
        m = np.asarray(light.matrix_world, np.float64)[:3, :3]
        sx, sy, sz = np.linalg.norm(m, axis=0)
        if half <= SPOT_SINGLE_VIEW_MAX_HALF_ANGLE:
            t = math.tan(half)
            return [_perspective_spec("spot", frame, origin, t * sx / sz, t * sy / sz, bounds)]
        skip = ("+Z",) if half <= 0.5 * math.pi else ()
        return _cube_specs(frame, origin, bounds, skip=skip)
    if light.type == "SUN":
        return _sun_specs(scene, light, bounds)
    raise ValueError(f"unknown light type {light.type!r}")


def _sun_specs(scene, light, bounds) -> list[RSMViewSpec]:
    box = _box_corners(*bounds)
    region = box
    if scene.camera is not None:
        region = convex_hex_intersection(_camera_frustum_corners(scene.camera), box)
        if len(region) == 0:
            return []
    direction = np.asarray(light.direction, np.float64)
    direction = direction / np.linalg.norm(direction)
    frame = _orthonormal_frame(light.matrix_world)
    # The frame's Z is the light's local +Z; the sun shines along -Z (light.direction).
    if frame[:, 2] @ direction > 0.0:
        frame = frame * np.array([1.0, -1.0, -1.0])
    x_axis, y_axis = frame[:, 0], frame[:, 1]
    u, v = region @ x_axis, region @ y_axis
    extent = float(np.ptp(box, axis=0).max())
    floor = 1e-6 * max(extent, 1e-3)
    hx = max(0.5 * float(np.ptp(u)), floor)
    hy = max(0.5 * float(np.ptp(v)), floor)
    centre = 0.5 * (u.min() + u.max()) * x_axis + 0.5 * (v.min() + v.max()) * y_axis
    depth = box @ direction  # the whole scene along the sun: occluders outside the camera count
    margin = 0.01 * max(extent, 1e-3)
    origin = centre + (depth.min() - margin) * direction - ((centre @ direction) * direction)
    view = _view_matrix(frame, origin)
    near, far = 0.5 * margin, float(np.ptp(depth)) + 1.5 * margin
    return [RSMViewSpec("sun", False, view, _orthographic(hx, hy, near, far), (hx, hy), near, far)]


def _outside_one_plane(clip: np.ndarray) -> np.ndarray:
    """For clip coordinates (..., k, 4) of k points: whether all k lie outside one clip plane."""
    w = clip[..., 3]
    outside = np.zeros(clip.shape[:-2], bool)
    for axis in range(3):
        outside |= np.all(clip[..., axis] > w, axis=-1)
        outside |= np.all(clip[..., axis] < -w, axis=-1)
    return outside


def view_sees_triangles(spec: RSMViewSpec, positions: np.ndarray, bounds=None) -> bool:
    """Whether some triangle is not entirely outside one of the view's clip planes (conservative:
    the clip planes are world-space planes, so this is exact per plane). With ``bounds`` (lo, hi)
    of the triangles, a box entirely outside one plane answers first without the per-triangle test
    (~3 ms per 20k triangles in numpy)."""
    if len(positions) == 0:
        return False
    matrix = spec.view_projection.T
    if bounds is not None:
        corners = _box_corners(*bounds)
        clip = np.c_[corners, np.ones(8)] @ matrix
        if _outside_one_plane(clip[None])[0]:
            return False
    h = np.c_[positions.reshape(-1, 3), np.ones(positions.shape[0] * 3)] @ matrix
    return bool(np.any(~_outside_one_plane(h.reshape(-1, 3, 4))))


# --- Rendering ---------------------------------------------------------------------------------


@dataclass
class RSMArrays:
    """An RSM view read back: the reference's :class:`RSM` and the texel quantities behind it.

    Arrays (H, W, ...), row 0 at the bottom of the view.
    """

    rsm: RSM
    flux: np.ndarray  # (H, W, 3) Φ per texel, W (RGB: Φ₁ × light colour)
    flux_white: np.ndarray  # (H, W) Φ₁, the texel flux of a white light
    texel_measure: np.ndarray  # (H, W) solid angle (sr), or area on the sun's plane (m²) for a sun
    roughness: np.ndarray  # (H, W) Principled roughness
    coverage: np.ndarray  # (H, W) bool, the texel sees geometry
    depth: np.ndarray  # (H, W) window depth in [0, 1] (1 = nothing)


@dataclass
class RSMView:
    """One rendered RSM view of a light: GPU textures plus the view's matrices."""

    light_index: int
    light: object
    spec: RSMViewSpec
    size: int
    textures: dict = field(default_factory=dict)  # ATTACHMENTS names and "depth" -> GPUTexture
    framebuffer: object = None
    constants: object = None  # the 10x1 view-constants texture the draw read

    @property
    def view_matrix(self) -> np.ndarray:
        return self.spec.view_matrix

    @property
    def projection_matrix(self) -> np.ndarray:
        return self.spec.projection_matrix

    def rsm_textures(self):
        """The view as VSGL generation's ``RSMTextures`` (no copy)."""
        from .vsgl_generation import RSMTextures

        return RSMTextures(self.size, **{name: self.textures[name] for name in RSM_LAYOUT.slot_names})

    def to_numpy(self) -> RSMArrays:
        s = self.size
        texels = {name: read_texture(self.textures[name], s, s) for name in RSM_LAYOUT.slot_names}
        fields = RSM_LAYOUT.unpack_slots(texels)
        depth = read_texture(self.textures["depth"], s, s, 1)[..., 0].astype(np.float64)
        rsm = RSM(
            position=fields["position"],
            normal=fields["normal"],
            flux_diffuse=fields["flux_diffuse"],
            flux_specular=fields["flux_specular"],
            specular_axis=fields["specular_axis"],
            specular_sharpness=fields["specular_sharpness"],
        )
        flux_white = fields["flux_white"]
        return RSMArrays(
            rsm=rsm,
            flux=flux_white[..., None] * np.asarray(self.light.color, np.float64),
            flux_white=flux_white,
            texel_measure=fields["texel_measure"],
            roughness=fields["roughness"],
            coverage=fields["coverage"] > 0.5,
            depth=depth,
        )

    def free(self) -> None:
        """Release the view's textures and framebuffer (Blender frees them with their last
        reference; nothing else keeps one)."""
        self.framebuffer = None
        self.constants = None
        self.textures.clear()


def _view_constants(light, spec: RSMViewSpec) -> np.ndarray:
    """(rows, 1, 4) float32: the per-view constants of glsl/rsm/rsm.frag.glsl (layouts.RSM_VIEW)."""
    view_to_world = spec.view_to_world[:3, :3]
    world_to_local = np.linalg.inv(np.asarray(light.matrix_world, np.float64)[:3, :3])
    axis = np.asarray(light.direction, np.float64)
    values = {f"view_to_world_row{i}": view_to_world[i][None] for i in range(3)}
    values.update({f"world_to_local_row{i}": world_to_local[i][None] for i in range(3)})
    values.update(light_position=np.asarray(light.position, np.float64)[None],
                  light_axis=(axis / np.linalg.norm(axis))[None],
                  light_params=np.asarray(light_params(light), np.float64)[None],
                  light_color=np.asarray(light.color, np.float64)[None])
    return RSM_VIEW.pack(values, 1)


def _render(scene_gpu: SceneGPU, light, spec: RSMViewSpec, size: int, textures: dict):
    import gpu

    program = shader()
    targets = [textures[name] for name in RSM_LAYOUT.slot_names]
    framebuffer = gpu.types.GPUFrameBuffer(depth_slot=textures["depth"], color_slots=targets)
    constants = texture_from_array(_view_constants(light, spec))
    with framebuffer.bind():
        framebuffer.clear(color=(0.0, 0.0, 0.0, 0.0), depth=1.0)
        gpu.state.viewport_set(0, 0, size, size)
        gpu.state.blend_set("NONE")
        gpu.state.depth_test_set("LESS")
        gpu.state.depth_mask_set(True)
        gpu.state.face_culling_set("NONE")
        program.bind()
        program.uniform_float("view_projection", matrix(spec.view_projection))
        program.uniform_sampler("view_constants", constants)
        program.uniform_float("view_params", (1.0 if spec.perspective else 0.0, spec.half_extent[0],
                                              spec.half_extent[1], float(size)))
        scene_gpu.draw(program)
        gpu.state.depth_test_set("NONE")
        gpu.state.depth_mask_set(False)
    return framebuffer, constants


def render_rsm_views(scene, light_index: int, size: int = 256) -> list[RSMView]:
    """Render the RSM views of ``scene.lights[light_index]`` at ``size`` x ``size`` texels.

    ``scene`` is a :class:`SceneGPU` (reuse it for every light) or a SceneDescription (uploaded for
    this call only). Views whose frustum holds no triangle are skipped, so a light that hits
    nothing returns []. Free each view with :meth:`RSMView.free` when done.
    """
    import gpu

    size = int(size)
    if not 1 <= size <= MAX_RSM_SIZE:
        raise ValueError(f"RSM size must be in [1, {MAX_RSM_SIZE}], not {size}")
    scene_gpu = scene if isinstance(scene, SceneGPU) else SceneGPU(scene)
    light = scene_gpu.scene.lights[light_index]
    views = []
    for spec in light_view_specs(scene_gpu.scene, light, scene_gpu.bounds):
        if not view_sees_triangles(spec, scene_gpu.positions, scene_gpu.bounds):
            continue
        textures = {name: gpu.types.GPUTexture((size, size), format="RGBA32F") for name in RSM_LAYOUT.slot_names}
        textures["depth"] = gpu.types.GPUTexture((size, size), format="DEPTH_COMPONENT32F")
        framebuffer, constants = _render(scene_gpu, light, spec, size, textures)
        views.append(RSMView(light_index, light, spec, size, textures, framebuffer, constants))
    return views


def total_flux(views: list[RSMView]) -> dict[str, np.ndarray]:
    """Sums over every texel of the views (read back, float64): Φ, Φ·Rd, Φ·Rs (RGB, W)."""
    totals = {"flux": np.zeros(3), "flux_diffuse": np.zeros(3), "flux_specular": np.zeros(3)}
    for view in views:
        arrays = view.to_numpy()
        totals["flux"] += arrays.flux.reshape(-1, 3).sum(axis=0)
        totals["flux_diffuse"] += arrays.rsm.flux_diffuse.reshape(-1, 3).sum(axis=0)
        totals["flux_specular"] += arrays.rsm.flux_specular.reshape(-1, 3).sum(axis=0)
    return totals


PASS = GPUPass(
    name="rsm",
    label="Reflective Shadow Maps",
    step=LIGHT_PASSES,
    shaders={"rsm": ShaderSpec(_interface, {"vertex": VERTEX_STAGE, "fragment": "rsm/rsm.frag.glsl"},
                               code=lambda: {"fragment": RSM_LAYOUT.glsl("outputs_store")
                                                         + RSM_VIEW.glsl("sampler_load")})},
    reads=("scene",),
    writes=(RSM_LAYOUT.name, "rsm_depth"),
    run=render_rsm_views,
)
