# SPDX-License-Identifier: GPL-3.0-or-later
"""Rectangle proxies of the scene's planar glossy reflectors (001 §3.6), from a SceneDescription.

001 approximates the scene's planar reflectors by rectangles ("rectangle proxies", built by offline
tools in the paper). Here they are found in the triangles themselves, bpy-free:

1. Candidate triangles: a material whose specular lobe is sharp, GGX α = roughness² below α_c
   (``caustic_roughness``, the split of light-paths.md), per object overridden by
   :data:`PROXY_MODES` ("always": every planar region of the object whatever its roughness,
   "never": none).
   Only triangles shaded flat (corner normals along the face normal) count: a smooth sphere's
   facets are planar but it is no planar reflector.
2. Planar regions: candidates with the same material whose planes agree (normals within
   ``NORMAL_TOLERANCE``, offsets within ``PLANE_TOLERANCE`` of the scene's size), connected through
   shared corners (positions within the same tolerance).
3. Each region with a large enough area gets its minimum-area oriented bounding rectangle (rotating
   calipers over the convex hull of its corners in the plane) and its material's GGX α and
   Schlick F0 (Principled: mix of the dielectric F0 and the base colour by metallic).

:func:`build_proxies` depends only on the geometry, the materials, α_c and the overrides, so a
:class:`ProxyCache` rebuilds only when one of these changes (not when a light or the view moves).
:func:`lit_proxies` is the per-frame filter: only proxies some light reaches and that have some
scene geometry (a receiver) in front of them are kept, each side on its own, so a scene without any
pays nothing.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from .layouts import PROXY_TABLE
from .reference.lights import light_intensity
from .reference.principled import principled_dielectric_f0
from .settings import PROXY_OVERRIDES

#: Per-object override of the automatic choice (stored by properties.py).
PROXY_MODES = PROXY_OVERRIDES.names
#: Default α_c: GGX α below which a reflector's specular lobe is "sharp" (light-paths.md).
CAUSTIC_ROUGHNESS = 0.1
#: Triangles are coplanar when their unit normals differ by less than this (≈ 0.6°).
NORMAL_TOLERANCE = 1e-2
#: Offsets and corner positions agree within this fraction of the scene's bounding diagonal.
PLANE_TOLERANCE = 1e-5
#: Smallest proxy area, as a fraction of the squared scene diagonal.
MIN_AREA_FRACTION = 1e-4
#: At most this many proxies (the GPU pass's table), the largest kept.
MAX_PROXIES = 16


@dataclass(frozen=True)
class RectangleProxy:
    """One rectangle R (001 §3.2): centre, unit normal (the region's front side), in-plane unit axes
    (u, v = n × u) and half extents, its material (index, GGX α, Schlick F0 RGB), where it comes
    from (object index, triangle count) and its triangles' area."""

    center: np.ndarray
    normal: np.ndarray
    axis_u: np.ndarray
    axis_v: np.ndarray
    half_u: float
    half_v: float
    material_index: int
    object_index: int
    alpha: float
    f0: np.ndarray
    area: float
    triangle_count: int

    def as_rect(self, channel: int | None = None) -> dict:
        """The mapping ``reference.mrp_asg`` takes (F0 of one channel, or its mean)."""
        f0 = float(np.mean(self.f0)) if channel is None else float(self.f0[channel])
        return dict(center=self.center, normal=self.normal, axis_u=self.axis_u, axis_v=self.axis_v,
                    half_u=self.half_u, half_v=self.half_v, roughness=self.alpha, f0=f0)

    def corners(self) -> np.ndarray:
        """(4, 3) corners, counter-clockwise about the normal (the debug overlay's outline)."""
        u = self.axis_u * self.half_u
        v = self.axis_v * self.half_v
        return np.array([self.center - u - v, self.center + u - v, self.center + u + v, self.center - u + v])


def material_f0(material) -> np.ndarray:
    """Schlick F0 (RGB) of a Principled material: dielectric F0 mixed with the base colour by metallic
    (a base colour image counts with its mean)."""
    base = np.asarray(material.base_color, np.float64)
    if material.base_color_image is not None:
        base = np.asarray(material.base_color_image, np.float64)[..., :3].reshape(-1, 3).mean(axis=0)
    dielectric = float(principled_dielectric_f0(material.ior, material.specular_ior_level))
    metallic = float(np.clip(material.metallic, 0.0, 1.0))
    return np.clip((1.0 - metallic) * dielectric + metallic * base, 0.0, 1.0)


def material_alpha(material) -> float:
    r = float(np.clip(material.roughness, 0.0, 1.0))
    return r * r


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Andrew's monotone chain, (H, 2) counter-clockwise (collinear points dropped)."""
    pts = np.unique(points, axis=0)
    if len(pts) < 3:
        return pts

    def half(sequence):
        chain = []
        for p in sequence:
            while len(chain) >= 2:
                a, b = chain[-2], chain[-1]
                if (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) > 0.0:
                    break
                chain.pop()
            chain.append(p)
        return chain

    lower = half(pts)
    upper = half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def oriented_rectangle(points: np.ndarray):
    """Minimum-area bounding rectangle of 2D ``points``: (centre (2,), axis (2,), half extents (2,)).
    One of its sides is collinear with a hull edge (Freeman–Shapira), so each edge direction is tried."""
    hull = _convex_hull(points)
    if len(hull) < 3:
        lo, hi = points.min(axis=0), points.max(axis=0)
        return 0.5 * (lo + hi), np.array([1.0, 0.0]), 0.5 * (hi - lo)
    edges = np.roll(hull, -1, axis=0) - hull
    lengths = np.linalg.norm(edges, axis=1)
    edges = edges[lengths > 0.0] / lengths[lengths > 0.0, None]
    normals = np.stack((-edges[:, 1], edges[:, 0]), axis=1)
    a = hull @ edges.T  # (H, E)
    b = hull @ normals.T
    area = (a.max(0) - a.min(0)) * (b.max(0) - b.min(0))
    best = int(np.argmin(area))
    axis, other = edges[best], normals[best]
    mid_a = 0.5 * (a[:, best].max() + a[:, best].min())
    mid_b = 0.5 * (b[:, best].max() + b[:, best].min())
    half = 0.5 * np.array([a[:, best].max() - a[:, best].min(), b[:, best].max() - b[:, best].min()])
    return mid_a * axis + mid_b * other, axis, half


def _components(keys_a: np.ndarray, keys_b: np.ndarray, count: int) -> np.ndarray:
    """Connected components of ``count`` items where items sharing a key (two key columns per
    item set; rows (item, key)) are connected: label = smallest item index (label propagation)."""
    labels = np.arange(count)
    item = keys_a
    key = keys_b
    _, key_index = np.unique(key, return_inverse=True)
    for _ in range(count + 1):
        smallest = np.full(key_index.max() + 1 if len(key_index) else 0, count, np.int64)
        np.minimum.at(smallest, key_index, labels[item])
        new = labels.copy()
        np.minimum.at(new, item, smallest[key_index])
        new = new[new]  # pointer jumping
        if np.array_equal(new, labels):
            break
        labels = new
    return labels


def build_proxies(scene, caustic_roughness: float = CAUSTIC_ROUGHNESS, overrides=None,
                  max_proxies: int = MAX_PROXIES) -> list[RectangleProxy]:
    """The rectangle proxies of ``scene`` (a SceneDescription); see the module documentation.
    ``overrides``: object name -> one of :data:`PROXY_MODES` (missing names are "auto")."""
    geometry = scene.geometry
    positions = np.asarray(geometry.positions, np.float64)
    if len(positions) == 0:
        return []
    overrides = overrides or {}
    mode_of_object = np.array([PROXY_MODES.index(overrides.get(name, "auto")) for name in scene.object_names]
                              or [0], np.int64)
    materials = scene.materials
    alpha = np.array([material_alpha(m) for m in materials])
    material_index = np.asarray(geometry.material_index, np.int64)
    object_index = np.asarray(geometry.object_index, np.int64)
    mode = mode_of_object[np.clip(object_index, 0, len(mode_of_object) - 1)]
    candidate = np.where(mode == 1, True, np.where(mode == 2, False, alpha[material_index] < caustic_roughness))
    cross = np.cross(positions[:, 1] - positions[:, 0], positions[:, 2] - positions[:, 0])
    double_area = np.linalg.norm(cross, axis=1)
    lo, hi = positions.reshape(-1, 3).min(axis=0), positions.reshape(-1, 3).max(axis=0)
    diagonal = max(float(np.linalg.norm(hi - lo)), 1e-12)
    candidate &= double_area > (1e-9 * diagonal) ** 2
    # Shaded flat: every corner normal along the face normal. A smooth-shaded curved surface (a
    # sphere's facets) is planar per triangle but not a planar reflector.
    face = cross / np.maximum(double_area, 1e-300)[:, None]
    corner = np.asarray(geometry.normals, np.float64)
    corner_cos = np.abs(np.einsum("tij,tj->ti", corner, face)) / np.maximum(np.linalg.norm(corner, axis=2), 1e-300)
    candidate &= np.all(corner_cos > 1.0 - NORMAL_TOLERANCE ** 2, axis=1)
    index = np.flatnonzero(candidate)
    if len(index) == 0:
        return []
    tri = positions[index]
    normal = cross[index] / double_area[index, None]
    offset = np.einsum("ij,ij->i", normal, tri[:, 0])
    # Plane buckets: quantized normal (sign fixed by the largest component) and offset, material.
    sign = np.sign(normal[np.arange(len(normal)), np.argmax(np.abs(normal), axis=1)])
    sign[sign == 0] = 1.0
    bucket_key = np.column_stack((np.round(normal * sign[:, None] / NORMAL_TOLERANCE),
                                  np.round(offset * sign / (PLANE_TOLERANCE * diagonal * 100.0)),
                                  material_index[index], object_index[index])).astype(np.int64)
    _, bucket = np.unique(bucket_key, axis=0, return_inverse=True)
    bucket = bucket.reshape(-1)
    corners = np.round(tri.reshape(-1, 3) / (PLANE_TOLERANCE * diagonal)).astype(np.int64)
    corner_key = np.column_stack((np.repeat(bucket, 3), corners))
    _, corner_id = np.unique(corner_key, axis=0, return_inverse=True)
    labels = _components(np.repeat(np.arange(len(index)), 3), corner_id.reshape(-1), len(index))
    proxies = []
    min_area = MIN_AREA_FRACTION * diagonal * diagonal
    for label in np.unique(labels):
        members = np.flatnonzero(labels == label)
        area = 0.5 * float(double_area[index[members]].sum())
        if area < min_area:
            continue
        weights = double_area[index[members]]
        n = (normal[members] * weights[:, None]).sum(axis=0)
        length = float(np.linalg.norm(n))
        if not (np.isfinite(length) and length > 0.0):
            continue  # degenerate (non-finite or cancelling) triangles: no plane
        n /= length
        points = tri[members].reshape(-1, 3)
        origin = points.mean(axis=0)
        helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(n, helper)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        local = np.column_stack(((points - origin) @ e1, (points - origin) @ e2))
        center2, axis2, half = oriented_rectangle(local)
        u = axis2[0] * e1 + axis2[1] * e2
        v = np.cross(n, u)
        center = origin + center2[0] * e1 + center2[1] * e2 + n * float(np.mean((points - origin) @ n))
        material = int(material_index[index[members[0]]])
        proxies.append(RectangleProxy(center=center, normal=n, axis_u=u, axis_v=v, half_u=float(half[0]),
                                      half_v=float(half[1]), material_index=material,
                                      object_index=int(object_index[index[members[0]]]),
                                      alpha=float(alpha[material]), f0=material_f0(materials[material]),
                                      area=area, triangle_count=len(members)))
    proxies.sort(key=lambda p: -p.area)
    return proxies[:max_proxies]


def flipped(proxy: RectangleProxy) -> RectangleProxy:
    """The same rectangle seen from its other side (normal and v negated, u kept: still right-handed)."""
    return RectangleProxy(**{**proxy.__dict__, "normal": -proxy.normal, "axis_v": -proxy.axis_v})


def lit_proxies(proxies, scene, samples: int = 5) -> list[tuple[RectangleProxy, np.ndarray]]:
    """(proxy, lit-by mask over scene.lights) of the proxies some light reaches and that have scene
    geometry in front of them, per side: triangles are two-sided, so each side of a rectangle is a
    reflector of the lights on that side (a proxy lit from both sides comes out twice, once with
    each normal). The light test samples a samples² grid on the rectangle (a spot's cone, an area
    light's front half-space). Occlusion is not tested here (the pass shadows each peak from the
    light's shadow map)."""
    positions = np.asarray(scene.geometry.positions, np.float64).reshape(-1, 3)
    grid = (np.arange(samples) + 0.5) / samples * 2.0 - 1.0
    kept = []
    for base in proxies:
        for proxy in (base, flipped(base)):
            tol = PLANE_TOLERANCE * 100.0 * max(proxy.half_u, proxy.half_v, 1e-9)
            if not np.any((positions - proxy.center) @ proxy.normal > tol):
                continue
            points = (proxy.center + grid[:, None, None] * proxy.half_u * proxy.axis_u
                      + grid[None, :, None] * proxy.half_v * proxy.axis_v).reshape(-1, 3)
            mask = np.zeros(len(scene.lights), bool)
            for i, light in enumerate(scene.lights):
                if light.type == "SUN":
                    mask[i] = float(-np.asarray(light.direction) @ proxy.normal) > 0.0
                    continue
                if float((np.asarray(light.position) - proxy.center) @ proxy.normal) <= 0.0:
                    continue
                directions = points - np.asarray(light.position)
                directions /= np.linalg.norm(directions, axis=1, keepdims=True)
                mask[i] = bool(np.any(light_intensity(light, directions) > 0.0))
            if mask.any():
                kept.append((proxy, mask))
    return kept


#: Debug outline colours (RGBA): a proxy some light reaches (MRP-ASG shades with it), one no light
#: reaches or no receiver faces (built, not used), and the tick along a lit side's normal.
OUTLINE_LIT = (1.0, 0.75, 0.1, 1.0)
OUTLINE_UNLIT = (0.55, 0.55, 0.55, 0.8)
OUTLINE_NORMAL = (0.2, 0.8, 1.0, 1.0)


def outline_lines(proxies, lit) -> tuple[np.ndarray, np.ndarray]:
    """(positions (2L, 3), colours (2L, 4)) float32 of line segments (pairs of rows) outlining
    ``proxies`` (every built rectangle) for the debug overlay: the four edges of each, coloured
    :data:`OUTLINE_LIT` when it has a side in ``lit`` ((proxy, mask) pairs) and :data:`OUTLINE_UNLIT`
    otherwise, and for each lit side a tick from the centre along that side's normal, a quarter of
    the rectangle's shorter side long (which way it reflects)."""
    lit_keys = [(proxy.object_index, proxy.material_index, np.asarray(proxy.center, np.float64)) for proxy, _ in lit]
    points, colours = [], []
    for proxy in proxies:
        corners = proxy.corners()
        centre = np.asarray(proxy.center, np.float64)
        is_lit = any(o == proxy.object_index and m == proxy.material_index and np.allclose(c, centre)
                     for o, m, c in lit_keys)
        for i in range(4):
            points += [corners[i], corners[(i + 1) % 4]]
            colours += [OUTLINE_LIT if is_lit else OUTLINE_UNLIT] * 2
    for proxy, _ in lit:
        tick = 0.5 * min(proxy.half_u, proxy.half_v)
        points += [proxy.center, proxy.center + tick * np.asarray(proxy.normal, np.float64)]
        colours += [OUTLINE_NORMAL] * 2
    if not points:
        return np.zeros((0, 3), np.float32), np.zeros((0, 4), np.float32)
    return np.asarray(points, np.float32), np.asarray(colours, np.float32)


def describe_proxies(lit, scene) -> list[dict]:
    """Plain, JSON-ready rows of ``lit`` ((proxy, lit-by mask) pairs, as :func:`lit_proxies` and
    ``renderer.scene_proxies`` give them) for the statistics panel and the render report: the object,
    the material, the rectangle's size (m), the material's roughness and GGX α, the side's normal
    and the names of the lights that reach that side."""
    rows = []
    for proxy, mask in lit:
        names = scene.object_names
        material = scene.materials[proxy.material_index] if 0 <= proxy.material_index < len(scene.materials) else None
        rows.append({
            "object": names[proxy.object_index] if 0 <= proxy.object_index < len(names) else "",
            "material": getattr(material, "name", ""),
            "size": [round(2.0 * proxy.half_u, 6), round(2.0 * proxy.half_v, 6)],
            "area": round(float(proxy.area), 6),
            "roughness": round(float(np.sqrt(max(proxy.alpha, 0.0))), 6),
            "alpha": round(float(proxy.alpha), 6),
            "normal": [round(float(c), 6) for c in proxy.normal],
            "triangles": int(proxy.triangle_count),
            "lit_by": [light.name for light, lit_by in zip(scene.lights, mask) if lit_by],
        })
    return rows


def describe_row(row: dict) -> str:
    """One line of the statistics panel for a :func:`describe_proxies` row."""
    lights = ", ".join(row["lit_by"]) or "no light"
    return (f"{row['object']}: {row['size'][0]:.2f} × {row['size'][1]:.2f} m, "
            f"roughness {row['roughness']:.3f}, lit by {lights}")


def geometry_key(scene, caustic_roughness: float, overrides) -> str:
    """What the proxies depend on: triangles, material indices and materials' roughness, metallic,
    colour and IOR, α_c, the overrides."""
    digest = hashlib.blake2b(digest_size=16)
    geometry = scene.geometry
    for array in (geometry.positions, geometry.material_index, geometry.object_index):
        digest.update(np.ascontiguousarray(array).tobytes())
    for material in scene.materials:
        digest.update(np.asarray([material.roughness, material.metallic, material.specular_ior_level,
                                  material.ior, *np.asarray(material.base_color, np.float64)]).tobytes())
    digest.update(repr((float(caustic_roughness), sorted((overrides or {}).items()), scene.object_names)).encode())
    return digest.hexdigest()


class ProxyCache:
    """The proxies of the last geometry seen; rebuilt only when :func:`geometry_key` changes."""

    def __init__(self):
        self.key = None
        self.proxies: list[RectangleProxy] = []
        self.builds = 0

    def get(self, scene, caustic_roughness: float = CAUSTIC_ROUGHNESS, overrides=None) -> list[RectangleProxy]:
        key = geometry_key(scene, caustic_roughness, overrides)
        if key != self.key:
            self.proxies = build_proxies(scene, caustic_roughness, overrides)
            self.key = key
            self.builds += 1
        return self.proxies


def proxy_table_array(proxies) -> np.ndarray:
    """The (slots, max(count, 1), 4) float32 :data:`~vsgl_addon.layouts.PROXY_TABLE` of ``proxies``
    (what the MRP-ASG pass and the RSM read); with none, one column that matches no texel (negative
    half extents)."""
    proxies = list(proxies)
    if not proxies:
        return PROXY_TABLE.pack({"half_u": np.array([-1.0]), "half_v": np.array([-1.0])}, 1)
    values = {name: np.array([getattr(p, name) for p in proxies], np.float64)
              for name in ("center", "half_u", "normal", "half_v", "axis_u", "alpha", "axis_v", "f0")}
    values["roughness"] = np.sqrt(np.maximum(values["alpha"], 0.0))
    return PROXY_TABLE.pack(values, len(proxies))
