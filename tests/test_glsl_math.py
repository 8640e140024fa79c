"""The GLSL SG/ASG/GGX libraries (glsl/lib) against the float64 numpy reference, on the GPU.

Every function is evaluated over a parameter grid that includes the extremes (sharpness 1e-6 … 1e6
and the 5e9 the grazing warp reaches, roughness 1e-3 … 1, cosines −1, 0, ±1e-7, 1, coincident and
opposite axes, angles scaled to each lobe's width θ = k/√λ plus far-off angles, ASG bandwidths
1e-6 … 1e7 in both directions, grazing views, axis-aligned and tilted frames). Inputs are made in
float64 and rounded to float32 (what the GPU sees); the reference runs in float64 on exactly those
float32 values. Criterion (glsl_harness.Accuracy): relative error <= 1e-4 wherever the reference is
above 1e-6 of its grid maximum, absolute error <= 1e-7 elsewhere, no NaN or Inf from the GPU.
Outputs that span many orders of magnitude by construction (normalized lobes, sharpnesses, GGX D)
are judged per slice of the scale parameter (see each case's comment): the "grid maximum" is the
slice's, and the absolute bound is in units of it when it exceeds 1 (glsl_harness.Accuracy says
why). Vectors are judged by the norm of the error against the norm of the reference.

Several functions are ill-conditioned in float32 at the grid's extremes (a cosine or tangent
coordinate cancelled out of O(1) products, then multiplied by a sharpness of up to 5e9): the GLSL
computes those parts in twice the precision (math.glsl); the tilted frames of the grid are what
exposes them (axis-aligned ones make every product exact).

One shader per function, the whole grid in one pass.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from glsl_harness import Accuracy, as_gpu_floats, evaluate_glsl
from vsgl_addon.reference import asg, ggx, sg
from vsgl_addon.shaders import GLSL_ROOT

pytestmark = pytest.mark.gpu

# --- Grid building blocks (float64; rounded to float32 by `as_gpu_floats`) -----------------------

_RNG_SEED = 20240611

# Lobe offsets in units of the lobe's width 1/sqrt(sharpness): exp(-k^2/2) from 1 down to 1.5e-8.
WIDTHS = np.array([0.0, 0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0])
# Far-off angles (radians), independent of the sharpness.
FAR_ANGLES = np.array([1e-2, 0.1, 0.5, 1.0, math.pi / 2, 2.0, 2.5, math.pi])
SHARPNESSES = np.concatenate(([0.0], np.logspace(-6.0, 6.0, 25)))
ROUGHNESSES = np.logspace(-3.0, 0.0, 7)
# Cosines of an incoming or view direction with the normal: normal incidence, grazing (around the
# floor 1e-4 of the warp), exactly tangent, and from below.
COSINES = np.array([1.0, 0.999, 0.9, 0.5, 0.1, 1e-2, 1e-3, 3e-4, 1.5e-4, 1e-4, 5e-5, 1e-7, 0.0,
                    -1e-7, -1e-3, -0.5, -1.0])


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _normals(count_tilted: int = 5, seed: int = _RNG_SEED) -> np.ndarray:
    """Axis-aligned normals (every product exact in float32) and tilted ones (nothing exact)."""
    rng = np.random.default_rng(seed)
    aligned = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    return np.concatenate((aligned, _unit(rng.normal(size=(count_tilted, 3)))))


def _tangents(axis):
    """Two unit vectors completing `axis` (unit, float64) to an orthonormal frame."""
    axis = np.asarray(axis, dtype=np.float64)
    helper = np.where(np.abs(axis[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    t1 = _unit(np.cross(axis, helper))
    return t1, np.cross(axis, t1)


def _around(axis, theta, psi):
    """Directions at angle `theta` from `axis`, azimuth `psi` (all broadcast; float64)."""
    axis = np.asarray(axis, dtype=np.float64)
    t1, t2 = _tangents(axis)
    theta = np.asarray(theta, dtype=np.float64)[..., None]
    psi = np.asarray(psi, dtype=np.float64)[..., None]
    return np.cos(theta) * axis + np.sin(theta) * (np.cos(psi) * t1 + np.sin(psi) * t2)


def _widths_and_far(sharpness, widths=WIDTHS, far=FAR_ANGLES):
    """Angles k/sqrt(sharpness) (within pi) followed by the far-off angles."""
    if sharpness > 0.0:
        near = widths / math.sqrt(sharpness)
        near = near[near <= math.pi]
    else:
        near = np.zeros(1)
    return np.concatenate((near, far))


def _table(rows: list[dict]) -> dict[str, np.ndarray]:
    """A list of per-point dicts as a dict of float64 arrays, rounded to float32 values."""
    return {name: as_gpu_floats([row[name] for row in rows]) for name in rows[0]}


# --- Cases ---------------------------------------------------------------------------------------


@dataclass
class Output:
    """One output of a GLSL function, its reference and the slices of its grid."""

    name: str
    size: int  # floats
    reference: Callable[[dict], np.ndarray]
    groups: Callable[[dict], np.ndarray] | None = None  # None: the whole grid is one slice


@dataclass
class Case:
    function: str
    library: str
    body: str  # GLSL; the inputs are locals named like the grid's keys
    grid: Callable[[], dict]  # name -> float32-valued float64 array (+ private keys starting "_")
    outputs: list[Output]


def _sg_evaluate_grid():
    rng = np.random.default_rng(_RNG_SEED + 1)
    rows = []
    for axis in _normals():
        for lam in SHARPNESSES:
            for theta in _widths_and_far(lam):
                for psi in rng.uniform(0.0, 2.0 * math.pi, 3):
                    rows.append({"omega": _around(axis, theta, psi), "axis": axis, "sharpness": lam})
    return _table(rows)


def _sg_integral_grid():
    return {"sharpness": as_gpu_floats(np.concatenate(([0.0, 1e-37], np.logspace(-8.0, 10.0, 721))))}


def _sg_product_grid():
    """Pairs of sharpness in {0} + 1e-6 … 1e6 (and the warp's 5e9), second axis coincident, opposite,
    k/sqrt(lam) from the first or from its opposite for either sharpness, and far off."""
    rng = np.random.default_rng(_RNG_SEED + 2)
    values = np.concatenate(([0.0], np.logspace(-6.0, 6.0, 13), [5e9]))
    rows = []
    for axis1 in _normals(3):
        for lam1 in values:
            for lam2 in values:
                angles = [0.0, math.pi, *FAR_ANGLES[1:6]]
                for lam in {lam1, lam2}:
                    if lam > 0.0:
                        near = WIDTHS[1:] / math.sqrt(lam)
                        near = near[near < 1.0]
                        angles += [*near, *(math.pi - near)]
                psi = rng.uniform(0.0, 2.0 * math.pi, len(angles))
                for theta, phi in zip(angles, psi):
                    rows.append({"axis1": axis1, "sharpness1": lam1, "axis2": _around(axis1, theta, phi),
                                 "sharpness2": lam2})
    return _table(rows)


def _pair_groups(grid):
    return np.stack((grid["sharpness1"], grid["sharpness2"]), axis=-1)


def _diffuse_grid():
    rng = np.random.default_rng(_RNG_SEED + 3)
    rows = []
    for normal in _normals():
        for theta in np.concatenate((np.linspace(0.0, math.pi, 91), [1e-7, math.pi / 2 - 1e-7])):
            for psi in rng.uniform(0.0, 2.0 * math.pi, 2):
                rows.append({"omega": _around(normal, theta, psi), "normal": normal})
    return _table(rows)


def _roughness_grid():
    return {"roughness": as_gpu_floats(np.logspace(-3.0, 0.0, 301))}


def _incoming(normal, cosine, psi):
    """A unit direction with the given cosine to `normal` (float64)."""
    return _around(normal, math.acos(cosine), psi)


def _warp_grid():
    rng = np.random.default_rng(_RNG_SEED + 4)
    rows = []
    for normal in _normals():
        for cosine in COSINES:
            for psi in rng.uniform(0.0, 2.0 * math.pi, 2):
                for alpha in ROUGHNESSES:
                    rows.append({"incoming": _incoming(normal, cosine, psi), "normal": normal,
                                 "roughness": alpha})
    return _table(rows)


def _specular_lobe_grid():
    """omega around the reference's lobe axis at k/sqrt(lam_s) (the lobe of the float32 inputs)."""
    rng = np.random.default_rng(_RNG_SEED + 5)
    base = _warp_grid()
    axis, lam = sg.specular_lobe_warp(base["incoming"], base["normal"], base["roughness"])
    rows = []
    for index in range(len(lam)):
        lobe_axis = _unit(axis[index])
        for theta in _widths_and_far(lam[index], far=FAR_ANGLES[::2]):
            rows.append({"omega": _around(lobe_axis, theta, rng.uniform(0.0, 2.0 * math.pi)),
                         "incoming": base["incoming"][index], "normal": base["normal"][index],
                         "roughness": base["roughness"][index], "_slice": index})
    return _table(rows)


SG_CASES = [
    Case("sg_evaluate", "lib/sg.glsl", "sg_evaluate(omega, axis, sharpness)", _sg_evaluate_grid,
         [Output("result", 1, lambda g: sg.sg_evaluate(g["omega"], g["axis"], g["sharpness"]))]),
    # A(lam) ~ 2 pi / lam spans 17 orders over the grid: every sharpness is its own slice.
    Case("sg_integral", "lib/sg.glsl", "sg_integral(sharpness)", _sg_integral_grid,
         [Output("result", 1, lambda g: sg.sg_integral(g["sharpness"]), lambda g: g["sharpness"])]),
    # sharpness = |xi_m| in [0, lam1 + lam2] and the product integral ~ 2 pi / (lam1 + lam2) scale
    # with the pair of sharpnesses: one slice per pair. The scale is in [0, 1], the axis a unit vector.
    Case("sg_product", "lib/sg.glsl",
         "sg_product(axis1, sharpness1, axis2, sharpness2, product_axis, product_sharpness, product_scale);",
         _sg_product_grid,
         [Output("product_axis", 3, lambda g: sg.sg_product(g["axis1"], g["sharpness1"], g["axis2"], g["sharpness2"])[0]),
          Output("product_sharpness", 1,
                 lambda g: sg.sg_product(g["axis1"], g["sharpness1"], g["axis2"], g["sharpness2"])[1], _pair_groups),
          Output("product_scale", 1,
                 lambda g: sg.sg_product(g["axis1"], g["sharpness1"], g["axis2"], g["sharpness2"])[2])]),
    Case("sg_product_integral", "lib/sg.glsl", "sg_product_integral(axis1, sharpness1, axis2, sharpness2)",
         _sg_product_grid,
         [Output("result", 1, lambda g: sg.sg_product_integral(g["axis1"], g["sharpness1"], g["axis2"],
                                                                g["sharpness2"]), _pair_groups)]),
    # The normalized lobe peaks at ~lam / (2 pi) (1.6e5 at lam = 1e6): one slice per sharpness.
    Case("sg_lobe_normalized", "lib/sg.glsl", "sg_lobe_normalized(omega, axis, sharpness)", _sg_evaluate_grid,
         [Output("result", 1, lambda g: sg.sg_lobe_normalized(g["omega"], g["axis"], g["sharpness"]),
                 lambda g: g["sharpness"])]),
    Case("diffuse_lobe", "lib/sg.glsl", "diffuse_lobe(omega, normal)", _diffuse_grid,
         [Output("result", 1, lambda g: sg.diffuse_lobe(g["omega"], g["normal"]))]),
    # 2 / alpha^2 from 2 to 2e6: one slice per roughness.
    Case("ndf_sharpness", "lib/sg.glsl", "ndf_sharpness(roughness)", _roughness_grid,
         [Output("result", 1, lambda g: sg.ndf_sharpness(g["roughness"]), lambda g: g["roughness"])]),
    # lam_s = 2 / alpha^2 / (4 max(|cos|, 1e-4)) reaches 5e9: one slice per roughness.
    Case("specular_lobe_warp", "lib/sg.glsl", "specular_lobe_warp(incoming, normal, roughness, lobe_axis, lobe_sharpness);",
         _warp_grid,
         [Output("lobe_axis", 3, lambda g: sg.specular_lobe_warp(g["incoming"], g["normal"], g["roughness"])[0]),
          Output("lobe_sharpness", 1, lambda g: sg.specular_lobe_warp(g["incoming"], g["normal"], g["roughness"])[1],
                 lambda g: g["roughness"])]),
    # Peaks at ~lam_s / (2 pi), up to 8e8: one slice per lobe (incoming direction, normal, roughness).
    Case("specular_lobe", "lib/sg.glsl", "specular_lobe(omega, incoming, normal, roughness)", _specular_lobe_grid,
         [Output("result", 1, lambda g: sg.specular_lobe(g["omega"], g["incoming"], g["normal"], g["roughness"]),
                 lambda g: g["_slice"])]),
]

# ASG bandwidths at both ends, with both anisotropies (every ordered pair).
BANDWIDTHS = np.array([0.0, 1e-6, 1e-3, 1.0, 10.0, 1e3, 1e5, 1e7])


def _frames(count_tilted: int = 5):
    """Orthonormal frames (x, y, z), float64: axis-aligned ones and tilted ones."""
    frames = []
    for z in _normals(count_tilted):
        x, y = _tangents(z)
        frames.append((x, y, z))
    return frames


def _asg_evaluate_grid():
    """omega tilted from z towards x by k/sqrt(eta_x), towards y by k/sqrt(eta_y), both at once,
    and far off (including below the horizon, where Ga = 0)."""
    rng = np.random.default_rng(_RNG_SEED + 6)
    rows = []
    for x, y, z in _frames():
        for eta_x in BANDWIDTHS:
            for eta_y in BANDWIDTHS:
                directions = []
                for k in WIDTHS:
                    ax = k / math.sqrt(eta_x) if eta_x > 0.0 else 0.0
                    ay = k / math.sqrt(eta_y) if eta_y > 0.0 else 0.0
                    if ax < math.pi / 2:
                        directions.append(math.cos(ax) * z + math.sin(ax) * x)
                    if ay < math.pi / 2:
                        directions.append(math.cos(ay) * z - math.sin(ay) * y)
                    if max(ax, ay) < math.pi / 2:
                        directions.append(_unit(z + math.tan(ax) * x + math.tan(ay) * y))
                for theta in FAR_ANGLES:
                    psi = rng.uniform(0.0, 2.0 * math.pi)
                    directions.append(math.cos(theta) * z + math.sin(theta) * (math.cos(psi) * x + math.sin(psi) * y))
                for omega in directions:
                    rows.append({"omega": omega, "x_axis": x, "y_axis": y, "z_axis": z,
                                 "eta_x": eta_x, "eta_y": eta_y})
    return _table(rows)


def _asg_lobe_grid():
    """The warp grid plus views near normal incidence (sines 1e-6 and 1e-3, and 1e-8 for the
    axis-aligned normals, where it is exact in float32: the fixed-tangent branch)."""
    rng = np.random.default_rng(_RNG_SEED + 7)
    rows = []
    normals = _normals()
    for index, normal in enumerate(normals):
        sines = [1e-6, 1e-3] + ([1e-8] if index < 3 else [])
        directions = [_incoming(normal, cosine, psi) for cosine in COSINES
                      for psi in rng.uniform(0.0, 2.0 * math.pi, 2)]
        directions += [_around(normal, math.asin(sine), rng.uniform(0.0, 2.0 * math.pi)) for sine in sines]
        for view in directions:
            for alpha in ROUGHNESSES:
                rows.append({"view": view, "normal": normal, "roughness": alpha})
    return _table(rows)


def _asg_lobe(grid):
    return asg.asg_specular_lobe(grid["view"], grid["normal"], grid["roughness"])


def _convolution_grid():
    """ASGs of every bandwidth pair (1e-6 ... 1e7 and the 2.5e13 of a grazing lobe; eta + nu > 0 keeps
    the reference finite) times SGs of sharpness 0 ... 1e6, the SG axis tilted from z by k/sqrt of
    the reduced bandwidths and far off."""
    rng = np.random.default_rng(_RNG_SEED + 8)
    bandwidths = np.concatenate((BANDWIDTHS[1:], [2.5e13]))
    rows = []
    for x, y, z in _frames(2):
        for eta_x in bandwidths:
            for eta_y in bandwidths:
                for lam in (0.0, 1e-6, 1e-2, 1.0, 100.0, 1e4, 1e6):
                    nu = lam / 2.0
                    rx, ry = eta_x * nu / (eta_x + nu), eta_y * nu / (eta_y + nu)
                    directions = [z]
                    for k in WIDTHS[1::2]:
                        for reduced, tangent in ((rx, x), (ry, y)):
                            angle = k / math.sqrt(reduced) if reduced > 0.0 else math.pi
                            if angle < math.pi / 2:
                                directions.append(math.cos(angle) * z + math.sin(angle) * tangent)
                    for theta in FAR_ANGLES[::2]:
                        psi = rng.uniform(0.0, 2.0 * math.pi)
                        directions.append(math.cos(theta) * z + math.sin(theta) * (math.cos(psi) * x + math.sin(psi) * y))
                    for p in directions:
                        rows.append({"sg_axis": p, "sg_sharpness": lam, "x_axis": x, "y_axis": y, "z_axis": z,
                                     "eta_x": eta_x, "eta_y": eta_y})
    return _table(rows)


def _asg_integral_grid():
    etas = np.concatenate((np.logspace(-6.0, 7.0, 27), [2.5e13]))
    eta_x, eta_y, amplitude = np.meshgrid(etas, etas, [1.0, 0.5, 1e-3, 1e3], indexing="ij")
    return {"eta_x": as_gpu_floats(eta_x.ravel()), "eta_y": as_gpu_floats(eta_y.ravel()),
            "amplitude": as_gpu_floats(amplitude.ravel())}


def _each_point(grid):
    return np.arange(len(next(iter(grid.values()))))


_CONVOLUTION_ARGUMENTS = ("sg_axis", "sg_sharpness", "x_axis", "y_axis", "z_axis", "eta_x", "eta_y")

ASG_CASES = [
    Case("asg_evaluate", "lib/asg.glsl", "asg_evaluate(omega, x_axis, y_axis, z_axis, eta_x, eta_y)",
         _asg_evaluate_grid,
         [Output("result", 1, lambda g: asg.asg_evaluate(g["omega"], g["x_axis"], g["y_axis"], g["z_axis"],
                                                         g["eta_x"], g["eta_y"]))]),
    # The frame is three unit vectors; eta_x = lam_h / (8 cos^2) up to 2.5e13 and eta_y = lam_h / 8
    # scale with the roughness: one slice per roughness.
    Case("asg_specular_lobe", "lib/asg.glsl",
         "asg_specular_lobe(view, normal, roughness, lobe_x, lobe_y, lobe_z, lobe_eta_x, lobe_eta_y);",
         _asg_lobe_grid,
         [Output("lobe_x", 3, lambda g: _asg_lobe(g)[0]),
          Output("lobe_y", 3, lambda g: _asg_lobe(g)[1]),
          Output("lobe_z", 3, lambda g: _asg_lobe(g)[2]),
          Output("lobe_eta_x", 1, lambda g: _asg_lobe(g)[3], lambda g: g["roughness"]),
          Output("lobe_eta_y", 1, lambda g: _asg_lobe(g)[4], lambda g: g["roughness"])]),
    # pi / sqrt((eta_x + nu)(eta_y + nu)) spans 1e-7 ... 3e6: one slice per (lam, eta_x, eta_y).
    Case("sg_asg_convolution", "lib/asg.glsl", f"sg_asg_convolution({', '.join(_CONVOLUTION_ARGUMENTS)})",
         _convolution_grid,
         [Output("result", 1, lambda g: asg.sg_asg_convolution(*(g[name] for name in _CONVOLUTION_ARGUMENTS)),
                 lambda g: np.stack((g["sg_sharpness"], g["eta_x"], g["eta_y"]), axis=-1))]),
    # pi t / sqrt(eta_x eta_y) spans 20 orders: every point is its own slice (relative error only).
    Case("asg_integral", "lib/asg.glsl", "asg_integral(eta_x, eta_y, amplitude)", _asg_integral_grid,
         [Output("result", 1, lambda g: asg.asg_integral(g["eta_x"], g["eta_y"], g["amplitude"]), _each_point)]),
]


def _ndf_grid():
    """Cosines -1 ... 1 with the extremes, cos(k alpha) across the peak, and the float32 values
    just below 1 (the peak of alpha = 1e-3 is 5e-7 wide in cosine, 8 float32 steps)."""
    rows = []
    base = [-1.0, -0.5, -1e-7, 0.0, 1e-7, 1e-3, 0.1, 0.5, 0.9, 0.99, 1.0]
    below_one = [1.0 - j * 2.0 ** -24 for j in range(1, 17)]
    for alpha in np.logspace(-3.0, 0.0, 13):
        peak = [math.cos(k * alpha) for k in (0.1, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 8.0, 16.0, 64.0)
                if k * alpha < math.pi]
        for c in base + below_one + peak:
            rows.append({"cos_theta": c, "roughness": alpha})
    return _table(rows)


def _masking_grid():
    cosines = [0.0, 1e-7, 1e-5, 1e-3, 0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 0.999, 1.0]
    rows = [{"cos_theta": sign * c, "roughness": alpha} for sign in (1.0, -1.0) for c in cosines
            for alpha in np.logspace(-3.0, 0.0, 13)]
    return _table(rows)


def _fresnel_grid():
    cosines = np.concatenate((np.linspace(-1.0, 1.0, 201), [-1e-7, 1e-7, 1.0 - 2.0 ** -24, 1e-3]))
    rows = [{"cos_theta": c, "f0": f0} for c in cosines for f0 in (0.0, 0.02, 0.04, 0.5, 0.95, 1.0)]
    return _table(rows)


def _brdf_grid():
    """Incoming directions at every cosine of COSINES, outgoing ones around the mirror direction at
    k alpha (the half vector then leaves the normal by ~k alpha / 2, the NDF's width) and far off."""
    rng = np.random.default_rng(_RNG_SEED + 9)
    rows = []
    group = 0
    for normal in _normals(3):
        for cosine in COSINES:
            incoming = _incoming(normal, cosine, rng.uniform(0.0, 2.0 * math.pi))
            mirror = _unit(2.0 * np.dot(incoming, normal) * normal - incoming)
            for alpha in ROUGHNESSES:
                angles = [*(2.0 * WIDTHS * alpha)[2.0 * WIDTHS * alpha < math.pi], *FAR_ANGLES]
                for f0 in (0.04, 1.0):
                    for theta in angles:
                        outgoing = _around(mirror, theta, rng.uniform(0.0, 2.0 * math.pi))
                        rows.append({"incoming": incoming, "outgoing": outgoing, "normal": normal,
                                     "roughness": alpha, "f0": f0, "_slice": group})
                    group += 1
    return _table(rows)


GGX_CASES = [
    # D(1) = 1 / (pi alpha^2) reaches 3e5: one slice per roughness.
    Case("ggx_ndf", "lib/ggx.glsl", "ggx_ndf(cos_theta, roughness)", _ndf_grid,
         [Output("result", 1, lambda g: ggx.ggx_ndf(g["cos_theta"], g["roughness"]), lambda g: g["roughness"])]),
    Case("g1_distant", "lib/ggx.glsl", "g1_distant(cos_theta, roughness)", _masking_grid,
         [Output("result", 1, lambda g: ggx.g1_distant(g["cos_theta"], g["roughness"]))]),
    Case("fresnel_schlick", "lib/ggx.glsl", "fresnel_schlick(cos_theta, f0)", _fresnel_grid,
         [Output("result", 1, lambda g: ggx.fresnel_schlick(g["cos_theta"], g["f0"]))]),
    # D of the half vector of directions above the surface (0 below, as microfacet_brdf uses it):
    # up to 3e5; one slice per lobe.
    Case("ggx_half_vector_ndf", "lib/ggx.glsl",
         "ggx_cosine(incoming, normal) > 0.0 && ggx_cosine(outgoing, normal) > 0.0 ? "
         "ggx_half_vector_ndf(incoming, outgoing, normal, roughness) : 0.0", _brdf_grid,
         [Output("result", 1, lambda g: np.where(
             (np.sum(g["incoming"] * g["normal"], -1) > 0.0) & (np.sum(g["outgoing"] * g["normal"], -1) > 0.0),
             ggx.ggx_half_vector_ndf(g["incoming"], g["outgoing"], g["normal"], g["roughness"]), 0.0),
             lambda g: g["_slice"])]),
    # Peaks at F D(1) / ((c_i + s_i)(c_o + s_o)), up to ~3e11 at alpha = 1e-3 and grazing incidence:
    # one slice per lobe (normal, incoming direction, roughness, f0).
    Case("microfacet_brdf", "lib/ggx.glsl", "microfacet_brdf(incoming, outgoing, normal, roughness, f0)", _brdf_grid,
         [Output("result", 1, lambda g: ggx.microfacet_brdf(g["incoming"], g["outgoing"], g["normal"],
                                                            g["roughness"], g["f0"]), lambda g: g["_slice"])]),
]

CASES = SG_CASES + ASG_CASES + GGX_CASES


def _run(case: Case, roots: tuple[Path, ...] = ()) -> tuple[dict, dict[str, Accuracy]]:
    """Evaluate `case` on its grid; `roots` may shadow glsl/ files (to check that the test fails)."""
    grid = case.grid()
    inputs = {name: values for name, values in grid.items() if not name.startswith("_")}
    sizes = {output.name: output.size for output in case.outputs}
    results = evaluate_glsl(case.body, inputs, sizes if len(sizes) > 1 or case.outputs[0].name != "result" else 1,
                            libraries=[case.library], roots=roots)
    if not isinstance(results, dict):
        results = {"result": results}
    accuracies = {}
    for output in case.outputs:
        groups = output.groups(grid) if output.groups else None
        accuracies[output.name] = Accuracy(results[output.name], output.reference(grid), groups)
    return inputs, accuracies


@pytest.mark.parametrize("case", CASES, ids=[case.function for case in CASES])
def test_glsl_matches_reference(case):
    inputs, accuracies = _run(case)
    problems = [f"{case.function} -> {name}: {accuracy.report(inputs)}"
                for name, accuracy in accuracies.items() if not accuracy.ok]
    assert not problems, "\n".join(problems)


# --- Constants shared with the reference -----------------------------------------------------------

_CONSTANT = re.compile(r"^const float (\w+) = ([^;]+);", re.MULTILINE)


MATH_LIBRARIES = ("math.glsl", "sg.glsl", "asg.glsl", "ggx.glsl")


def _glsl_constants() -> dict[str, str]:
    constants = {}
    for path in (GLSL_ROOT / "lib" / name for name in MATH_LIBRARIES):
        for name, value in _CONSTANT.findall(path.read_text(encoding="utf-8")):
            assert name not in constants, f"{name} is defined twice in glsl/lib"
            constants[name] = value
    return constants


# GLSL name -> the reference's value.
SHARED_CONSTANTS = {
    "COSINE_FLOOR": sg.COSINE_FLOOR,
    "DIFFUSE_SHARPNESS": sg.DIFFUSE_SHARPNESS,
    "ASG_PARALLEL_SINE": asg._PARALLEL_SINE,
    "PI": math.pi,
    "TWO_PI": 2.0 * math.pi,
    "FOUR_PI": 4.0 * math.pi,
}


def test_constants_are_the_references():
    constants = _glsl_constants()
    for name, value in SHARED_CONSTANTS.items():
        assert name in constants, f"glsl/lib defines no {name}"
        assert np.float32(float(constants[name])) == np.float32(value), (name, constants[name], value)


def test_constants_reach_the_gpu_as_the_references_float32():
    names = list(SHARED_CONSTANTS)
    values = evaluate_glsl(f"result = vec4({', '.join(names[:4])});\nsecond = vec2({', '.join(names[4:])});",
                           {"unused": np.zeros(1)}, {"result": 4, "second": 2}, libraries=["lib/asg.glsl"])
    gpu = np.concatenate((values["result"][0], values["second"][0]))
    expected = np.array([SHARED_CONSTANTS[name] for name in names], dtype=np.float32)
    assert np.array_equal(gpu, expected.astype(np.float64)), dict(zip(names, gpu))


# --- math.glsl -----------------------------------------------------------------------------------


def test_expm1():
    """Relative error everywhere (every point its own slice); the series range |x| < 0.5 does not
    depend on the driver's exp and is checked at the float32 level too."""
    x = as_gpu_floats(np.concatenate((
        [0.0, 1e-37, -1e-37], np.logspace(-30.0, 0.0, 301), -np.logspace(-30.0, 0.0, 301),
        np.linspace(-1.0, 1.0, 20001), np.linspace(-80.0, 80.0, 1601),
        np.nextafter(np.float32([0.5, -0.5]), np.float32(0.0)), [0.5, -0.5])))
    gpu = evaluate_glsl("expm1(x)", {"x": x}, libraries=["lib/math.glsl"])
    reference = np.expm1(x)
    accuracy = Accuracy(gpu, reference, np.arange(len(x)))
    assert accuracy.ok, accuracy.report({"x": x})
    series = (np.abs(x) < 0.5) & (reference != 0.0)
    assert np.max(np.abs(gpu[series] / reference[series] - 1.0)) < 3e-7


def test_one_minus_exp_ratio():
    # Up to 1e37: beyond, the result is a float32 denormal, which the GPU flushes to 0.
    x = as_gpu_floats(np.concatenate(([0.0, 1e-37], np.logspace(-30.0, 37.0, 671), [np.inf])))
    gpu = evaluate_glsl("one_minus_exp_ratio(x)", {"x": x}, libraries=["lib/math.glsl"])
    with np.errstate(invalid="ignore", divide="ignore"):
        reference = np.where(x > 0.0, -np.expm1(-x) / x, 1.0)
    reference[np.isinf(x)] = 0.0
    accuracy = Accuracy(gpu, reference, np.arange(len(x)))
    assert accuracy.ok, accuracy.report({"x": x})


def test_safe_normalize_and_length():
    """Magnitudes 1e-30 ... 1e30 (the plain dot(v, v) under- or overflows beyond ~1e+-19) and 0."""
    rng = np.random.default_rng(_RNG_SEED + 10)
    scales = np.logspace(-30.0, 30.0, 61)
    directions = _unit(rng.normal(size=(len(scales) * 4, 3)))
    directions[:3] = np.eye(3)  # one non-zero component
    v = as_gpu_floats(directions * np.repeat(scales, 4)[:, None])
    v = np.concatenate((v, np.zeros((1, 3))))
    results = evaluate_glsl("unit = safe_normalize(v, vec3(0.0, 0.0, -1.0));\nlength_ = safe_length(v);",
                            {"v": v}, {"unit": 3, "length_": 1}, libraries=["lib/math.glsl"])
    norms = np.linalg.norm(v, axis=-1)
    expected = np.where(norms[:, None] > 0.0, v / np.where(norms > 0.0, norms, 1.0)[:, None], [0.0, 0.0, -1.0])
    for name, gpu, reference in (("unit", results["unit"], expected), ("length", results["length_"], norms)):
        accuracy = Accuracy(gpu, reference, np.arange(len(v)))
        assert accuracy.ok, f"{name}: {accuracy.report({'v': v})}"


def test_error_free_transformations_are_exact():
    """two_sum and two_product return the rounded result and its exact error (Knuth; Dekker)."""
    rng = np.random.default_rng(_RNG_SEED + 11)
    count = 20000
    a = as_gpu_floats(rng.choice([-1.0, 1.0], count) * 10.0 ** rng.uniform(-3.0, 3.0, count))
    b = as_gpu_floats(rng.choice([-1.0, 1.0], count) * 10.0 ** rng.uniform(-3.0, 3.0, count))
    b[:100] = as_gpu_floats(-a[:100] * (1.0 + 2.0 ** -20))  # cancelling sums
    results = evaluate_glsl("sum_ = two_sum(a, b);\nproduct = two_product(a, b);", {"a": a, "b": b},
                            {"sum_": 2, "product": 2}, libraries=["lib/math.glsl"])
    # float32 sums (exponents within 2^29 here) and products (48 bits) are exact in float64.
    for name, exact in (("sum_", a + b), ("product", a * b)):
        high, low = results[name][:, 0], results[name][:, 1]
        assert np.array_equal(high, as_gpu_floats(exact)), name  # the rounded result
        assert np.array_equal(high + low, exact), name  # and its exact error


def test_dot_accurate():
    """As if computed in twice the precision: Ogita-Rump-Oishi's bound for Dot2 in float32 is
    |error| <= eps |a.b| + ~3.3 eps^2 sum|a_i b_i|, eps = 2^-24; the plain dot product is checked
    to be worse (the cancelling cases are the point)."""
    rng = np.random.default_rng(_RNG_SEED + 12)
    count = 50000
    a = _unit(rng.normal(size=(count, 3)))
    b = _unit(rng.normal(size=(count, 3)))
    b = _unit(b - np.sum(a * b, axis=-1, keepdims=True) * a + a * np.logspace(-12.0, 0.0, count)[:, None])
    a, b = as_gpu_floats(a), as_gpu_floats(b)
    results = evaluate_glsl("rounded = dot_accurate(a, b);\nsplit_ = dot_accurate2(a, b);\nplain = dot(a, b);",
                            {"a": a, "b": b}, {"rounded": 1, "split_": 2, "plain": 1}, libraries=["lib/math.glsl"])
    exact = np.sum(a * b, axis=-1)  # float32 products are exact in float64
    magnitude = np.sum(np.abs(a * b), axis=-1)
    eps = 2.0 ** -24
    assert np.all(np.abs(results["split_"].sum(axis=-1) - exact) <= 4.0 * eps * eps * magnitude)
    assert np.all(np.abs(results["rounded"] - exact) <= eps * np.abs(exact) + 4.0 * eps * eps * magnitude)
    cancelled = np.abs(exact) < 1e-4 * magnitude
    assert cancelled.sum() > 1000
    assert (np.max(np.abs(results["plain"] - exact)[cancelled])
            > 100.0 * np.max(np.abs(results["rounded"] - exact)[cancelled]))


# --- The harness itself ----------------------------------------------------------------------------


def test_harness_lays_out_inputs_and_outputs_exactly():
    """n not a multiple of the grid width, several rows, inputs of 1-4 floats, several outputs."""
    from glsl_harness import probe

    rng = np.random.default_rng(_RNG_SEED + 13)
    count = 2048 * 3 + 5
    inputs = {"s": rng.normal(size=count), "v2": rng.normal(size=(count, 2)),
              "v3": rng.normal(size=(count, 3)), "v4": rng.normal(size=(count, 4))}
    body = "first = vec4(s, v2, float(gl_FragCoord.x));\nsecond = v3;\nthird = v4;"
    results = evaluate_glsl(body, inputs, {"first": 4, "second": 3, "third": 4})
    assert np.array_equal(results["first"][:, 0], as_gpu_floats(inputs["s"]))
    assert np.array_equal(results["first"][:, 1:3], as_gpu_floats(inputs["v2"]))
    assert np.array_equal(results["second"], as_gpu_floats(inputs["v3"]))
    assert np.array_equal(results["third"], as_gpu_floats(inputs["v4"]))
    assert np.array_equal(results["first"][:, 3], np.arange(count) % 2048 + 0.5)
    # A single output comes back as (n,); the compiled probe is reused for other inputs and sizes.
    single = evaluate_glsl("s * 2.0", {"s": inputs["s"][:7]})
    assert single.shape == (7,) and np.array_equal(single, 2.0 * as_gpu_floats(inputs["s"][:7]))
    assert probe("s * 2.0", {"s": 1}) is probe("s * 2.0", {"s": 1})
    assert evaluate_glsl("s * 2.0", {"s": np.zeros(0)}).shape == (0,)


def test_harness_rejects_bad_inputs_and_reports_compile_errors():
    from vsgl_addon.shaders import ShaderCompileError

    with pytest.raises(ValueError, match="shape"):
        evaluate_glsl("s", {"s": np.zeros((3, 5))})
    with pytest.raises(ValueError, match="length"):
        evaluate_glsl("a + b", {"a": np.zeros(3), "b": np.zeros(4)})
    with pytest.raises(ShaderCompileError) as caught:
        evaluate_glsl("no_such_function(s)", {"s": np.zeros(3)})
    assert "no_such_function" in str(caught.value)
    assert any("generated stage" in note for note in caught.value.__notes__)


def test_erfc():
    """Relative error where erfc is a float32 normal (x < 9.1), erfc(−x) = 2 − erfc(x)."""
    x = as_gpu_floats(np.concatenate(([0.0], np.linspace(-10.0, 9.0, 3801), np.logspace(-30.0, 0.9, 200),
                                      -np.logspace(-30.0, 0.9, 200))))
    gpu = evaluate_glsl("erfc(x)", {"x": x}, libraries=["lib/math.glsl"])
    reference = np.array([math.erfc(v) for v in x])
    assert np.all(np.isfinite(gpu))
    # Numerical Recipes' fit: 1.2e-7; the float32 exponent −x² − 1.27 + … carries ~x² ulp on top.
    normal = reference > 1e-37
    relative = np.abs(gpu[normal] / reference[normal] - 1.0)
    assert np.all(relative <= 4e-7 * (1.0 + x[normal] ** 2)), float(np.max(relative / (1.0 + x[normal] ** 2)))
    assert np.all(gpu[~normal] < 1e-36)


def test_sg_clamped_cosine_integral():
    """sg.glsl's twin of reference sg_clamped_cosine_integral over sharpness 0, 1e-6 … 1e20 (the
    switches at λ = 0.5 and 1 on both sides) and cosines −1 … 1 (grazing, below the horizon): per
    sharpness relative error ≤ 1e-4 above 1e-6 of its peak S(1, λ) (glsl_harness.Accuracy), and its
    pieces Su, Sl, t to 1e-5."""
    lam = np.concatenate(([0.0], np.logspace(-6.0, 6.0, 49), [1e10, 1e20], np.nextafter(np.float32([0.5, 1.0]), 0),
                          np.nextafter(np.float32([0.5, 1.0]), 2)))
    mu = np.concatenate((np.linspace(-1.0, 1.0, 81), COSINES))
    grid_lam, grid_mu = (a.ravel() for a in np.meshgrid(lam, mu, indexing="ij"))
    inputs = {"cosine": as_gpu_floats(grid_mu), "sharpness": as_gpu_floats(grid_lam)}
    body = ("result = sg_clamped_cosine_integral(cosine, sharpness);\n"
            "parts = vec3(sg_upper_clamped_cosine(sharpness), sg_lower_clamped_cosine(sharpness), "
            "sg_clamped_cosine_steepness(sharpness));")
    gpu = evaluate_glsl(body, inputs, {"result": 1, "parts": 3}, libraries=["lib/sg.glsl"])
    assert np.all(np.isfinite(gpu["result"])) and np.all(np.isfinite(gpu["parts"]))
    reference = sg.sg_clamped_cosine_integral(inputs["cosine"], inputs["sharpness"])
    accuracy = Accuracy(gpu["result"], reference, inputs["sharpness"])
    assert accuracy.ok, accuracy.report(inputs)
    parts = np.stack((sg.sg_upper_clamped_cosine(inputs["sharpness"]), sg.sg_lower_clamped_cosine(inputs["sharpness"]),
                      sg.sg_clamped_cosine_steepness(inputs["sharpness"])), -1)
    significant = parts > 1e-30
    np.testing.assert_allclose(gpu["parts"][significant], parts[significant], rtol=1e-5)
