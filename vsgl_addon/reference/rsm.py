# SPDX-License-Identifier: GPL-3.0-or-later
"""Float64 twin of the RSM texel quantities (formulas.md §4; 000 §4): what ``glsl/rsm/rsm.frag.glsl``
computes per texel, given the texel's ray, position, normal and material.

Used by the tests of :mod:`vsgl_addon.passes.rsm` and by anything that needs the light model of the
RSM without a GPU. Blender's units throughout: the lights are the emission model of
:mod:`vsgl_addon.reference.lights` (point and spot P/(4π) W/sr, spot times Blender's cone, area a
Lambertian point emitter (P/π) cos θ, sun S W/m²), the one the direct light uses.

A texel's flux is Φ = I(ω) dω: the intensity towards the texel centre times the texel's solid angle
dω = ∫ cos³ dA over the texel's area on the image plane at distance 1 (:func:`texel_solid_angles`;
the midpoint rule, area × cos³ at the centre, would be off by 1 % in the corner texels of a 16²
cube face, so the GPU integrates it exactly: see ``glsl/rsm/rsm.frag.glsl`` texel_solid_angle); for
a sun, S times the texel's area on the sun's plane (orthographic view).

Reflectances (:func:`principled_reflectances`): the Principled BSDF base layer of
:mod:`vsgl_addon.reference.principled` (Cycles' model, calibrated against its Diffuse/Glossy Color
passes), the one the direct light uses, evaluated for the texel's incidence ω' (from the surface
towards the light), μ' = n·ω'. A texel lit from ω' reflects the intensity Φ ρ(ω', ω) ⟨ω, n⟩
(formulas.md §4), and its two lobes carry

* Rd = base colour × (1 − metallic) × (1 − E_spec(μ')): the flux the dielectric layer lets through
  to the Lambertian base (Cycles' layering weight with the dielectric lobe's directional albedo,
  real Fresnel and multiple scattering included), so the diffuse lobe of 000 Eq. 6,
  Rd · G(ω; n, λd)/A(λd), re-emits Φ·Rd in all;
* Rs = (1 − metallic) E_dielectric(μ') + metallic E_metal(μ'): the directional albedo of the
  specular lobes for incidence ω' (the fraction of Φ they reflect, with Cycles' multiple-scattering
  energy compensation), so the normalized warped lobe of 000 Eq. 7, Rs · G(ω; ξs, λs)/A(λs),
  re-emits Φ·Rs in all.

Cycles' layering weight depends on the outgoing direction of a path (here ω, towards the receiving
point); a VPL carries one Rd for every receiver, and by reciprocity the incidence ω' gives the
energy the texel actually reflects of the light it receives.

The specular lobe of a texel is 000 Eq. 7's spherical warp (``sg.specular_lobe_warp``) for the
incoming direction ω' with GGX α = max(roughness², 1e-6) (``principled.principled_alpha``: the
roughness 1e-3 keeps λh = 2/α² finite for a roughness of 0).
"""

from __future__ import annotations

import numpy as np

from .numerics import f64, norm
from .principled import principled_alpha, principled_terms
from .sg import specular_lobe_warp


def principled_reflectances(base_color, metallic, specular_ior_level, ior, roughness, cos_incidence):
    """(Rd, Rs) RGB of a texel whose surface (Principled base layer) is lit at μ' = n·ω'
    (``cos_incidence``; see the module documentation): the diffuse reflectance and the specular
    lobes' directional albedo. Numpy broadcasting over texels."""
    terms = principled_terms(base_color, metallic, specular_ior_level, ior, roughness, cos_incidence)
    return terms["diffuse"], terms["specular_albedo"]


def texel_solid_angles(size: int, half_extent) -> np.ndarray:
    """(size, size) exact solid angles of the texels of a perspective view whose image plane at
    distance 1 spans [−hx, hx] × [−hy, hy] (row 0 = bottom, as the GPU's texture rows).

    Closed form per texel: the solid angle of [0, x] × [0, y] at distance 1 is
    atan(xy / √(1 + x² + y²)); a texel is four such corners. (The GPU takes this form up to 8²
    texels and 3×3 Gauss-Legendre on cos³ beyond, within 2e-6 of it.)
    """
    hx, hy = (float(v) for v in half_extent)
    edges = np.linspace(-1.0, 1.0, size + 1)
    x = edges[None, :] * hx
    y = edges[:, None] * hy
    corner = np.arctan(x * y / np.sqrt(1.0 + x * x + y * y))
    return corner[1:, 1:] - corner[1:, :-1] - corner[:-1, 1:] + corner[:-1, :-1]


def texel_rays(size: int, half_extent, view_to_world) -> np.ndarray:
    """(size, size, 3) unit world directions from the light through the texel centres."""
    hx, hy = (float(v) for v in half_extent)
    centres = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    u, v = np.meshgrid(centres * hx, centres * hy)
    local = np.stack([u, v, -np.ones_like(u)], axis=-1)
    local /= norm(local)[..., None]
    return local @ f64(view_to_world)[:3, :3].T


def incoming_directions(light, positions) -> np.ndarray:
    """ω' per texel (..., 3): unit, from the surface towards the light (a sun: −its direction)."""
    positions = f64(positions)
    if light.type == "SUN":
        return np.broadcast_to(-f64(light.direction), positions.shape).copy()
    towards = f64(light.position) - positions
    return towards / norm(towards)[..., None]


def specular_lobes(incoming, normal, roughness):
    """(ξs, λs) of the texels: 000 Eq. 7's warp with α = ``principled.principled_alpha``."""
    return specular_lobe_warp(incoming, normal, principled_alpha(roughness))
