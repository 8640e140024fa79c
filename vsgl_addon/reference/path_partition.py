# SPDX-License-Identifier: GPL-3.0-or-later
"""The light-path table of ../shared/reference/light-paths.md as float64 code: which RSM texel's
flux belongs to which cell, and the brute force of one bounce restricted to a cell.

A one-bounce path light → y (an RSM texel) → x (a receiver) → eye is split by the reflector lobe at
y (diffuse Φ Rd; specular Φ Rs with GGX α ≥ α_c; sharp (α < α_c) on a rectangle proxy; sharp
elsewhere) and by the receiver lobe at x (diffuse, specular). The frame's techniques each take a
set of cells (VSGL sets, glossy VPLs, MRP-ASG); the check of light-paths.md is that the cells
summed are the whole and that the techniques' inputs, composed as the frame composes them, are
the whole too: a path counted twice gives more, a dropped one less
(tests/test_path_partition.py, benchmarks/path_partition.py).
"""

from __future__ import annotations

import numpy as np

from .ggx import microfacet_brdf
from .numerics import f64
from .principled import principled_alpha
from .rsm import incoming_directions

#: The reflector-lobe rows of light-paths.md's table, in its order.
CELLS = ("diffuse lobe", "specular, alpha >= alpha_c", "specular, sharp, on a proxy", "specular, sharp, elsewhere")


def rsm_on_proxy(position, geometric_normal, roughness, proxies, light=None) -> np.ndarray:
    """(M,) bool: texels in one of ``proxies`` as the glossy receivers' RSM tests it
    (glsl/rsm/rsm.frag.glsl rsm_on_proxy): in its plane and rectangle within 1e-4 of its size,
    parallel to it, of its Principled roughness (the proxy table's √α). ``proxies``: RectangleProxy
    (for every texel) or (proxy, lit-by mask) pairs, which with ``light`` (M,) (each texel's light
    index) hold only for the texels of the mask's lights (pipeline.render_scene_vsgls)."""
    position = f64(position).reshape(-1, 3)
    geometric_normal = f64(geometric_normal).reshape(-1, 3)
    roughness = f64(roughness).reshape(-1)
    inside = np.zeros(len(position), bool)
    for proxy in proxies:
        lights = np.ones(len(position), bool)
        if isinstance(proxy, tuple):
            proxy, mask = proxy
            if light is not None:
                lights = np.asarray(mask, bool)[np.asarray(light, np.int64)]
        tolerance = 1e-4 * (1.0 + max(proxy.half_u, proxy.half_v))
        d = position - f64(proxy.center)
        inside |= ((np.abs(d @ f64(proxy.normal)) <= tolerance)
                   & (np.abs(d @ f64(proxy.axis_u)) <= proxy.half_u + tolerance)
                   & (np.abs(d @ f64(proxy.axis_v)) <= proxy.half_v + tolerance)
                   & (np.abs(geometric_normal @ f64(proxy.normal)) > 0.999)
                   & (np.abs(roughness - np.sqrt(max(proxy.alpha, 0.0))) < 1e-4) & lights)
    return inside


def set_texels(table_set, lights) -> dict:
    """Every texel of every RSM view of a frame VSGL set (pipeline.SceneVSGLs: its views_by_light,
    each view's to_numpy()), flat, float64, in (light, view, texel) order: position, normal (unit),
    flux_diffuse Φ Rd, flux_specular Φ Rs, roughness (Principled), incoming ω' (towards the light),
    light (index), covered. ``lights``: the scene's lights (their positions give ω')."""
    parts = []
    for light_index in sorted(table_set.views_by_light):
        for view in table_set.views_by_light[light_index]:
            a = view.to_numpy()
            position = f64(a.rsm.position).reshape(-1, 3)
            normal = f64(a.rsm.normal).reshape(-1, 3)
            normal = normal / np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-30)
            parts.append({"position": position, "normal": normal,
                          "flux_diffuse": f64(a.rsm.flux_diffuse).reshape(-1, 3),
                          "flux_specular": f64(a.rsm.flux_specular).reshape(-1, 3),
                          "roughness": f64(a.roughness).reshape(-1),
                          "incoming": incoming_directions(lights[light_index], position),
                          "light": np.full(len(position), light_index),
                          "covered": np.asarray(a.coverage).reshape(-1)})
    if not parts:
        return {}
    return {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}


def cell_fluxes(texels: dict, proxies, caustic_roughness: float) -> dict:
    """cell name (:data:`CELLS`) -> (Φ Rd, Φ Rs) (M, 3) of ``texels`` (:func:`set_texels` of the
    whole RSM) that belong to it, a texel on a proxy only for the lights of its lit-by mask when
    ``proxies`` are (proxy, mask) pairs; the four sum to the texels' fluxes exactly."""
    sharp = principled_alpha(texels["roughness"]) < caustic_roughness
    proxy = rsm_on_proxy(texels["position"], texels["normal"], texels["roughness"], proxies, texels["light"])
    zero = np.zeros_like(texels["flux_diffuse"])
    fs = texels["flux_specular"]
    return {CELLS[0]: (texels["flux_diffuse"], zero),
            CELLS[1]: (zero, np.where((~sharp)[:, None], fs, 0.0)),
            CELLS[2]: (zero, np.where((sharp & proxy)[:, None], fs, 0.0)),
            CELLS[3]: (zero, np.where((sharp & ~proxy)[:, None], fs, 0.0))}


def brute_force_one_bounce(texels: dict, flux_diffuse, flux_specular, position, normal, view,
                           diffuse_reflectance, specular_f0, roughness, chunk: int = 16):
    """(diffuse, specular) radiance (P, 3) at the receivers from every texel as a VPL:
    Φ Rd/π ⟨ω, n⟩ + Φ Rs f_GGX(ω', ω; F = 1) ⟨ω, n⟩ (004 Eq. 7's glossy VPL, α ≥ 10⁻³ as its
    VPLs), onto the receiver's Lambert Rd/π and GGX (Schlick ``specular_f0``, GGX α ``roughness``);
    no visibility, texels at the receiver skipped. Linear in the fluxes, so the cells' sum is the
    whole's to rounding."""
    from .vpl_culling import VPL_ALPHA_MIN
    from .vsgl_shading import _ggx_rgb

    flux_diffuse, flux_specular = f64(flux_diffuse), f64(flux_specular)
    keep = (np.abs(flux_diffuse).sum(-1) + np.abs(flux_specular).sum(-1)) > 0.0
    y, n, w = texels["position"][keep], texels["normal"][keep], texels["incoming"][keep]
    fd, fs = flux_diffuse[keep], flux_specular[keep]
    ay = np.maximum(principled_alpha(texels["roughness"][keep]), VPL_ALPHA_MIN)
    position, normal, view = f64(position), f64(normal), f64(view)
    rd, f0, alpha = f64(diffuse_reflectance), f64(specular_f0), f64(roughness)
    diffuse = np.zeros((len(position), 3))
    specular = np.zeros((len(position), 3))
    for start in range(0, len(position), chunk):
        p = slice(start, start + chunk)
        r = y[None] - position[p, None]  # receiver -> texel
        d2 = np.einsum("pmi,pmi->pm", r, r)
        ok = d2 > 1e-12
        omega = r / np.sqrt(np.where(ok, d2, 1.0))[..., None]
        out = -omega  # texel -> receiver
        cos_y = np.maximum(np.einsum("pmi,mi->pm", out, n), 0.0)
        cos_x = np.maximum(np.einsum("pmi,pi->pm", omega, normal[p]), 0.0)
        geometry = np.where(ok, cos_y * cos_x / np.where(ok, d2, 1.0), 0.0)
        f1 = microfacet_brdf(np.broadcast_to(w, out.shape), out, np.broadcast_to(n, out.shape),
                             np.broadcast_to(ay, out.shape[:-1]), 1.0)
        irradiance = (fd[None] / np.pi + fs[None] * f1[..., None]) * geometry[..., None]
        diffuse[p] = irradiance.sum(axis=1) * rd[p] / np.pi
        brdf = _ggx_rgb(omega, np.broadcast_to(view[p, None], omega.shape),
                        np.broadcast_to(normal[p, None], omega.shape),
                        np.broadcast_to(alpha[p, None], omega.shape[:-1]), np.broadcast_to(f0[p, None], omega.shape))
        specular[p] = (irradiance * brdf).sum(axis=1)
    return diffuse, specular


def match_vpl_flux(texels: dict, vpl_position, vpl_flux, decimals: int = 6):
    """((M, 3) the glossy VPLs' Φ Rs at the texels of ``texels`` they were made from, matched by
    position; the number of VPLs matched to no texel)."""
    index = {tuple(np.round(p, decimals)): i for i, p in enumerate(texels["position"]) if texels["covered"][i]}
    flux = np.zeros_like(texels["flux_specular"])
    unmatched = 0
    for p, value in zip(f64(vpl_position), f64(vpl_flux)):
        i = index.get(tuple(np.round(p, decimals)))
        if i is None:
            unmatched += 1
        else:
            flux[i] += value
    return flux, unmatched
