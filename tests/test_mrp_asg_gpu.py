# SPDX-License-Identifier: GPL-3.0-or-later
"""MRP-ASG on the GPU (llvmpipe): every function of glsl/lib/mrp_asg.glsl against its float64 twin
in vsgl_addon/reference/mrp_asg.py, at the extremes (roughness 1e-3 … 1, disk radius 0 … 1e6,
σ → 90°, peaks on and outside the rectangle's edge, receivers in and behind its plane, grazing
views, point / spot / area / sun lights). Inputs are rounded to float32 and the reference runs on
those values. Criterion: glsl_harness.Accuracy (relative 1e-4 where the reference is above 1e-6 of
its slice's maximum; the whole shade 2e-3, see ``test_mrp_shade``), no NaN/Inf."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from glsl_harness import Accuracy, as_gpu_floats, evaluate_glsl
from vsgl_addon.reference import lights as ref_lights, mrp_asg as mrp

pytestmark = pytest.mark.gpu

LIB = ["lib/mrp_asg.glsl"]


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def gpu_unit(v):
    """Unit vectors as the GPU receives them (float32), renormalized in float64 for the reference."""
    return as_gpu_floats(unit(v))


def check(gpu, ref, groups=None, relative=1e-4, label="", inputs=None):
    accuracy = Accuracy(gpu, ref, groups, relative=relative)
    assert accuracy.ok, f"{label}: {accuracy.report(inputs)}"


def test_peaks():
    rng = np.random.default_rng(2)
    n = 4000
    normal = gpu_unit(rng.normal(size=(n, 3)) * 0.2 + [0, 0, 1])
    center = as_gpu_floats(rng.uniform(-1, 1, (n, 3)))
    position = as_gpu_floats(center + rng.uniform(-2, 2, (n, 3)))
    light = as_gpu_floats(center + rng.uniform(-2, 2, (n, 3)))
    incoming = gpu_unit(rng.normal(size=(n, 3)))
    out = evaluate_glsl(
        "vec3 p; bool ok = mrp_peak_local(position, center, normal, light, p);"
        "local = vec4(p, ok ? 1.0 : 0.0);"
        "ok = mrp_peak_distant(position, center, normal, incoming, p); distant = vec4(p, ok ? 1.0 : 0.0);",
        dict(position=position, center=center, normal=normal, light=light, incoming=incoming),
        {"local": 4, "distant": 4}, libraries=LIB)
    for name, (peak, valid) in (("local", mrp.mrp_peak_local(position, center, normal, light)),
                                ("distant", mrp.mrp_peak_distant(position, center, normal, incoming))):
        got = out[name]
        # Validity may differ only where a height is within float32 rounding of 0.
        agree = (got[:, 3] > 0.5) == valid
        assert agree.mean() > 0.999, name
        # The peak's error grows as the heights' sum (local) or i.n_r (distant) vanish: compare
        # where they are not tiny.
        h_x = np.einsum("ij,ij->i", position - center, normal)
        denom = (np.einsum("ij,ij->i", light - center, normal) + h_x if name == "local"
                 else np.einsum("ij,ij->i", incoming, normal))
        good = agree & valid & (np.abs(denom) > 1e-2)
        scale = np.linalg.norm(peak - position, axis=1) + 1.0
        assert np.all(np.linalg.norm(got[good, :3] - peak[good], axis=1) / scale[good] < 1e-4), name
        assert np.isfinite(got).all()


def test_scalar_functions():
    cos_sigma = np.array([1.0, 0.9, 0.5, 0.1, 1e-2, 1e-4, 1e-6, 0.0])
    roughness = np.array([1e-3, 1e-2, 0.05, 0.1, 0.3, 0.6, 1.0])
    extent = np.array([0.0, 1e-6, 1e-4, 1e-2, 0.1, 0.5, 1.0, 3.0, 20.0, 1e3, 1e6, 1e9])
    spread = np.array([1.0, 1.5, 3.0, 100.0])
    c, a, e, s = (as_gpu_floats(x.ravel()) for x in np.meshgrid(cos_sigma, roughness, extent, spread,
                                                                 indexing="ij"))
    out = evaluate_glsl(
        "disk = mrp_disk_integral(c, a, e, s); band = mrp_bandwidth(e); brdf = mrp_peak_brdf(c, a, 0.9);"
        "ratio = mrp_exp_ratio(e * (s - 2.0)); lobe = mrp_lobe_extent(c, a, s);",
        dict(c=c, a=a, e=e, s=s), {"disk": 1, "band": 1, "brdf": 1, "ratio": 1, "lobe": 1}, libraries=LIB)
    groups = np.stack((c, a), axis=1)
    check(out["disk"], mrp.mrp_disk_integral(c, a, e, s), groups, label="disk")
    check(out["lobe"], mrp.mrp_lobe_extent(c, a, s), groups, label="lobe extent")
    check(out["band"], mrp.mrp_bandwidth(e), label="bandwidth", groups=e)
    check(out["brdf"], mrp.mrp_peak_brdf(c, a, 0.9), groups, label="peak brdf")
    x = e * (s - 2.0)
    finite = np.abs(x) < 80.0
    check(out["ratio"][finite], mrp.mrp_exp_ratio(as_gpu_floats(x[finite])), label="exp ratio")


def test_area_ratio():
    rng = np.random.default_rng(4)
    n = 6000
    center = as_gpu_floats(rng.uniform(-1, 1, (n, 3)))
    axis_u = gpu_unit(rng.normal(size=(n, 3)))
    axis_v = gpu_unit(np.cross(axis_u, rng.normal(size=(n, 3))))
    half = as_gpu_floats(rng.choice([0.0, 1e-3, 0.5, 2.0], (n, 2)))
    radius = as_gpu_floats(rng.choice([0.0, 1e-4, 0.1, 1.0, 1e3], n))
    # Peaks inside, on the edge (x0 = a exactly: the half disk) and outside.
    k = rng.choice([0.0, 0.3, 1.0, 1.2, 5.0], (n, 2)) * rng.choice([-1.0, 1.0], (n, 2))
    peak = as_gpu_floats(center + k[:, :1] * half[:, :1] * axis_u + k[:, 1:] * half[:, 1:] * axis_v)
    got = evaluate_glsl("mrp_area_ratio(peak, center, axis_u, axis_v, half_.x, half_.y, radius)",
                        dict(peak=peak, center=center, axis_u=axis_u, axis_v=axis_v, half_=half, radius=radius),
                        libraries=LIB)
    ref = mrp.mrp_area_ratio(peak, center, axis_u, axis_v, half[:, 0], half[:, 1], radius)
    assert np.isfinite(got).all() and (got >= 0).all()
    # Where a peak sits on R's edge the ratio moves with the peak's float32 rounding (~1e-7 of the
    # coordinates) over the disk radius: the bound is that conditioning.
    coordinate = np.abs(peak).max(axis=1) + np.abs(center).max(axis=1) + 1.0
    bound = 1e-5 + 4.0 * 6e-8 * coordinate / np.maximum(radius, 1e-30)
    assert np.all(np.abs(got - ref) <= bound)


def test_frame_receiver_and_convolution():
    rng = np.random.default_rng(6)
    n = 5000
    normal = gpu_unit(rng.normal(size=(n, 3)) * 0.3 + [0, 0, 1])
    position = as_gpu_floats(rng.normal(size=(n, 3)) + [0, 0, 2])
    peak = as_gpu_floats(rng.normal(size=(n, 3)) * [1, 1, 0])
    position[:50] = peak[:50] + normal[:50] * 1e-3 * np.arange(50)[:, None]  # normal incidence, d → 0
    position[:50] = as_gpu_floats(position[:50])
    out = evaluate_glsl(
        "vec3 m, n, z; float d, c; mrp_asg_frame(position, peak, normal, m, n, z, d, c);"
        "fm = vec4(m, d); fn = vec4(n, c); fz = z;",
        dict(position=position, peak=peak, normal=normal), {"fm": 4, "fn": 4, "fz": 3}, libraries=LIB)
    m, nn, z, d, c = mrp.mrp_asg_frame(position, peak, normal)
    check(out["fm"][:, 3], d, label="distance")
    assert np.all(np.abs(out["fn"][:, 3] - c) < 1e-5)
    assert np.all(np.linalg.norm(out["fz"] - z, axis=1) < 1e-5)
    oblique = np.linalg.norm(np.cross(z, normal), axis=1) > 1e-3
    assert np.all(np.linalg.norm(out["fm"][oblique, :3] - m[oblique], axis=1) < 1e-4)
    assert np.all(np.abs(np.linalg.norm(out["fm"][:, :3], axis=1) - 1.0) < 1e-5)
    # Receiver SG, receiver factor and the convolution (both modes) on the reference's frame.
    view = gpu_unit(rng.normal(size=(n, 3)))
    view[:100] = gpu_unit(np.cross(normal[:100], [0.3, 0.1, 1.0]))  # grazing
    roughness = as_gpu_floats(rng.choice([1e-3, 1e-2, 0.1, 0.5, 1.0], n))
    bands = as_gpu_floats(rng.choice([1e-3, 1.0, 50.0, 1e3, 3e8], (n, 2)))
    z = gpu_unit(z)
    m = gpu_unit(m)
    nn = gpu_unit(np.cross(-z, m))
    inputs = dict(view=view, normal=normal, roughness=roughness, m=m, n_=nn, z=z, bands=bands)
    out = evaluate_glsl(
        "asg = mrp_convolve(view, normal, roughness, m, n_, z, bands.x, bands.y, 1.0, MRP_MODE_ASG);"
        "sg = mrp_convolve(view, normal, roughness, m, n_, z, bands.x, bands.y, 1.0, MRP_MODE_SG);"
        "factor = mrp_receiver_factor(z, view, normal, roughness, 0.04);",
        inputs, {"asg": 1, "sg": 1, "factor": 1}, libraries=LIB)
    # The ASG's clamped cosine <p, z> at the receiver lobe's axis p is a float32 dot product with an
    # absolute error of ~1e-7: points within 1e-3 of its horizon are ill-conditioned (compared in
    # absolute terms by the criterion's slice maximum instead).
    axis, _, _ = mrp.mrp_receiver_sg(view, normal, roughness)
    conditioned = np.abs(np.einsum("ij,ij->i", axis, z)) > 1e-3
    for mode in mrp.MODES:
        ref = mrp.mrp_convolve(view, normal, roughness, m, nn, z, bands[:, 0], bands[:, 1], 1.0, mode)
        assert np.isfinite(out[mode]).all()
        check(out[mode][conditioned], ref[conditioned], roughness[conditioned], relative=1e-3, label=mode,
              inputs={k: v[conditioned] for k, v in inputs.items()})
    check(out["factor"], mrp.mrp_receiver_factor(z, view, normal, roughness, 0.04), roughness, label="factor")


def _light(kind):
    direction = unit([0.4, 0.1, -1.0])
    m = np.eye(4)
    z = -direction
    x = unit(np.cross([0.0, 1.0, 0.0], z))
    m[:3, :3] = np.stack((x, np.cross(z, x), z), axis=1)
    m[:3, 3] = (-1.0, 0.2, 1.5)
    import types
    return types.SimpleNamespace(type=kind, position=m[:3, 3].copy(), direction=direction, power=800.0,
                                 matrix_world=m, spot_size=math.radians(100.0), spot_blend=0.3)


@pytest.mark.parametrize("kind", ["POINT", "SPOT", "AREA", "SUN"])
def test_mrp_shade(kind):
    """The whole of one rectangle and one light against reference.mrp_shade (per channel of both
    F0s), over receivers in front of, in and behind the plane, views towards the peak and grazing,
    roughness 1e-3 … 1 at both ends and disk radii 0 … 1e6."""
    rng = np.random.default_rng(8)
    light = _light(kind)
    count = 3000
    rects = [dict(center=np.zeros(3), normal=np.array([0, 0, 1.0]), axis_u=np.array([1.0, 0, 0]),
                  axis_v=np.array([0, 1.0, 0]), half_u=2.0, half_v=1.0, roughness=a, f0=0.0)
             for a in (1e-3, 0.05, 0.3, 1.0)]
    position = rng.uniform([-3, -2, -0.5], [3, 2, 2.5], (count, 3))
    position[:100, 2] = 0.0
    normal = unit(rng.normal(size=(count, 3)) * 0.5 + [0, 0, -1])
    view = unit(rng.normal(size=(count, 3)))
    # Grazing views at cosines ±1e-2, ±1e-4 (not 0, whose sign float32 rounding decides).
    tangent = unit(np.cross(normal[100:300], [0.2, 0.3, 1.0]))
    cosines = np.resize([1e-2, -1e-2, 1e-4, -1e-4], 200)[:, None]
    view[100:300] = cosines * normal[100:300] + np.sqrt(1 - cosines ** 2) * tangent
    # Views mirroring the direction to the peak (where the receiver sees the reflection).
    peak, valid = (mrp.mrp_peak_distant(position, np.zeros(3), [0, 0, 1.0], -light.direction) if kind == "SUN"
                   else mrp.mrp_peak_local(position, np.zeros(3), [0, 0, 1.0], light.position))
    w = unit(peak - position + 1e-9)
    mirror = 2 * np.einsum("ij,ij->i", w, normal)[:, None] * normal - w
    view[300:2000] = unit(mirror[300:2000] + rng.normal(size=(1700, 3)) * 0.05)
    position, normal, view = as_gpu_floats(position), gpu_unit(normal), gpu_unit(view)
    # Horizon tests (the view's and the peak direction's cosines at the receiver, the receiver's height
    # above the plane) decide on float32 rounding within ~1e-6 of 0: criterion away from them.
    z_dir = unit(peak - position + 1e-12)
    conditioned = ((np.abs(np.einsum("ij,ij->i", view, normal)) > 1e-3)
                   & (np.abs(np.einsum("ij,ij->i", z_dir, normal)) > 1e-3) & (np.abs(position[:, 2]) > 1e-3))
    params = np.array(ref_lights.light_params(light))
    to_local = np.linalg.inv(light.matrix_world[:3, :3])
    f0 = np.array([0.04, 0.5, 1.0])
    rect_f0 = np.array([0.9, 0.6, 0.2])
    for rect, roughness, radius, mode in itertools.product(rects, (1e-3, 0.2, 1.0), (0.0, 0.05, 0.5, 1e6),
                                                            mrp.MODES):
        if radius == 1e6 and roughness != 0.2:
            continue
        inputs = dict(position=position, normal=normal, view=view)
        declarations = (
            f"const vec4 L_PARAMS = vec4({', '.join(f'{v:.9g}' for v in params)});\n"
            f"const mat3 L_TO_LOCAL = transpose(mat3({', '.join(f'{v:.9g}' for v in to_local.ravel())}));\n")
        body = (
            f"vec3 rad, pk; mrp_shade(position, normal, view, {roughness:.9g}, vec3(0.04, 0.5, 1.0),"
            f" vec3(0.0), vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0), 2.0, 1.0,"
            f" {rect['roughness']:.9g}, vec3(0.9, 0.6, 0.2),"
            f" vec3({', '.join(f'{v:.9g}' for v in light.position)}),"
            f" vec3({', '.join(f'{v:.9g}' for v in light.direction)}), L_PARAMS, L_TO_LOCAL,"
            f" {radius:.9g}, {mrp.MODES.index(mode)}, rad, pk); result = rad;")
        got = evaluate_glsl(body, inputs, 3, libraries=LIB, declarations=declarations)
        gpu_light = _light(kind)
        gpu_light.position = as_gpu_floats(light.position)
        gpu_light.direction = as_gpu_floats(light.direction)
        ref = np.stack([mrp.mrp_shade(position, normal, view, roughness, f0[ch], {**rect, "f0": rect_f0[ch]},
                                      gpu_light, radius, mode) for ch in range(3)], axis=1)
        label = f"{kind} α_r={rect['roughness']} α={roughness} r_d={radius} {mode}"
        assert np.isfinite(got).all() and (got >= 0).all(), label
        check(got[conditioned], ref[conditioned], relative=2e-3, label=label)
        # Where a horizon test flips on float32 rounding (χ+ of a grazing view at α = 1e-3 jumps from 0 to
        # 1/(c + α)), the value still stays a small part of the image's largest.
        error = np.abs(got - ref).max(axis=1)
        worst = int(np.argmax(error))
        assert error[worst] <= 1e-2 * max(ref.max(), 1e-30) + 1e-7, (
            label, worst, got[worst], ref[worst], position[worst], normal[worst], view[worst])


# --- The pass ---------------------------------------------------------------------------------------


def _scene_light(kind):
    from vsgl_addon.scene_description import Light

    light = _light(kind)
    return Light(name=kind, type=kind, matrix_world=light.matrix_world, position=light.position,
                 direction=light.direction, color=np.array([1.0, 0.8, 0.5]), power=light.power,
                 energy=light.power, exposure=0.0, normalize=True, radius=0.0, spot_size=light.spot_size,
                 spot_blend=light.spot_blend, sun_angle=0.0, shape="SQUARE" if kind == "AREA" else "",
                 size=np.zeros(2), diffuse_factor=1.0, specular_factor=0.7)


def _proxy(alpha, center=(0.0, 0.0, 0.0), half=(2.0, 1.0)):
    from vsgl_addon.proxies import RectangleProxy

    return RectangleProxy(center=np.array(center, float), normal=np.array([0, 0, 1.0]),
                          axis_u=np.array([1.0, 0, 0]), axis_v=np.array([0, 1.0, 0]), half_u=half[0],
                          half_v=half[1], material_index=1, object_index=0, alpha=alpha,
                          f0=np.array([0.9, 0.6, 0.2]), area=4 * half[0] * half[1], triangle_count=2)


@pytest.mark.parametrize("mode", mrp.MODES)
def test_pass_against_reference(mode):
    """The full-screen pass over a numpy G-buffer (receivers above, in and below a proxy's plane,
    background pixels, perceptual roughness 0.03 … 1), two lights (a point light and a sun, colours
    and glossy factors), two proxies (one lit by both, one by the sun only), no shadows: per pixel
    against the reference summed over lights and proxies."""
    from vsgl_addon.passes import mrp_asg as mrp_pass
    from vsgl_addon.passes.vsgl_shading import upload_gbuffer

    rng = np.random.default_rng(12)
    h, w = 24, 32
    position = rng.uniform([-2, -1, -0.3], [2, 1, 2.0], (h, w, 3))
    position[0] = rng.uniform([-2, -1, 0], [2, 1, 0], (w, 3))
    coverage = np.ones((h, w))
    coverage[1, :5] = 0.0
    camera = np.array([3.0, -2.0, 2.5])
    normal = unit(rng.normal(size=(h, w, 3)) * 0.6 + [0, 0, -1])
    view = unit(camera - position)
    normal = np.where((np.sum(normal * view, -1) > 0)[..., None], normal, -normal)
    roughness = rng.choice([0.03, 0.1, 0.3, 0.7, 1.0], (h, w))
    f0 = rng.uniform(0.02, 1.0, (h, w, 3))
    position, normal, f0 = as_gpu_floats(position), gpu_unit(normal), as_gpu_floats(f0)
    gbuffer = upload_gbuffer(position, coverage, normal, roughness, np.zeros((h, w, 3)), f0,
                             roughness_is_perceptual=True)
    lights = [_scene_light("POINT"), _scene_light("SUN")]
    lit = [(_proxy(0.02), np.array([True, True])), (_proxy(0.1, (0.5, 0.2, -0.2), (0.5, 0.5)), np.array([False, True]))]
    pass_ = mrp_pass.run(gbuffer, camera, lights, {0: [], 1: []}, lit, 0.2, mode, shadows=False)
    try:
        image = pass_.read()
    finally:
        pass_.free()
    assert np.isfinite(image).all() and image.shape == (h, w, 4)
    flat = lambda a: a.reshape(-1, a.shape[-1]) if a.ndim == 3 else a.reshape(-1)
    pos, nrm = flat(position), flat(normal)
    vw = unit(camera - pos)
    alpha = flat(as_gpu_floats(roughness)) ** 2
    expected = np.zeros((h * w, 3))
    for index, light in enumerate(lights):
        for proxy, mask in lit:
            if not mask[index]:
                continue
            for ch in range(3):
                expected[:, ch] += (mrp.mrp_shade(pos, nrm, vw, alpha, flat(f0)[:, ch], proxy.as_rect(ch), light,
                                                  0.2, mode) * light.color[ch] * light.specular_factor)
    expected[flat(coverage) == 0] = 0.0
    got = flat(image[..., :3])
    assert np.count_nonzero(expected.max(axis=1) > 0) > 50
    check(got, expected, relative=2e-3, label=f"pass {mode}")
    # Alpha counts the draws that served each covered pixel (all of its receivers are in range).
    np.testing.assert_array_equal(image[..., 3], np.where(coverage > 0, 2.0, 0.0))
