"""VSGL shading on the GPU (llvmpipe): the GLSL twins (glsl/lib/vsgl_shading.glsl) and the
full-screen pass (vsgl_addon/passes/vsgl_shading.py) against the float64 reference
(vsgl_addon/reference/vsgl_shading.py).

GLSL twins: one VSGL lobe at one shading point over a randomized grid of the extremes (distance
0 … 1e3, σv² 0 … 100, λv 0 … 1e6 with the VSGL's axis at k/√λv of facing the shading point, far
off, or facing away, receiver roughness 1e-3 … 1, view cosines 1 … 0 and below, incoming
directions near the specular peak). Inputs are made in float64 and rounded to float32; the
reference runs on exactly those values. Criterion (glsl_harness.Accuracy): relative error ≤ 1e-4
where the reference is above 1e-6 of its slice maximum (slices: distance × σv² × λv × roughness),
no NaN/Inf. Points where the problem itself is ill-conditioned in float32 are excluded and
counted: the reference recomputed with the inputs moved by 1 float32 ulp changes by more than
3e-5 (see ``_conditioning``). Both the one-lobe function and the fused per-VSGL function the pass
uses are checked.

The pass: G-buffers made in numpy with extreme pixels (background, grazing views at cosines ±1e-2
… ±1e-4, normals facing away, roughness 1e-3 … 1, a pixel at a VSGL's mean, black and white
materials), N = 1 and N = 4096 (8x8 pixels), extreme VSGL tables, two tables blended, every
diffuse mode (the separable one also with receivers on a lit floor's own plane), the generation's table read on the GPU, perceptual roughness, an orthographic
camera: per pixel against the reference (relative 2e-4 + 1e-6 of the image or pixel maximum).
``test_shading_time`` prints the time against N and resolution.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from glsl_harness import RELATIVE_TOLERANCE, Accuracy, as_gpu_floats, evaluate_glsl
from vsgl_addon.reference import vsgl_shading as vs

pytestmark = pytest.mark.gpu

DISTANCES = np.array([0.0, 1e-6, 1e-3, 0.05, 1.0, 30.0, 1e3])
VARIANCES = np.array([0.0, 1e-12, 1e-9, 1e-6, 1e-3, 0.1, 1.0, 100.0])
SHARPNESSES = np.array([0.0, 1e-6, 1e-3, 0.1, 0.5, 2.0, 10.0, 1e3, 1e5, 1e6])
ROUGHNESSES = np.array([1e-3, 1e-2, 0.1, 0.5, 1.0])
VIEW_COSINES = np.array([1.0, 0.9, 0.5, 0.1, 1e-2, 1e-4, 0.0, -0.5])
WIDTHS = np.array([0.0, 0.5, 1.0, 2.0, 4.0])
FAR_ANGLES = np.array([1e-2, 0.5, math.pi / 2, 2.5, math.pi])


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _around(axis, theta, psi):
    axis = _unit(axis)
    helper = np.where(np.abs(axis[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    t1 = _unit(np.cross(axis, helper))
    t2 = np.cross(axis, t1)
    theta = np.asarray(theta)[..., None]
    psi = np.asarray(psi)[..., None]
    return np.cos(theta) * axis + np.sin(theta) * (np.cos(psi) * t1 + np.sin(psi) * t2)


def lobe_grid(count=60_000, seed=7):
    """Random combinations of the extremes (see the module documentation), float32 values."""
    rng = np.random.default_rng(seed)
    pick = lambda values: rng.integers(0, len(values), count)  # noqa: E731
    i_dist, i_var, i_lam, i_rough, i_cos = (pick(DISTANCES), pick(VARIANCES), pick(SHARPNESSES),
                                            pick(ROUGHNESSES), pick(VIEW_COSINES))
    dist, var, lam = DISTANCES[i_dist], VARIANCES[i_var], SHARPNESSES[i_lam]
    rough, cos_o = ROUGHNESSES[i_rough], VIEW_COSINES[i_cos]
    # Half the normals axis-aligned (exact products), half tilted.
    normal = np.where((rng.random(count) < 0.5)[:, None], [0.0, 0.0, 1.0], _unit(rng.normal(size=(count, 3))))
    view = _around(normal, np.arccos(cos_o), rng.uniform(0, 2 * np.pi, count))
    mirror = 2 * np.sum(view * normal, -1)[:, None] * normal - view
    # Direction to the VSGL: near the specular peak (k alpha off), random above, random anywhere.
    kind = rng.integers(0, 3, count)
    near_peak = _around(mirror, rng.choice([0.0, 0.3, 1.0, 2.0], count) * rough, rng.uniform(0, 2 * np.pi, count))
    anywhere = _unit(rng.normal(size=(count, 3)))
    above = anywhere * np.where(np.sum(anywhere * normal, -1) < 0, -1.0, 1.0)[:, None]
    xi_mu = np.where((kind == 0)[:, None], near_peak, np.where((kind == 1)[:, None], above, anywhere))
    # VSGL axis: facing the shading point within k/sqrt(lam), or far off.
    near = np.where(lam > 0, rng.choice(WIDTHS, count) / np.sqrt(np.maximum(lam, 1e-300)), 0.0)
    theta = np.where(rng.random(count) < 0.6, np.minimum(near, np.pi), rng.choice(FAR_ANGLES, count))
    axis = -_around(xi_mu, theta, rng.uniform(0, 2 * np.pi, count))
    scale = np.where(rng.random(count) < 0.5, 1.0, 100.0)
    position = rng.uniform(-1, 1, (count, 3)) * scale[:, None]
    mean = position + dist[:, None] * xi_mu
    grid = {"position": position, "mean": mean, "variance": var, "lobe_axis": _unit(axis),
            "lobe_sharpness": lam, "normal": normal, "view": view, "roughness": rough}
    grid = {name: as_gpu_floats(value) for name, value in grid.items()}
    groups = np.stack([i_dist, i_var, i_lam, i_rough], -1)
    return grid, groups


def lobe_reference(g):
    """Reference outputs of one lobe (amplitude 1): incoming (axis, λin), scale, both diffuse
    factors, the specular for F0 = 1 and F0 = 0.04 (the GLSL accumulates k (1 - m⁵) and k m⁵
    apart; each alone cancels where the other dominates, their F0-weighted sum does not)."""
    axis_in, lam_in, scale = vs.vsgl_incoming_sg(g["position"], g["mean"], g["variance"], g["lobe_axis"],
                                            g["lobe_sharpness"])
    cosine = scale * vs.vsgl_diffuse_factor(axis_in, lam_in, g["normal"], "cosine")
    conv = scale * vs.vsgl_diffuse_factor(axis_in, lam_in, g["normal"], "sg-convolution")
    clamped = scale * vs.vsgl_diffuse_factor(axis_in, lam_in, g["normal"], "clamped-cosine")
    xi_mu, lam_sigma, separable_scale = vs.vsgl_separable_lobe(g["position"], g["mean"], g["variance"],
                                                               g["lobe_axis"], g["lobe_sharpness"])
    separable = separable_scale * vs.vsgl_diffuse_factor(xi_mu, lam_sigma, g["normal"], "separable")
    _, _, lambert_scale = vs.vsgl_separable_lobe(g["position"], g["mean"], g["variance"], g["lobe_axis"],
                                                 g["lobe_sharpness"], "lambert")
    separable_lambert = lambert_scale * vs.vsgl_diffuse_factor(xi_mu, lam_sigma, g["normal"], "separable")
    k1 = vs.vsgl_specular_factor(axis_in, lam_in, g["view"], g["normal"], g["roughness"], np.ones((len(lam_in), 3)))[:, 0]
    k0 = vs.vsgl_specular_factor(axis_in, lam_in, g["view"], g["normal"], g["roughness"], np.zeros((len(lam_in), 3)))[:, 0]
    # The fused function's separable mode scales a diffuse lobe's specular to its Lambertian emission
    # where the receiver gathers from (vs.shade's product specular).
    toward = vs.specular_emission_direction(axis_in, lam_in, g["view"], g["normal"], g["roughness"])
    ratio = vs.vsgl_diffuse_emission_ratio(np.sum(-toward * g["lobe_axis"], -1), g["lobe_sharpness"])
    return {"incoming": np.concatenate([axis_in, lam_in[:, None]], -1), "scale": scale,
            "specular_separable_f0_1": scale * ratio * k1,
            "specular_separable_f0_004": scale * ratio * (0.04 * k1 + 0.96 * k0),
            "diffuse_cosine": cosine, "diffuse_convolution": conv, "diffuse_clamped_cosine": clamped,
            "diffuse_separable": separable, "diffuse_separable_lambert": separable_lambert,
            "specular_f0_1": scale * k1, "specular_f0_004": scale * (0.04 * k1 + 0.96 * k0)}


LOBE_BODY = """
vec3 axis_in; float sharpness_in; float s;
vsgl_incoming_sg(position, mean, variance, lobe_axis, lobe_sharpness, axis_in, sharpness_in, s);
incoming = vec4(axis_in, sharpness_in);
scale = s;
VSGLReceiver rc = vsgl_receiver(position, normal, view, roughness);
vec3 d0 = vec3(0.0), d1 = vec3(0.0), sp = vec3(0.0), fr = vec3(0.0), unused_s = vec3(0.0), unused_f = vec3(0.0);
vsgl_accumulate_lobe(rc, mean, variance, vec3(1.0), lobe_axis, lobe_sharpness, VSGL_DIFFUSE_COSINE, d0, sp, fr);
vsgl_accumulate_lobe(rc, mean, variance, vec3(1.0), lobe_axis, lobe_sharpness, VSGL_DIFFUSE_SG_CONVOLUTION, d1, unused_s, unused_f);
diffuse_cosine = d0.x;
diffuse_convolution = d1.x;
specular_f0_1 = sp.x + fr.x;
specular_f0_004 = 0.04 * sp.x + fr.x;
"""
LOBE_OUTPUTS = {"incoming": 4, "scale": 1, "diffuse_cosine": 1, "diffuse_convolution": 1,
                "specular_f0_1": 1, "specular_f0_004": 1}
# The clamped-cosine diffuse mode in a shader of its own (the harness has at most six outputs), the
# lobe in the diffuse slot of the fused function.
CLAMPED_BODIES = {"lobe": """
VSGLReceiver rc = vsgl_receiver(position, normal, view, roughness);
vec3 d = vec3(0.0), sp = vec3(0.0), fr = vec3(0.0);
vsgl_accumulate_lobe(rc, mean, variance, vec3(1.0), lobe_axis, lobe_sharpness, VSGL_DIFFUSE_CLAMPED_COSINE, d, sp, fr);
diffuse_clamped_cosine = d.x;
""", "fused": """
VSGLReceiver rc = vsgl_receiver(position, normal, view, roughness);
vec3 d = vec3(0.0), sp = vec3(0.0), fr = vec3(0.0);
vsgl_accumulate(rc, vsgl_position(position, mean, variance), vec3(1.0), lobe_axis, lobe_sharpness,
                vsgl_position(position, vec3(-7.0, 3.0, 1.0), 0.5), vec3(0.0), vec3(0.0, 0.0, 1.0), 1.0,
                VSGL_DIFFUSE_CLAMPED_COSINE, d, sp, fr);
diffuse_clamped_cosine = d.x;
"""}

# The separable diffuse mode (the modified and original kernels'), likewise in shaders of its own.
SEPARABLE_BODIES = {"lobe": """
VSGLReceiver rc = vsgl_receiver(position, normal, view, roughness);
vec3 d = vec3(0.0), sp = vec3(0.0), fr = vec3(0.0);
vsgl_accumulate_lobe(rc, mean, variance, vec3(1.0), lobe_axis, lobe_sharpness, VSGL_DIFFUSE_SEPARABLE, d, sp, fr);
diffuse_separable = d.x;
""", "fused": """
VSGLReceiver rc = vsgl_receiver(position, normal, view, roughness);
vec3 d = vec3(0.0), sp = vec3(0.0), fr = vec3(0.0);
vsgl_accumulate(rc, vsgl_position(position, mean, variance), vec3(1.0), lobe_axis, lobe_sharpness,
                vsgl_position(position, vec3(-7.0, 3.0, 1.0), 0.5), vec3(0.0), vec3(0.0, 0.0, 1.0), 1.0,
                VSGL_DIFFUSE_SEPARABLE, d, sp, fr);
diffuse_separable = d.x;
"""}

# Its specular, in a shader of its own.
SEPARABLE_SPECULAR_BODY = """
VSGLReceiver rc = vsgl_receiver(position, normal, view, roughness);
vec3 d = vec3(0.0), sp = vec3(0.0), fr = vec3(0.0);
vsgl_accumulate(rc, vsgl_position(position, mean, variance), vec3(1.0), lobe_axis, lobe_sharpness,
                vsgl_position(position, vec3(-7.0, 3.0, 1.0), 0.5), vec3(0.0), vec3(0.0, 0.0, 1.0), 1.0,
                VSGL_DIFFUSE_SEPARABLE, d, sp, fr);
specular_separable_f0_1 = sp.x + fr.x;
specular_separable_f0_004 = 0.04 * sp.x + fr.x;
"""
SEPARABLE_SPECULAR_OUTPUTS = {"specular_separable_f0_1": 1, "specular_separable_f0_004": 1}


def _conditioning(grid, reference, seed=11):
    """Largest relative change of each output when every input moves by ~1 float32 ulp."""
    rng = np.random.default_rng(seed)
    worst = {name: np.zeros(len(grid["variance"])) for name in reference}
    for _ in range(4):
        moved = {}
        for name, value in grid.items():
            ulp = np.spacing(np.abs(value).astype(np.float32)).astype(np.float64)
            moved[name] = value + rng.choice([-1.0, 1.0], value.shape) * ulp
        moved["lobe_axis"] = _unit(moved["lobe_axis"])
        moved["normal"] = _unit(moved["normal"])
        moved["view"] = _unit(moved["view"])
        moved["variance"] = np.maximum(moved["variance"], 0.0)
        moved["lobe_sharpness"] = np.maximum(moved["lobe_sharpness"], 0.0)
        moved["roughness"] = np.maximum(moved["roughness"], 0.0)
        other = lobe_reference(moved)
        for name in reference:
            a, b = reference[name], other[name]
            if a.ndim == 2:
                a, b = a[:, -1], b[:, -1]  # the sharpness
            with np.errstate(divide="ignore", invalid="ignore"):
                change = np.where(np.abs(a) > 0, np.abs(b - a) / np.abs(a), np.where(b == 0, 0.0, np.inf))
            worst[name] = np.maximum(worst[name], change)
    return worst


# The fused per-VSGL function the pass calls: the same outputs as LOBE_BODY's, with the lobe in the
# diffuse slot (first call: diffuse_cosine and the specular outputs) and in the specular slot
# (second call: diffuse_convolution); the other slot has no power and a position of its own, which
# must not leak into the lobe's (per-lobe positions).
FUSED_BODY = """
vec3 axis_in; float sharpness_in; float s;
vsgl_incoming_sg(position, mean, variance, lobe_axis, lobe_sharpness, axis_in, sharpness_in, s);
incoming = vec4(axis_in, sharpness_in);
scale = s;
VSGLReceiver rc = vsgl_receiver(position, normal, view, roughness);
vec3 d0 = vec3(0.0), d1 = vec3(0.0), sp = vec3(0.0), fr = vec3(0.0), unused_s = vec3(0.0), unused_f = vec3(0.0);
VSGLPosition here = vsgl_position(position, mean, variance);
VSGLPosition elsewhere = vsgl_position(position, vec3(-7.0, 3.0, 1.0), 0.5);
vsgl_accumulate(rc, here, vec3(1.0), lobe_axis, lobe_sharpness,
                elsewhere, vec3(0.0), vec3(0.0, 0.0, 1.0), 1.0, VSGL_DIFFUSE_COSINE, d0, sp, fr);
vsgl_accumulate(rc, elsewhere, vec3(0.0), vec3(0.0, 0.0, 1.0), 1.0,
                here, vec3(1.0), lobe_axis, lobe_sharpness, VSGL_DIFFUSE_SG_CONVOLUTION, d1,
                unused_s, unused_f);
diffuse_cosine = d0.x;
diffuse_convolution = d1.x;
specular_f0_1 = sp.x + fr.x;
specular_f0_004 = 0.04 * sp.x + fr.x;
"""


@pytest.fixture(scope="module")
def lobe_results(gpu_context):
    grid, groups = lobe_grid()
    start = time.perf_counter()
    gpu = {body: evaluate_glsl(source, grid, LOBE_OUTPUTS, libraries=["lib/vsgl_shading.glsl"])
           for body, source in (("lobe", LOBE_BODY), ("fused", FUSED_BODY))}
    for body, source in CLAMPED_BODIES.items():
        gpu[body]["diffuse_clamped_cosine"] = evaluate_glsl(source, grid, {"diffuse_clamped_cosine": 1},
                                                            libraries=["lib/vsgl_shading.glsl"])["diffuse_clamped_cosine"]
    for body, source in SEPARABLE_BODIES.items():
        gpu[body]["diffuse_separable"] = evaluate_glsl(source, grid, {"diffuse_separable": 1},
                                                       libraries=["lib/vsgl_shading.glsl"])["diffuse_separable"]
    gpu["fused"].update(evaluate_glsl(SEPARABLE_SPECULAR_BODY, grid, SEPARABLE_SPECULAR_OUTPUTS,
                                      libraries=["lib/vsgl_shading.glsl"]))
    elapsed = time.perf_counter() - start
    reference = lobe_reference(grid)
    return grid, groups, gpu, reference, _conditioning(grid, reference), elapsed


@pytest.mark.parametrize("body", ["lobe", "fused"])
@pytest.mark.parametrize("output", [*LOBE_OUTPUTS, "diffuse_clamped_cosine", "diffuse_separable"])
def test_glsl_lobe_matches_reference(lobe_results, output, body):
    grid, groups, gpu, reference, conditioning, _ = lobe_results
    gpu = gpu[body]
    # vsgl_accumulate's diffuse lobe (the fused body's tested lobe) emits as Lambert's lobes in the
    # separable mode, vsgl_accumulate_lobe as the SG (the specular lobe's emission).
    key = "diffuse_separable_lambert" if (body, output) == ("fused", "diffuse_separable") else output
    well_conditioned = conditioning[key] <= 3e-5
    values, expected = gpu[output], reference[key]
    assert np.all(np.isfinite(values)), "NaN or Inf from the GPU"
    # Below 1e-25 (float32 products of the intermediate terms underflow there) values count as 0;
    # the GPU must then give (almost) 0 too: the absolute criterion checks it.
    if expected.ndim == 1:
        tiny = np.abs(expected) < 1e-25
        expected = np.where(tiny, 0.0, expected)
        values = np.where(tiny & (np.abs(values) < 1e-25), 0.0, values)
    keep = well_conditioned
    # The clamped cosine's smoothing factor s (sg.glsl) sums terms up to ~1e3 times larger than
    # itself below the horizon (½ μ erfc(−tμ) against the Gaussian tail), so float32 erfc's 1.2e-7
    # reaches 1.5e-4 of the light there (2 of 44 000 points); everywhere else 1e-4 holds.
    relative = 2e-4 if output == "diffuse_clamped_cosine" else RELATIVE_TOLERANCE
    accuracy = Accuracy(values[keep], expected[keep], groups[keep], relative=relative)
    print(f"\n{output}: {accuracy.summary()}; {int((~keep).sum())} of {len(keep)} points excluded as "
          f"ill-conditioned (1 ulp of input moves the reference by > 3e-5)")
    assert accuracy.ok, accuracy.report({name: value[keep] for name, value in grid.items()})


@pytest.mark.parametrize("output", SEPARABLE_SPECULAR_OUTPUTS)
def test_glsl_separable_specular_matches_reference(lobe_results, output):
    """vsgl_accumulate's specular in the separable mode (a flat diffuse lobe's Lambertian emission at
    vsgl_specular_emission_direction) against the reference over the lobe grid, as the other outputs,
    where the tested lobe is a diffuse lobe's (λv ≤ 2.1: Toksvig of texels' λd = 2 lobes, rounded).
    Sharper lobes in the diffuse slot only have to stay finite: there Lambert's lobe over the SG is
    e^(λv (1 − μ)) of a float32 cosine μ near 1, ill-conditioned (1e-7 of μ is 10 % at λv = 1e6)."""
    grid, groups, gpu, reference, conditioning, _ = lobe_results
    values, expected = gpu["fused"][output], reference[output]
    assert np.all(np.isfinite(values)), "NaN or Inf from the GPU"
    tiny = np.abs(expected) < 1e-25
    expected = np.where(tiny, 0.0, expected)
    values = np.where(tiny & (np.abs(values) < 1e-25), 0.0, values)
    keep = (conditioning[output] <= 3e-5) & (grid["lobe_sharpness"] <= 2.1)
    accuracy = Accuracy(values[keep], expected[keep], groups[keep], relative=RELATIVE_TOLERANCE)
    print(f"\n{output}: {accuracy.summary()}; {int((~keep).sum())} of {len(keep)} points excluded as "
          f"ill-conditioned (1 ulp of input moves the reference by > 3e-5)")
    assert accuracy.ok, accuracy.report({name: value[keep] for name, value in grid.items()})


def test_diffuse_emission_ratio_matches_reference():
    """vsgl_diffuse_emission_ratio against its twin across the SG → Lambert blend and out-of-range
    sharpnesses (λv 0 … 2.1, 1e-6, 10, 1e6), every cosine including below the horizon; finite, ≥ 0."""
    lam = np.concatenate([np.linspace(0.0, 2.1, 211), [1e-6, 10.0, 1e6]])
    mu = np.linspace(-1.0, 1.0, 41)
    grid_lam, grid_mu = (a.ravel() for a in np.meshgrid(lam, mu, indexing="ij"))
    axis = np.tile([0.0, 0.0, 1.0], (len(grid_mu), 1))
    direction = np.stack([np.sqrt(np.maximum(1.0 - grid_mu ** 2, 0.0)), np.zeros_like(grid_mu), grid_mu], -1)
    inputs = {"direction": _f32(direction), "axis": _f32(axis), "lam": _f32(grid_lam)}
    out = evaluate_glsl("ratio = vsgl_diffuse_emission_ratio(direction, axis, lam);", inputs, {"ratio": 1},
                        libraries=["lib/vsgl_shading.glsl"])["ratio"]
    expected = vs.vsgl_diffuse_emission_ratio(inputs["direction"][:, 2], inputs["lam"])
    assert np.all(np.isfinite(out)) and np.all(out >= 0.0)
    # As vsgl_diffuse_emission's: where the smoothstep's weight is within 1e-2 of 1, 1 - w carries its
    # rounding amplified by 1/(1 - w).
    low, high = vs.FLAT_CLUSTER
    t = np.clip((vs.mean_normal_length(inputs["lam"]) - low) / (high - low), 0.0, 1.0)
    tail = (t * t * (3.0 - 2.0 * t) > 0.99) & (t < 1.0)
    for part, relative in ((~tail, 1e-4), (tail, 1e-3)):
        accuracy = Accuracy(out[part], expected[part], inputs["lam"][part], relative=relative)
        assert accuracy.ok, accuracy.report({k: v[part] for k, v in inputs.items()})


def test_diffuse_emission_matches_reference():
    """vsgl_diffuse_emission against its twin across the SG → Lambert blend (λv 0 … 2.1, the blend at
    1.73 … 1.94, and 1e6), every cosine including below the horizon; finite, ≥ 0."""
    lam = np.concatenate([np.linspace(0.0, 2.1, 211), [1e-6, 1e6]])
    mu = np.linspace(-1.0, 1.0, 41)
    grid_lam, grid_mu = (a.ravel() for a in np.meshgrid(lam, mu, indexing="ij"))
    axis = np.tile([0.0, 0.0, 1.0], (len(grid_mu), 1))
    direction = np.stack([np.sqrt(np.maximum(1.0 - grid_mu ** 2, 0.0)), np.zeros_like(grid_mu), grid_mu], -1)
    inputs = {"direction": _f32(direction), "axis": _f32(axis), "lam": _f32(grid_lam)}
    out = evaluate_glsl("emission = vsgl_diffuse_emission(direction, axis, lam);", inputs, {"emission": 1},
                        libraries=["lib/vsgl_shading.glsl"])["emission"]
    expected = vs.vsgl_diffuse_emission(inputs["direction"][:, 2], inputs["lam"])
    assert np.all(np.isfinite(out)) and np.all(out >= 0.0)
    # Where the smoothstep's weight w is within 1e-2 of 1, the SG's share (1 - w) carries w's float32
    # rounding amplified by 1/(1 - w) (3.1e-4 measured below the horizon, where that share is all the
    # light): 1e-3 there, 1e-4 elsewhere.
    low, high = vs.FLAT_CLUSTER
    t = np.clip((vs.mean_normal_length(inputs["lam"]) - low) / (high - low), 0.0, 1.0)
    tail = (t * t * (3.0 - 2.0 * t) > 0.99) & (t < 1.0)
    for part, relative in ((~tail, 1e-4), (tail, 1e-3)):
        accuracy = Accuracy(out[part], expected[part], inputs["lam"][part], relative=relative)
        assert accuracy.ok, accuracy.report({k: v[part] for k, v in inputs.items()})


# --- The shading pass --------------------------------------------------------------------------

from test_reference_vsgl_shading import floor_vpls  # noqa: E402
from vsgl_addon.passes import vsgl_shading as shading_pass  # noqa: E402
from vsgl_addon.passes.vsgl_generation import VSGLGeneration  # noqa: E402
from vsgl_addon.reference.vsgl import generate_vsgls  # noqa: E402

CAMERA = np.array([-1.5, 0.3, 0.4])


def extreme_gbuffer(height=16, width=16, seed=5):
    """A wall (x = 0.9) and a ceiling (z = 0.9) around the floor's VSGLs, with extreme pixels:
    background (coverage 0), grazing views, normals facing away from the camera, roughness 1e-3
    and 1, tilted normals, a pixel at a VSGL's mean (set by the caller), and white/black materials."""
    rng = np.random.default_rng(seed)
    v, u = np.meshgrid(np.linspace(0.05, 0.95, height), np.linspace(-0.45, 0.45, width), indexing="ij")
    position = np.zeros((height, width, 3))
    normal = np.zeros((height, width, 3))
    wall = np.arange(width)[None, :] < width // 2
    wall = np.broadcast_to(wall, (height, width))
    position[..., 0] = np.where(wall, 0.9, u)
    position[..., 1] = np.where(wall, u, v - 0.5)
    position[..., 2] = np.where(wall, v, 0.9)
    normal[..., 0] = np.where(wall, -1.0, 0.0)
    normal[..., 2] = np.where(wall, 0.0, -1.0)
    tilt = rng.normal(scale=0.2, size=(height, width, 3))
    normal = np.where((rng.random((height, width)) < 0.5)[..., None], normal + tilt, normal)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    roughness = rng.choice([1e-3, 1e-2, 0.1, 0.3, 0.6, 1.0], (height, width))
    # Grazing views in row 1: view.normal = +-1e-2, 1e-3, 1e-4 (not 0: the GGX lobe jumps there from
    # its finite grazing limit to 0, and the float32 view decides which side a cosine of 1e-17 is).
    view = CAMERA - position[1]
    view /= np.linalg.norm(view, axis=-1, keepdims=True)
    side = np.cross(view, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side, axis=-1, keepdims=True)
    cosines = np.resize([1e-2, 1e-3, 1e-4, -1e-4, -1e-3], width)[:, None]
    normal[1] = np.sqrt(1.0 - cosines**2) * side + cosines * view
    normal[2, :4] = -normal[2, :4]  # facing away from the camera
    coverage = np.ones((height, width))
    coverage[0, :3] = 0.0
    position[0, :3] = np.nan * 0.0  # background holds anything (zeros here)
    rd = rng.uniform(0, 1, (height, width, 3))
    rd[3, 0] = 0.0
    f0 = rng.uniform(0.02, 1.0, (height, width, 3))
    f0[3, 1] = 1.0
    return {"position": position, "coverage": coverage, "normal": normal, "roughness": roughness,
            "diffuse_reflectance": rd, "specular_f0": f0}


def _f32(array):
    return np.asarray(array, dtype=np.float32).astype(np.float64)


def reference_image(gbuffer, vsgl_tables, camera=CAMERA, diffuse_mode=vs.DEFAULT_DIFFUSE_MODE):
    g = {name: _f32(value) for name, value in gbuffer.items()}
    height, width = g["coverage"].shape
    normal = g["normal"] / np.linalg.norm(g["normal"], axis=-1, keepdims=True)
    view = _f32(camera) - g["position"]
    view /= np.maximum(np.linalg.norm(view, axis=-1, keepdims=True), 1e-300)
    diffuse = np.zeros((height * width, 3))
    specular = np.zeros((height * width, 3))
    for table in vsgl_tables:
        table = {name: _f32(table[name]) for name in vs.VSGL_KEYS}
        d, s = vs.shade(table, g["position"].reshape(-1, 3), normal.reshape(-1, 3), view.reshape(-1, 3),
                        g["diffuse_reflectance"].reshape(-1, 3), g["specular_f0"].reshape(-1, 3),
                        g["roughness"].reshape(-1), diffuse_mode=diffuse_mode)
        diffuse += d
        specular += s
    covered = (g["coverage"] > 0).reshape(-1, 1)
    return (np.where(covered, diffuse, 0.0).reshape(height, width, 3),
            np.where(covered, specular, 0.0).reshape(height, width, 3))


def upload(gbuffer):
    return shading_pass.upload_gbuffer(**gbuffer)


def assert_image_matches(gpu, reference, relative=2e-4, label="", per_pixel=False):
    """Per pixel and channel: |gpu - ref| <= relative * |ref| + 1e-6 * M (float32 sums of up to 2N
    terms), M = max |ref| of the image, or of the pixel's channels with ``per_pixel`` (for images
    spanning many orders of magnitude); everything finite."""
    values = gpu[..., :3].astype(np.float64)
    assert np.all(np.isfinite(gpu)), f"{label}: NaN or Inf"
    error = np.abs(values - reference)
    scale = np.abs(reference).max(axis=-1, keepdims=True) if per_pixel else np.abs(reference).max()
    floor = 1e-6 * scale + 1e-30
    bound = relative * np.abs(reference) + floor
    worst = np.max(error / np.maximum(np.abs(reference), floor))
    print(f"\n{label}: worst relative error {worst:.3g} (max {np.abs(reference).max():.4g})")
    assert np.all(error <= bound), f"{label}: {int((error > bound).sum())} values off, worst {worst:.3g}"


@pytest.fixture(scope="module")
def floor_rsm():
    return floor_vpls(64).rsm()


@pytest.mark.parametrize("diffuse_mode", [vs.diffuse_mode_for_kernel("modified"), "cosine"])
@pytest.mark.parametrize("count", [1, 4096])
def test_pass_matches_reference(gpu_context, floor_rsm, count, diffuse_mode):
    size = 16 if count == 1 else 8
    vsgls = generate_vsgls(floor_rsm, count)
    gbuffer = extreme_gbuffer(size, size)
    gbuffer["position"][3, 2] = vsgls["diffuse_mean"][0]  # pixels at a VSGL lobe's mean
    gbuffer["position"][4, 2] = vsgls["specular_mean"][0]
    gpu_d, gpu_s = shading_pass.shade_gpu(upload(gbuffer), CAMERA, vsgls, diffuse_mode)
    ref_d, ref_s = reference_image(gbuffer, [vsgls], diffuse_mode=diffuse_mode)
    assert_image_matches(gpu_d, ref_d, label=f"diffuse N={count} {diffuse_mode}")
    assert_image_matches(gpu_s, ref_s, label=f"specular N={count} {diffuse_mode}")
    background = gbuffer["coverage"] == 0
    assert np.all(gpu_d[background] == 0.0) and np.all(gpu_s[background] == 0.0)
    np.testing.assert_array_equal(gpu_d[..., 3], gbuffer["coverage"])


def extreme_vsgls():
    """VSGLs at the extremes: σv² at the floor and large, λ 0 … 1e6, a VSGL facing away, zero
    power, one at a pixel's position (row 0)."""
    rows = [
        # mean, variance, d_amp, d_axis, d_sharp, s_amp, s_axis, s_sharp
        ([0.9, 0.0, 0.5], 1e-12, [1, 1, 1], [1, 0, 0], 2.0, [5, 5, 5], [1, 0, 0], 1e6),
        ([0.0, 0.0, 0.0], 1e-12, [0.3, 0.2, 0.1], [0, 0, 1], 2.0, [2, 2, 2], [0.6, 0, 0.8], 1e6),
        ([0.2, 0.1, 0.0], 0.05, [0.3, 0.2, 0.1], [0, 0, 1], 1e-6, [2, 2, 2], [0.6, 0, 0.8], 1e3),
        ([0.0, -0.2, 0.0], 100.0, [0.3, 0.2, 0.1], [0, 0, 1], 0.0, [2, 2, 2], [0, 0.6, 0.8], 0.0),
        ([0.0, 0.3, 0.0], 1e-4, [0.3, 0.2, 0.1], [0, 0, -1], 2.0, [2, 2, 2], [0, 0, -1], 1e5),
        ([0.1, 0.1, 0.0], 1e-4, [0, 0, 0], [0, 0, 1], 0.0, [0, 0, 0], [0, 0, 1], 0.0),
    ]
    keys = ("mean", "variance", "diffuse_amplitude", "diffuse_axis", "diffuse_sharpness",
            "specular_amplitude", "specular_axis", "specular_sharpness")
    out = {key: np.array([row[i] for row in rows], dtype=np.float64) for i, key in enumerate(keys)}
    for key in ("diffuse_axis", "specular_axis"):
        out[key] = _unit(out[key])
    # Each lobe at its own position (per-lobe distribution): the specular lobes shifted by one row.
    out["diffuse_mean"], out["diffuse_variance"] = out["mean"], out["variance"]
    out["specular_mean"], out["specular_variance"] = np.roll(out["mean"], 1, 0), np.roll(out["variance"], 1)
    return out


@pytest.mark.parametrize("diffuse_mode", vs.DIFFUSE_MODES)
def test_pass_with_extreme_vsgls_and_several_tables(gpu_context, floor_rsm, diffuse_mode):
    """Two tables (blended) = the sum of both; extreme VSGLs; every diffuse mode; finite."""
    extreme = extreme_vsgls()
    two = generate_vsgls(floor_rsm, 2, kernel="two-vsgl")
    gbuffer = extreme_gbuffer(12, 12)
    gbuffer["position"][5, 1] = extreme["mean"][0]
    gbuffer["position"][6, 1] = extreme["specular_mean"][0]
    gpu_d, gpu_s = shading_pass.shade_gpu(upload(gbuffer), CAMERA, [extreme, two], diffuse_mode)
    ref_d, ref_s = reference_image(gbuffer, [extreme, two], diffuse_mode=diffuse_mode)
    # The image spans 1e-9 ... 1e11 (a pixel at a VSGL of variance 1e-12): judged per pixel.
    assert_image_matches(gpu_d, ref_d, label=f"diffuse extreme {diffuse_mode}", per_pixel=True)
    assert_image_matches(gpu_s, ref_s, label=f"specular extreme {diffuse_mode}", per_pixel=True)
    np.testing.assert_array_equal(gpu_d[..., 3], gbuffer["coverage"])


def test_separable_pass_on_the_reflectors_own_plane(gpu_context, floor_rsm):
    """Receivers on the lit floor's own plane (z = 0, normal +z: ⟨ξµ, n⟩ = 0) get no diffuse light
    from its VSGLs in the separable mode, on the GPU as in the reference, while the wall and ceiling
    of the extreme G-buffer match it per pixel; grazing and at-the-mean pixels included, finite."""
    vsgls = generate_vsgls(floor_rsm, 256)
    gbuffer = extreme_gbuffer(8, 8)
    u = np.linspace(-0.45, 0.45, 8)
    gbuffer["position"][5:] = np.stack([u[None, :] * np.ones((3, 1)), np.linspace(-0.4, 0.4, 3)[:, None]
                                        * np.ones((1, 8)), np.zeros((3, 8))], -1)
    gbuffer["normal"][5:] = [0.0, 0.0, 1.0]
    gbuffer["position"][4, 2] = vsgls["diffuse_mean"][0]
    gpu_d, gpu_s = shading_pass.shade_gpu(upload(gbuffer), CAMERA, vsgls, "separable")
    ref_d, ref_s = reference_image(gbuffer, [vsgls], diffuse_mode="separable")
    assert np.all(ref_d[5:] == 0.0) and np.all(gpu_d[5:, :, :3] == 0.0)
    assert ref_d[:5].max() > 0.0
    assert_image_matches(gpu_d, ref_d, label="diffuse separable, own plane")
    assert_image_matches(gpu_s, ref_s, label="specular separable, own plane")


def test_shared_positions_are_computed_once_with_the_same_result(gpu_context, floor_rsm):
    """A table whose lobes share their position (the paper's distribution) is shaded with the
    position terms computed once per VSGL: the same image as computing them per lobe."""
    shared = shading_pass.upload_vsgl_table(generate_vsgls(floor_rsm, 64, positional_distribution="shared"))
    per_lobe = shading_pass.upload_vsgl_table(generate_vsgls(floor_rsm, 64))
    assert shared.shared_positions and not per_lobe.shared_positions
    gbuffer = upload(extreme_gbuffer(8, 8))
    once = shading_pass.shade_gpu(gbuffer, CAMERA, shared)
    twice = shading_pass.shade_gpu(gbuffer, CAMERA, shading_pass.VSGLTable(shared.texture, shared.count, False))
    for a, b in zip(once, twice):
        assert np.all(np.isfinite(a))
        np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-30)
    generation = VSGLGeneration()
    try:
        generation.run(floor_rsm, 16, positional_distribution="shared")
        assert shading_pass.VSGLTable.from_generation(generation).shared_positions
        generation.run(floor_rsm, 16)
        assert not shading_pass.VSGLTable.from_generation(generation).shared_positions
    finally:
        generation.free()


def test_pass_reads_the_generation_table_on_the_gpu(gpu_context, floor_rsm):
    generation = VSGLGeneration()
    shading = shading_pass.VSGLShading()
    try:
        generation.run(floor_rsm, 256, rotation=(0.3, 0.7))
        table = shading_pass.VSGLTable.from_generation(generation)
        gbuffer = extreme_gbuffer(8, 8)
        shading.run(upload(gbuffer), np.append(CAMERA, 1.0), table)
        gpu_d, gpu_s = shading.read()
        vsgls = generation.read_table()
        ref_d, ref_s = reference_image(gbuffer, [vsgls])
        assert_image_matches(gpu_d, ref_d, label="diffuse from generation")
        assert_image_matches(gpu_s, ref_s, label="specular from generation")
        # The G-buffer pass's convention: perceptual roughness in normal.a (alpha = r^2).
        perceptual = dict(gbuffer, roughness=np.sqrt(gbuffer["roughness"]))
        shading.run(shading_pass.upload_gbuffer(**perceptual, roughness_is_perceptual=True), CAMERA, table)
        perceptual_d, perceptual_s = shading.read()
        squared = dict(gbuffer, roughness=_f32(perceptual["roughness"]) ** 2)
        ref_d, ref_s = reference_image(squared, [vsgls])
        assert_image_matches(perceptual_s, ref_s, label="specular, perceptual roughness")
        # No tables: zero radiance, coverage kept.
        shading.run(upload(gbuffer), CAMERA, [])
        empty_d, empty_s = shading.read()
        assert np.all(empty_d[..., :3] == 0) and np.all(empty_s[..., :3] == 0)
        np.testing.assert_array_equal(empty_d[..., 3], gbuffer["coverage"])
    finally:
        generation.free()
        shading.free()


def test_entries_without_a_mode_shade_as_the_renderer(gpu_context, floor_rsm):
    """The pass's entries default to the renderer's diffuse mode for the default kernel (the
    reference's default), not Eq. 12's "cosine"."""
    import inspect

    for entry in (shading_pass.run, shading_pass.shade_gpu, shading_pass.shader, shading_pass.VSGLShading.run):
        assert inspect.signature(entry).parameters["diffuse_mode"].default == vs.DEFAULT_DIFFUSE_MODE
    vsgls = generate_vsgls(floor_rsm, 16)
    gbuffer = upload(extreme_gbuffer(8, 8))
    default_d, _ = shading_pass.shade_gpu(gbuffer, CAMERA, vsgls)
    named_d, _ = shading_pass.shade_gpu(gbuffer, CAMERA, vsgls, vs.DEFAULT_DIFFUSE_MODE)
    cosine_d, _ = shading_pass.shade_gpu(gbuffer, CAMERA, vsgls, "cosine")
    np.testing.assert_array_equal(default_d, named_d)
    rgb = np.s_[..., :3]  # alpha is coverage in every mode
    assert np.abs(default_d[rgb] - cosine_d[rgb]).max() > 1e-2 * cosine_d[rgb].max()


def test_orthographic_camera(gpu_context, floor_rsm):
    vsgls = generate_vsgls(floor_rsm, 16)
    gbuffer = extreme_gbuffer(8, 8)
    direction = _unit(np.array([-1.0, 0.2, 0.3]))
    gpu_d, gpu_s = shading_pass.shade_gpu(upload(gbuffer), np.append(direction, 0.0), vsgls)
    g = {name: _f32(value) for name, value in gbuffer.items()}
    normal = g["normal"] / np.linalg.norm(g["normal"], axis=-1, keepdims=True)
    view = np.broadcast_to(_f32(direction), normal.shape)
    table = {name: _f32(vsgls[name]) for name in vs.VSGL_KEYS}
    d, s = vs.shade(table, g["position"].reshape(-1, 3), normal.reshape(-1, 3), view.reshape(-1, 3),
                    g["diffuse_reflectance"].reshape(-1, 3), g["specular_f0"].reshape(-1, 3), g["roughness"].reshape(-1))
    covered = (g["coverage"] > 0)[..., None]
    assert_image_matches(gpu_s, np.where(covered, s.reshape(8, 8, 3), 0.0), label="specular ortho")
    assert_image_matches(gpu_d, np.where(covered, d.reshape(8, 8, 3), 0.0), label="diffuse ortho")
