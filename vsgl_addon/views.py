# SPDX-License-Identifier: GPL-3.0-or-later
"""View geometry, pure numpy (no bpy, no GPU): every matrix a pass rasterises through.

* **Camera** (:func:`camera_view_matrix`, :func:`camera_viewplane`, :func:`camera_projection_matrix`,
  :func:`camera_vector`): Blender's camera as it renders, the view plane computed as
  BKE_camera_params_compute_viewplane does; :class:`~vsgl_addon.scene_description.Camera` delegates
  here. :func:`render_size` is Blender's output size (resolution × percentage, integer division as
  BKE_render_resolution), the one rule the render engine, the operators and the camera extraction
  share, so the image and the camera's aspect always agree.
* **Bands** (:func:`band_projection`): the projection of a band of image rows, for rendering an
  image in horizontal strips.
* **RSM views per light** (:func:`light_view_specs`; formulas.md §4, 000 §4):

  - spot: one perspective view along the spot axis covering the cone (the light's local frame,
    the object scale's ellipse included) when the half angle is at most
    ``SPOT_SINGLE_VIEW_MAX_HALF_ANGLE`` (60°), else the faces of a cube in the light's frame (the
    back face only beyond 90°);
  - point: the six 90° faces of a world-aligned cube;
  - area: a Lambertian emitter; the five faces of a cube in the light's frame that can receive
    flux (the back face, behind the emitter, is skipped);
  - sun: one orthographic view along the sun, fitted to the reflectors that can bounce light into
    the camera's view (:func:`sun_fit_rectangle`): the intersection of the scene's bounding box with
    the camera frustum (exact convex-polytope intersection, :func:`convex_hex_intersection`), grown
    by the reach :func:`sun_reach` and cut to the scene's box, as a rectangle in the light's X/Y;
    its depth range spans the whole scene so that occluders outside the camera's view still cast
    shadows. No camera: the scene box; a camera that sees none of the scene box: no view.

  A view whose frustum contains no triangle (:func:`view_sees_triangles`: every triangle lies
  outside one frustum plane) is not rendered at all: a light that hits nothing costs a numpy test
  and yields no views (zero flux).

Conventions: views look down −Z with +Y up; projections are OpenGL clip space (z in [−w, w]);
matrices are float64 (4, 4), world → view.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Largest spot half angle covered by one perspective view; wider cones use cube faces (a single
#: view's corner texels would shrink to cos³ of the field of view, wasting resolution).
SPOT_SINGLE_VIEW_MAX_HALF_ANGLE = math.radians(60.0)

#: Near plane of perspective views as a fraction of the far plane (geometry closer than that to the
#: light is clipped); depth is 32-bit float.
NEAR_FRACTION = 1e-4

#: The fraction of a receiver's one-bounce light from a lit ground that the sun's view may leave
#: out beyond its reach (:func:`sun_reach`): 10 %, half the suite's sun-wall tolerance.
SUN_REACH_TOLERANCE = 0.1


# --- Camera ------------------------------------------------------------------------------------


def render_size(render) -> tuple[int, int]:
    """Blender's output size in pixels of ``render`` (anything with ``resolution_x``,
    ``resolution_y`` and ``resolution_percentage``, e.g. ``scene.render``): resolution ×
    percentage with Blender's integer division (BKE_render_resolution), at least 1 pixel."""
    percentage = int(render.resolution_percentage)
    return (max(1, int(render.resolution_x) * percentage // 100),
            max(1, int(render.resolution_y) * percentage // 100))


def camera_view_matrix(matrix_world) -> np.ndarray:
    """(4, 4) float64 world -> camera space: the inverse of the orthonormalised world matrix."""
    m = np.array(matrix_world, np.float64)
    # Blender's view matrix ignores the camera object's scale.
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
    view = np.eye(4)
    view[:3, :3] = rot.T
    view[:3, 3] = -rot.T @ m[:3, 3]
    return view


def camera_viewplane(camera) -> tuple[float, float, float, float]:
    """(xmin, xmax, ymin, ymax) of ``camera``'s view plane at clip_start (PERSP) or in metres
    (ORTHO); ``camera`` has the fields of :class:`~vsgl_addon.scene_description.Camera`.

    The same computation as Blender's BKE_camera_params_compute_viewplane (zoom 1, no offset).
    """
    winx = float(camera.resolution[0])
    winy = float(camera.resolution[1])
    aspx, aspy = camera.pixel_aspect
    ycor = aspy / aspx
    sensor = camera.sensor_height if camera.sensor_fit == "VERTICAL" else camera.sensor_width
    if camera.type == "ORTHO":
        pixsize = camera.ortho_scale
    else:
        pixsize = sensor * camera.clip_start / camera.lens
    fit = camera.sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if aspx * winx >= aspy * winy else "VERTICAL"
    viewfac = winx if fit == "HORIZONTAL" else ycor * winy
    pixsize /= viewfac
    dx = camera.shift_x * viewfac
    dy = camera.shift_y * viewfac
    return (
        (-0.5 * winx + dx) * pixsize,
        (0.5 * winx + dx) * pixsize,
        (-0.5 * ycor * winy + dy) * pixsize,
        (0.5 * ycor * winy + dy) * pixsize,
    )


def camera_projection_matrix(camera) -> np.ndarray:
    """(4, 4) float64 OpenGL-style projection (clip z in [-w, w]) of ``camera``, as Blender's
    Camera.calc_matrix_camera."""
    xmin, xmax, ymin, ymax = camera_viewplane(camera)
    n, f = camera.clip_start, camera.clip_end
    p = np.zeros((4, 4))
    if camera.type == "ORTHO":
        p[0, 0] = 2.0 / (xmax - xmin)
        p[1, 1] = 2.0 / (ymax - ymin)
        p[2, 2] = -2.0 / (f - n)
        p[0, 3] = -(xmax + xmin) / (xmax - xmin)
        p[1, 3] = -(ymax + ymin) / (ymax - ymin)
        p[2, 3] = -(f + n) / (f - n)
        p[3, 3] = 1.0
    else:
        p[0, 0] = 2.0 * n / (xmax - xmin)
        p[1, 1] = 2.0 * n / (ymax - ymin)
        p[0, 2] = (xmax + xmin) / (xmax - xmin)
        p[1, 2] = (ymax + ymin) / (ymax - ymin)
        p[2, 2] = -(f + n) / (f - n)
        p[2, 3] = -2.0 * f * n / (f - n)
        p[3, 2] = -1.0
    return p


def camera_vector(view_matrix, projection_matrix) -> np.ndarray:
    """(4,) float64: (camera position, 1) for a perspective projection, (unit direction towards the
    camera, 0) for an orthographic one (projection[3, 3] == 1)."""
    view = np.asarray(view_matrix, np.float64)
    inverse = np.linalg.inv(view)
    if abs(float(np.asarray(projection_matrix)[3, 3]) - 1.0) < 1e-12:  # orthographic
        back = inverse[:3, 2] / np.linalg.norm(inverse[:3, 2])
        return np.r_[back, 0.0]
    return np.r_[inverse[:3, 3], 1.0]


def band_projection(projection_matrix, first_row: int, end_row: int, height: int) -> np.ndarray:
    """The projection of rows [first_row, end_row) of an image `height` rows high (row 0 at the
    bottom): the same view, NDC y of that band stretched to [-1, 1]. Perspective or orthographic."""
    y0 = -1.0 + 2.0 * first_row / height
    y1 = -1.0 + 2.0 * end_row / height
    crop = np.eye(4)
    crop[1, 1] = 2.0 / (y1 - y0)
    crop[1, 3] = -(y1 + y0) / (y1 - y0)
    return crop @ np.asarray(projection_matrix, np.float64)


# --- RSM views ---------------------------------------------------------------------------------


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


def view_from_frame(rotation: np.ndarray, origin) -> np.ndarray:
    """World -> view for a view whose world axes are the columns of ``rotation`` (X right, Y up,
    looking down -Z) at ``origin``."""
    view = np.eye(4)
    view[:3, :3] = rotation.T
    view[:3, 3] = -rotation.T @ np.asarray(origin, np.float64)
    return view


def perspective_projection(hx: float, hy: float, near: float, far: float) -> np.ndarray:
    """OpenGL perspective projection of a symmetric frustum whose image plane at distance 1 spans
    [-hx, hx] x [-hy, hy] (half extents are tangents of the half angles), depth [near, far]."""
    p = np.zeros((4, 4))
    p[0, 0] = 1.0 / hx
    p[1, 1] = 1.0 / hy
    p[2, 2] = -(far + near) / (far - near)
    p[2, 3] = -2.0 * far * near / (far - near)
    p[3, 2] = -1.0
    return p


def orthographic_projection(hx: float, hy: float, near: float, far: float) -> np.ndarray:
    """OpenGL orthographic projection of the box [-hx, hx] x [-hy, hy] (metres) x depth [near, far]."""
    p = np.eye(4)
    p[0, 0] = 1.0 / hx
    p[1, 1] = 1.0 / hy
    p[2, 2] = -2.0 / (far - near)
    p[2, 3] = -(far + near) / (far - near)
    return p


def box_corners(lo, hi) -> np.ndarray:
    """(8, 3) corners, index = bit0 x, bit1 y, bit2 z (the hexahedron layout of _HEX_*)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    return np.array([[(hi if (i >> a) & 1 else lo)[a] for a in range(3)] for i in range(8)])


# Hexahedron with corners indexed by bits (x, y, z): its 12 edges and 6 faces.
_HEX_EDGES = [(i, i | (1 << a)) for a in range(3) for i in range(8) if not (i >> a) & 1]
_HEX_FACES = [[i for i in range(8) if ((i >> a) & 1) == side] for a in range(3) for side in (0, 1)]


def hex_planes(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
    (``box_corners`` layout): the corners of each inside the other, and the crossings of each one's
    edges with the other's faces. Empty (0, 3) when they do not meet."""
    points = []
    scale = max(np.ptp(a, axis=0).max(), np.ptp(b, axis=0).max(), 1e-30)
    eps = tolerance * scale
    planes = {0: hex_planes(a), 1: hex_planes(b)}
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


def camera_frustum_corners(camera) -> np.ndarray:
    inverse = np.linalg.inv(camera.projection_matrix() @ camera.view_matrix())
    ndc = box_corners((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))
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
    view = view_from_frame(rotation, origin)
    _, far = _depth_range(view, box_corners(*bounds))
    far = max(far * 1.01, 1e-3)
    near = far * NEAR_FRACTION
    return RSMViewSpec(name, True, view, perspective_projection(hx, hy, near, far), (hx, hy), near, far)


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


def sun_reach(seen: np.ndarray) -> float:
    """How far from the part of the scene the camera sees (``seen``: (k, 3) points) the sun's view
    reaches for reflectors that bounce light into it, in metres: (4/π) · H / SUN_REACH_TOLERANCE,
    H the smallest side of ``seen``'s bounding box (its height over a ground, its thinnest extent).

    Why this distance: for a receiver at height h above a lit plane, the part of the plane farther
    than R gives at most (4/π) · h/R of the plane's one-bounce irradiance on a vertical receiver (the
    point-to-plane form factor cos θ_x cos θ_y / (π d²) integrated beyond R: (2h/π) ∫_R^∞ ρ² /
    (ρ² + h²)² dρ ≤ 2h/(πR), of a total 1/2) and (h / R)² on one facing the plane; every receiver
    in view lies within H of the box's lowest face, so the reflectors left out give it at most
    SUN_REACH_TOLERANCE of that light. A flat view (H = 0, a lit plane alone) bounces nothing onto
    itself and reaches nowhere. Geometry outside the reach that stands tall (a wall farther than R)
    is left out; its solid angle from the receivers is then small unless it is much higher than H."""
    seen = np.asarray(seen, np.float64).reshape(-1, 3)
    if len(seen) == 0:
        return 0.0
    return 4.0 / math.pi * float(np.ptp(seen, axis=0).min()) / SUN_REACH_TOLERANCE


def sun_fit_rectangle(camera_corners, bounds, x_axis, y_axis):
    """(lo, hi) (2,) each: the rectangle in the sun's X/Y (``x_axis``, ``y_axis``, world unit
    vectors) that its view covers, or None when the camera sees none of the scene's box ``bounds``
    (lo, hi). ``camera_corners``: the camera frustum (:func:`box_corners` layout), None for no
    camera (the whole box).

    The receivers are in view, their reflectors need not be: a sun behind a courtyard's wall lights
    the wall behind the camera, which bounces light onto what the camera sees (one bounce sums the
    VPL of every lit RSM texel, formulas.md §4 after 000 §4, seen by the camera or not). So the view holds the
    scene's box within :func:`sun_reach` R of the part of it the camera sees (``seen``: the frustum
    inside the box): the points within R of ``seen`` project (orthographically, which shortens no
    distance) into ``seen``'s own rectangle grown by R, and lie in ``seen``'s bounding box grown by
    R, cut to the scene's box; the view is the intersection of those two rectangles. R = 0 (a flat
    view) leaves ``seen``'s rectangle, the camera's footprint alone."""
    lo, hi = (np.asarray(v, np.float64) for v in bounds)
    axes = np.stack([np.asarray(x_axis, np.float64), np.asarray(y_axis, np.float64)], axis=1)
    box = box_corners(lo, hi)
    if camera_corners is None:
        projected = box @ axes
        return projected.min(axis=0), projected.max(axis=0)
    seen = convex_hex_intersection(np.asarray(camera_corners, np.float64), box)
    if len(seen) == 0:
        return None
    reach = sun_reach(seen)
    projected = seen @ axes
    grown = box_corners(np.maximum(seen.min(axis=0) - reach, lo), np.minimum(seen.max(axis=0) + reach, hi)) @ axes
    return (np.maximum(projected.min(axis=0) - reach, grown.min(axis=0)),
            np.minimum(projected.max(axis=0) + reach, grown.max(axis=0)))


def _sun_specs(scene, light, bounds) -> list[RSMViewSpec]:
    box = box_corners(*bounds)
    direction = np.asarray(light.direction, np.float64)
    direction = direction / np.linalg.norm(direction)
    frame = _orthonormal_frame(light.matrix_world)
    # The frame's Z is the light's local +Z; the sun shines along -Z (light.direction).
    if frame[:, 2] @ direction > 0.0:
        frame = frame * np.array([1.0, -1.0, -1.0])
    x_axis, y_axis = frame[:, 0], frame[:, 1]
    frustum = camera_frustum_corners(scene.camera) if scene.camera is not None else None
    rectangle = sun_fit_rectangle(frustum, bounds, x_axis, y_axis)
    if rectangle is None:
        return []
    (u0, v0), (u1, v1) = rectangle
    extent = float(np.ptp(box, axis=0).max())
    floor = 1e-6 * max(extent, 1e-3)
    hx = max(0.5 * float(u1 - u0), floor)
    hy = max(0.5 * float(v1 - v0), floor)
    centre = 0.5 * (u0 + u1) * x_axis + 0.5 * (v0 + v1) * y_axis
    depth = box @ direction  # the whole scene along the sun: occluders outside the camera count
    margin = 0.01 * max(extent, 1e-3)
    origin = centre + (depth.min() - margin) * direction - ((centre @ direction) * direction)
    view = view_from_frame(frame, origin)
    near, far = 0.5 * margin, float(np.ptp(depth)) + 1.5 * margin
    return [RSMViewSpec("sun", False, view, orthographic_projection(hx, hy, near, far), (hx, hy), near, far)]


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
        corners = box_corners(*bounds)
        clip = np.c_[corners, np.ones(8)] @ matrix
        if _outside_one_plane(clip[None])[0]:
            return False
    h = np.c_[positions.reshape(-1, 3), np.ones(positions.shape[0] * 3)] @ matrix
    return bool(np.any(~_outside_one_plane(h.reshape(-1, 3, 4))))


#: Smallest RSM side the plan gives a light that shares N with others. √share × the settings' side
#: keeps a light's texels per VSGL what one light alone has (128² for N = 256: 64); a point light
#: with 3 % of N (8 VSGLs over 6 cube views) needs 11² per view for that, so 32² still gives each of
#: its VSGLs 12 times the lone light's texels. The views are also the direct light's shadow maps,
#: whose texel grows with it (a 90° cube face of 32²: 2.8°). Measured on 32 point lights at N = 256
#: (benchmarks/frame_planner.py's 32-light variant, llvmpipe): the light passes 553 -> 340 ms from a
#: 64² floor to 32², 278 ms at 16².
MIN_RSM_SIZE = 32


def rsm_size_for_share(rsm_size: int, share: float) -> int:
    """The RSM side of a light expected to get ``share`` of the frame's VSGLs: √share × ``rsm_size``
    rounded up to a power of two, within [min(MIN_RSM_SIZE, rsm_size), rsm_size]."""
    floor = min(MIN_RSM_SIZE, rsm_size)
    if not share > 0.0:
        return floor
    side = rsm_size * math.sqrt(min(share, 1.0))
    return int(min(max(2 ** math.ceil(math.log2(max(side, 1.0)) - 1e-9), floor), rsm_size))
