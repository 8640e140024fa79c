"""VSGL shading reference (vsgl_addon/reference/vsgl_shading.py, 000 app. C) against brute force.

Brute force: every texel of a small RSM (a 16² floor patch under a spot, checker of diffuse and
glossy materials, roughness 0.1/0.3/0.6, bumpy normals) is a VPL with its exact Lambert + GGX
radiant intensity, summed exactly at receivers on a wall and a ceiling, seen from a camera, for
receiver roughness 0.1, 0.3, 1. The errors of each approximation are measured in steps
(``approximation_table``; run this file with ``-s`` to print it):

    exact VPLs ─(VPL lobes as SGs, 000 Eqs. 6-7)→ SG VPLs ─(receiver lobes: diffuse cosine
    pulled out, specular ASG, 000 app. C)→ VSGLs at N = M ─(clustering, 000 §4)→ VSGLs at N < M.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vsgl_addon.reference import vsgl_shading as vs
from vsgl_addon.reference.asg import asg_specular_lobe
from vsgl_addon.reference import sg
from vsgl_addon.reference.sg import sg_evaluate, sg_integral, sg_product_integral
from vsgl_addon.reference.vsgl import generate_vsgls

RECEIVER_ROUGHNESS = (0.1, 0.3, 1.0)


def floor_vpls(size=16):
    """VPLs of a 1 m² floor patch at z = 0 lit by a 10 W point-like spot at (0.2, -0.3, 1.5)."""
    u = (np.arange(size) + 0.5) / size - 0.5
    x, y = np.meshgrid(u, u, indexing="ij")
    position = np.stack([x, y, np.zeros_like(x)], -1)
    normal = np.stack([0.15 * np.sin(5 * x), 0.1 * np.cos(4 * y), np.ones_like(x)], -1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    light = np.array([0.2, -0.3, 1.5])
    incoming = light - position
    d2 = np.sum(incoming * incoming, -1)
    incoming /= np.sqrt(d2)[..., None]
    cos = np.maximum(np.sum(incoming * normal, -1), 0.0)
    flux = (10.0 / (4 * np.pi) * cos / d2 / size**2)[..., None] * np.array([1.0, 0.9, 0.8])
    checker = ((np.arange(size)[:, None] // 4 + np.arange(size)[None, :] // 4) % 2)[..., None] == 1
    rd = np.where(checker, [0.8, 0.2, 0.1], [0.1, 0.6, 0.2])
    f0 = np.where(checker, [0.04, 0.04, 0.04], [0.9, 0.6, 0.3])
    rough = np.array([0.1, 0.3, 0.6])[(np.arange(size)[:, None] * 3 // size) % 3] * np.ones((size, size))
    return vs.VPLs(position, normal, flux, rd, f0, rough, incoming)


def receivers(alpha):
    """21 shading points: 12 on a wall x = 0.9 (normal -x), 9 on a ceiling z = 0.9 (normal -z)."""
    points, normals = [], []
    for y in np.linspace(-0.4, 0.4, 4):
        for z in np.linspace(0.2, 0.8, 3):
            points.append([0.9, y, z])
            normals.append([-1.0, 0.0, 0.0])
    for x in np.linspace(-0.3, 0.3, 3):
        for y in np.linspace(-0.3, 0.3, 3):
            points.append([x, y, 0.9])
            normals.append([0.0, 0.0, -1.0])
    points, normals = np.array(points), np.array(normals)
    view = np.array([-1.5, 0.3, 0.4]) - points
    view /= np.linalg.norm(view, axis=-1, keepdims=True)
    count = len(points)
    return points, normals, view, np.full((count, 3), 0.7), np.full((count, 3), 0.5), np.full(count, alpha)


def relative_error(value, reference):
    """Σ|value - reference| / Σ|reference| over points and channels."""
    return float(np.abs(value - reference).sum() / np.abs(reference).sum())


@pytest.fixture(scope="module")
def scene():
    vpls = floor_vpls()
    return vpls, vpls.rsm(), vs.per_texel_vsgls(vpls.rsm())


# --- Building blocks ----------------------------------------------------------------------------


def test_incoming_sg_is_the_product_of_eq_12():
    rng = np.random.default_rng(3)
    omega = rng.normal(size=(200, 3))
    omega /= np.linalg.norm(omega, axis=-1, keepdims=True)
    position = np.array([0.3, -0.2, 0.5])
    mean = np.array([0.1, 0.4, 0.0])
    variance = 0.02
    axis = np.array([0.0, 0.6, 0.8])
    for sharpness in (0.0, 0.5, 2.0, 50.0):
        axis_in, lam_in, scale = vs.vsgl_incoming_sg(position, mean, variance, axis, sharpness)
        r = mean - position
        xi_mu = r / np.linalg.norm(r)
        direct = (sg_evaluate(omega, -axis, sharpness) * sg_evaluate(omega, xi_mu, r @ r / variance)
                  / (2 * np.pi * variance))
        np.testing.assert_allclose(scale * sg_evaluate(omega, axis_in, lam_in), direct, rtol=1e-10,
                                   atol=1e-14 * direct.max())


def _asg_point_light_specular(vsgls, points, normals, view, f0, alpha):
    """Independent point-light form of the ASG specular: I(ω)/d² C(ω) Ǵ(ω) at ω = towards µv."""
    out = np.zeros((len(points), 3))
    for p in range(len(points)):
        r = vsgls["mean"] - points[p]
        d2 = np.sum(r * r, -1)
        omega = r / np.sqrt(d2)[:, None]
        x, y, z, ex, ey = asg_specular_lobe(view[p], normals[p], alpha[p])
        ci = np.maximum(omega @ normals[p], 0.0)
        co = view[p] @ normals[p]
        a2 = alpha[p] ** 2
        half = omega + view[p]
        half /= np.linalg.norm(half, axis=-1, keepdims=True)
        fresnel = f0[p] + (1 - f0[p]) * ((1 - np.clip(np.sum(omega * half, -1), 0, 1)) ** 5)[:, None]
        lobe = ci * np.exp(-ex * (omega @ x) ** 2 - ey * (omega @ y) ** 2) / (np.pi * a2) / (
            (ci + np.sqrt((1 - a2) * ci**2 + a2)) * (co + np.sqrt((1 - a2) * co**2 + a2)))
        intensity = (vsgls["diffuse_amplitude"] * sg_evaluate(-omega, vsgls["diffuse_axis"], vsgls["diffuse_sharpness"])[:, None]
                     + vsgls["specular_amplitude"] * sg_evaluate(-omega, vsgls["specular_axis"], vsgls["specular_sharpness"])[:, None])
        out[p] = np.sum(intensity / d2[:, None] * fresnel * lobe[:, None], 0)
    return out


@pytest.mark.parametrize("alpha", RECEIVER_ROUGHNESS)
def test_per_texel_vsgls_are_the_point_light_limit(scene, alpha):
    """N = M: σv² at its floor, each VSGL is its VPL with SG lobes as a point light; the diffuse is
    then exactly brute force with SG VPL lobes (the pulled-out cosine is exact for a point), the
    specular the receiver's ASG lobe evaluated at the light's direction."""
    vpls, rsm, texel_vsgls = scene
    rec = receivers(alpha)
    diffuse, specular = vs.shade(texel_vsgls, *rec, diffuse_mode="cosine")
    sg_diffuse, _ = vs.brute_force_shading(vpls, *rec, vpl_lobes="sg")
    np.testing.assert_allclose(diffuse, sg_diffuse, rtol=1e-4)
    expected = _asg_point_light_specular(texel_vsgls, rec[0], rec[1], rec[2], rec[4], rec[5])
    np.testing.assert_allclose(specular, expected, rtol=2e-4, atol=1e-6 * expected.max())


def approximation_table(quadrature=True):
    """Relative errors (Σ|Δ|/Σ|ref|) of each approximation, per receiver roughness: rows of
    (step, alpha, diffuse error, specular error)."""
    vpls = floor_vpls()
    rsm = vpls.rsm()
    texel_vsgls = vs.per_texel_vsgls(rsm)
    rows = []
    for alpha in RECEIVER_ROUGHNESS:
        rec = receivers(alpha)
        exact = vs.brute_force_shading(vpls, *rec)
        sg_vpls = vs.brute_force_shading(vpls, *rec, vpl_lobes="sg")
        rows.append(("VPL lobes as SGs (000 Eqs. 6-7) vs exact VPLs", alpha,
                     relative_error(sg_vpls[0], exact[0]), relative_error(sg_vpls[1], exact[1])))
        per_texel = vs.shade(texel_vsgls, *rec, diffuse_mode="cosine")
        rows.append(("receiver lobes (cosine out, ASG + C) vs SG VPLs, N = M", alpha,
                     relative_error(per_texel[0], sg_vpls[0]), relative_error(per_texel[1], sg_vpls[1])))
        literal = vs.shade(texel_vsgls, *rec, diffuse_mode="cosine", specular_cosine="lobe-axis")
        rows.append(("  same, ASG cosine <w,xi_z> kept (C literal)", alpha, float("nan"),
                     relative_error(literal[1], sg_vpls[1])))
        rows.append(("VSGL shading N = M vs exact VPLs (total)", alpha,
                     relative_error(per_texel[0], exact[0]), relative_error(per_texel[1], exact[1])))
        for count in (16, 64):
            vsgls = generate_vsgls(rsm, count)
            clustered = vs.shade(vsgls, *rec, diffuse_mode="cosine")
            rows.append((f"clustering N = {count} vs N = M", alpha,
                         relative_error(clustered[0], per_texel[0]), relative_error(clustered[1], per_texel[1])))
            rows.append((f"VSGL shading N = {count} vs exact VPLs (total)", alpha,
                         relative_error(clustered[0], exact[0]), relative_error(clustered[1], exact[1])))
        two = generate_vsgls(rsm, 2, kernel="two-vsgl")
        two_shaded = vs.shade(two, *rec, diffuse_mode="sg-convolution")
        rows.append(("2-VSGL mode (003, SG-convolution diffuse) vs exact VPLs", alpha,
                     relative_error(two_shaded[0], exact[0]), relative_error(two_shaded[1], exact[1])))
        if quadrature:
            vsgls = generate_vsgls(rsm, 16)
            approx = vs.shade(vsgls, *rec, diffuse_mode="cosine")
            rows.append(("diffuse cosine pulled out vs quadrature of Eq. 12's SG, N = 16", alpha,
                         relative_error(approx[0], diffuse_quadrature(vsgls, *rec)), float("nan")))
    return rows


def diffuse_quadrature(vsgls, points, normals, view, rd, f0, alpha, samples=100_000, incoming="eq-12"):
    """∫ Lin(ω) Rd/π ⟨ω,n⟩ dω of Eq. 12's SGs (or of the separable incoming radiance,
    ``incoming="separable"``) by a Fibonacci-sphere rule (no cosine pulled out)."""
    i = np.arange(samples) + 0.5
    z = 1 - 2 * i / samples
    phi = np.pi * (1 + 5**0.5) * i
    s = np.sqrt(1 - z * z)
    omega = np.stack([s * np.cos(phi), s * np.sin(phi), z], -1)
    weight = 4 * np.pi / samples
    out = np.zeros((len(points), 3))
    for p in range(len(points)):
        cos = np.maximum(omega @ normals[p], 0.0)
        for lobe in ("diffuse", "specular"):
            incoming_lobe = vs.vsgl_separable_lobe if incoming == "separable" else vs.vsgl_incoming_sg
            axis_in, lam_in, scale = incoming_lobe(points[p], vsgls["mean"], vsgls["variance"],
                                                   vsgls[f"{lobe}_axis"], vsgls[f"{lobe}_sharpness"])
            c_in = vsgls[f"{lobe}_amplitude"] * scale[:, None]
            for j in range(len(lam_in)):
                integral = weight * np.sum(sg_evaluate(omega, axis_in[j], lam_in[j]) * cos)
                out[p] += c_in[j] * rd[p] / np.pi * integral
    return out


@pytest.fixture(scope="module")
def table():
    rows = approximation_table(quadrature=False)
    print("\n| step | α | diffuse | specular |\n|---|---|---|---|")
    for step, alpha, d, s in rows:
        print(f"| {step} | {alpha} | {d:.3f} | {s:.3f} |")
    return {(step, alpha): (d, s) for step, alpha, d, s in rows}


@pytest.mark.parametrize("alpha", RECEIVER_ROUGHNESS)
def test_vsgl_shading_converges_to_brute_force(table, alpha):
    """Measured (see the table): the diffuse error is the λd = 2 SG of the VPLs' Lambert lobe
    (5.6 %: normalized over the hemisphere, sg.DIFFUSE_HEMISPHERE_SCALE, it carries Lambert's
    energy but is 15.6 % above Lambert at the normal, where these receivers above a lit floor see
    most of it; sphere-normalized it was 4 % here and 11-13 % short in the suite's closed rooms) at
    N = M and grows slowly with clustering; the specular error is dominated by the receiver's
    Gaussian fit of GGX (λh = 2/α², wider at the peak, no tails: 25-40 %; 52 % at α = 0.1, where
    the hemisphere-normalized diffuse lobes' light on the receivers' sharp GGX lobe, 15.6 % above
    Lambert's near the reflector's normal, adds 7 points to the 45 % of the sphere-normalized one)."""
    d_total, s_total = table[("VSGL shading N = M vs exact VPLs (total)", alpha)]
    d_sg, s_sg = table[("VPL lobes as SGs (000 Eqs. 6-7) vs exact VPLs", alpha)]
    assert d_total <= d_sg + 1e-3 and d_total < 0.06
    assert s_total < 0.55
    for count in (16, 64):
        d_n, s_n = table[(f"VSGL shading N = {count} vs exact VPLs (total)", alpha)]
        assert d_n < 0.11
        assert s_n < 0.6
        d_c, s_c = table[(f"clustering N = {count} vs N = M", alpha)]
        assert d_c < 0.08 and s_c < 0.25
    # Clustering error falls as N -> M (it is 0 at N = M by construction).
    d16, s16 = table[("clustering N = 16 vs N = M", alpha)]
    d64, s64 = table[("clustering N = 64 vs N = M", alpha)]
    assert d64 < d16 and s64 < s16
    # C with the rendering equation's cosine <w, n> (the default) beats the literal ASG cosine.
    _, s_literal = table[("  same, ASG cosine <w,xi_z> kept (C literal)", alpha)]
    _, s_default = table[("receiver lobes (cosine out, ASG + C) vs SG VPLs, N = M", alpha)]
    assert s_default < s_literal


def test_generated_vsgls_at_n_equal_m_match_per_texel_vsgls(scene):
    """The generator at N = M with a uniform PDF puts one kernel on every texel (level 0)."""
    vpls, rsm, texel_vsgls = scene
    vsgls = generate_vsgls(rsm, rsm.texel_count, pdf=np.ones((rsm.size, rsm.size)), seed=None)
    rec = receivers(0.3)
    a = vs.shade(vsgls, *rec, diffuse_mode="cosine")
    b = vs.shade(texel_vsgls, *rec, diffuse_mode="cosine")
    assert relative_error(a[0], b[0]) < 0.02 and relative_error(a[1], b[1]) < 0.05


def test_two_vsgl_mode_convolves_with_the_diffuse_sg():
    axis_in = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.6, 0.0, 0.8]])
    lam_in = np.array([5.0, 5.0, 0.3])
    normal = np.array([0.0, 0.0, 1.0])
    conv = vs.vsgl_diffuse_factor(axis_in, lam_in, normal, "sg-convolution")
    np.testing.assert_allclose(conv, sg_product_integral(axis_in, lam_in, normal, 2.0) / sg_integral(2.0))
    cosine = vs.vsgl_diffuse_factor(axis_in, lam_in, normal, "cosine")
    assert cosine[1] == 0.0 and conv[1] > 0.0  # the SG convolution leaks light from below
    assert vs.diffuse_mode_for_kernel("two-vsgl") == "sg-convolution"
    assert vs.diffuse_mode_for_kernel("modified") == "separable"
    assert vs.diffuse_mode_for_kernel("original") == "separable"


def test_a_call_without_a_mode_shades_as_the_renderer(scene):
    """A direct call that names no diffuse mode gets the renderer's for the settings' default kernel
    (the separable form), not Eq. 12's."""
    from vsgl_addon.settings import VSGLSettings

    assert vs.DEFAULT_DIFFUSE_MODE == vs.diffuse_mode_for_kernel(VSGLSettings().kernel) == "separable"
    _, rsm, _ = scene
    vsgls = generate_vsgls(rsm, 16)
    rec = receivers(0.3)
    default, _ = vs.shade(vsgls, *rec)
    np.testing.assert_array_equal(default, vs.shade(vsgls, *rec, diffuse_mode="separable")[0])
    assert relative_error(default, vs.shade(vsgls, *rec, diffuse_mode="cosine")[0]) > 1e-3


def test_extremes_are_finite():
    """VSGL at the shading point, σv² → 0, λ from 0 to 1e20, grazing and back-facing views,
    back-facing VSGLs, zero power: every output finite and non-negative."""
    n = 7
    vsgls = {
        "mean": np.array([[0, 0, 0], [0, 0, 1e-9], [0, 0, 1], [0, 0, -1], [3, 0, 0.1], [0, 1e3, 1], [0, 0, 2]], float),
        "variance": np.array([0.0, 1e-12, 1e-12, 1.0, 1e-30, 1e-12, 1e4]),
        "diffuse_amplitude": np.array([[1, 1, 1]] * 6 + [[0, 0, 0]], float),
        "diffuse_axis": np.array([[0, 0, -1]] * n, float),
        "diffuse_sharpness": np.array([2.0, 1e6, 1e-6, 0.0, 1e20, 2.0, 2.0]),
        "specular_amplitude": np.array([[1e5, 1e5, 1e5]] * 6 + [[0, 0, 0]], float),
        "specular_axis": np.array([[0, 0, -1], [0, 0, 1], [1, 0, 0], [0, 0, -1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]], float),
        "specular_sharpness": np.array([1e6, 1e6, 0.0, 1e-6, 1e6, 1e6, 1e6]),
    }
    # Each lobe at its own position (per-lobe positional distribution): the specular lobes in
    # reverse order, so every extreme position meets both lobes.
    vsgls["diffuse_mean"], vsgls["diffuse_variance"] = vsgls["mean"], vsgls["variance"]
    vsgls["specular_mean"], vsgls["specular_variance"] = vsgls["mean"][::-1], vsgls["variance"][::-1]
    views = np.array([[0, 0, 1], [1, 0, 1e-7], [1, 0, 0], [1, 0, -0.5], [0.6, 0, 0.8]], float)
    views /= np.linalg.norm(views, axis=-1, keepdims=True)
    for alpha in (0.0, 1e-3, 0.5, 1.0):
        for mode in vs.DIFFUSE_MODES:
            m = len(views)
            d, s = vs.shade(vsgls, np.zeros((m, 3)), np.tile([0, 0, 1.0], (m, 1)), views,
                            np.full((m, 3), 0.8), np.full((m, 3), 0.04), np.full(m, alpha), diffuse_mode=mode)
            assert np.all(np.isfinite(d)) and np.all(np.isfinite(s))
            assert np.all(d >= 0) and np.all(s >= 0)
    # Back-facing view: no specular; back-facing VSGL (light from below): no diffuse.
    below = {k: v[3:4] for k, v in vsgls.items()}
    d, s = vs.shade(below, np.zeros((1, 3)), [[0, 0, 1.0]], [[0, 0, 1.0]], [[1, 1, 1.0]], [[1, 1, 1.0]], [0.5],
                    diffuse_mode="cosine")
    assert np.all(d == 0.0)


def test_pulling_the_cosine_out_costs_a_few_percent(scene):
    """000 app. C pulls ⟨ω, n⟩ out of the diffuse integral: against a quadrature of Eq. 12's SGs
    times the cosine (N = 16 clusters, receivers as above) it costs 2.8 % (Σ|Δ|/Σ)."""
    vpls, rsm, _ = scene
    vsgls = generate_vsgls(rsm, 16)
    rec = receivers(0.3)
    approx, _ = vs.shade(vsgls, *rec, diffuse_mode="cosine")
    exact = diffuse_quadrature(vsgls, *rec, samples=40_000)
    error = relative_error(approx, exact)
    print(f"\ncosine pulled out vs quadrature, N = 16: {error:.4f}")
    assert error < 0.05


def test_clamped_cosine_diffuse_is_the_integral_of_eq_12(scene):
    """The clamped-cosine diffuse mode integrates Eq. 12's SG times the clamped cosine (Tokuyoshi et al.
    2024, reference/sg.py) instead of pulling the cosine out: against the same quadrature as above
    (N = 16 and N = 256) it is 0.35 % and 0.04 % off (partly the quadrature's own error), 000 app. C
    3.1 % and 0.24 % on this open floor patch (in the suite's rooms, where much light arrives at
    grazing angles and from broad lobes, the difference is 6-7 %: benchmarks/energy_budget.py)."""
    vpls, rsm, _ = scene
    rec = receivers(0.3)
    for count in (16, 256):
        vsgls = generate_vsgls(rsm, count)
        exact = diffuse_quadrature(vsgls, *rec, samples=40_000)
        clamped, _ = vs.shade(vsgls, *rec, diffuse_mode="clamped-cosine")
        cosine, _ = vs.shade(vsgls, *rec, diffuse_mode="cosine")
        print(f"\nN = {count}: clamped cosine {relative_error(clamped, exact):.4f}, cosine pulled out "
              f"{relative_error(cosine, exact):.4f}")
        assert relative_error(clamped, exact) < min(0.005, relative_error(cosine, exact) / 5.0)


def test_clamped_cosine_lights_a_flat_reflectors_own_surface(scene):
    """Why the clamped cosine is not the default (module documentation): receivers on the lit floor
    patch itself (normal +z) get no light from it, by brute force and with the cosine pulled out
    (Eq. 12's lobe axis is below their horizon); the exact integral of Eq. 12's SG gives them 27-44 %
    of what the wall and ceiling receive (N = 16 and 256)."""
    vpls, rsm, _ = scene
    u = np.linspace(-0.4, 0.4, 5)
    x, y = np.meshgrid(u, u)
    floor = (np.stack([x.ravel(), y.ravel(), np.zeros(25)], -1), np.tile([0.0, 0.0, 1.0], (25, 1)),
             np.tile([0.0, 0.0, 1.0], (25, 1)), np.ones((25, 3)), np.zeros((25, 3)), np.full(25, 0.5))
    brute, _ = vs.brute_force_shading(vpls, *floor)
    assert np.all(brute == 0.0)
    rec = receivers(0.3)
    for count in (16, 256):
        vsgls = generate_vsgls(rsm, count)
        cosine, _ = vs.shade(vsgls, *floor, diffuse_mode="cosine")
        separable, _ = vs.shade(vsgls, *floor, diffuse_mode="separable")
        clamped, _ = vs.shade(vsgls, *floor, diffuse_mode="clamped-cosine")
        walls, _ = vs.shade(vsgls, *rec, diffuse_mode="clamped-cosine")
        print(f"\nN = {count}: floor self-light / wall light {clamped.mean() / walls.mean():.3f}")
        assert np.all(cosine == 0.0) and np.all(separable == 0.0)
        assert clamped.mean() > 0.2 * walls.mean()


# --- The separable incoming radiance (the default diffuse mode) ----------------------------------


def test_separable_lobe_is_eqs_10_11_at_the_direction_of_the_mean():
    """Lin(ω) = G(−ξµ; ξv, λv) G(ω; ξµ, λσ)/(2πσv²): 000 Eq. 10-11 with Iv(−ω) taken at ω = ξµ."""
    rng = np.random.default_rng(4)
    omega = rng.normal(size=(200, 3))
    omega /= np.linalg.norm(omega, axis=-1, keepdims=True)
    position, mean, variance = np.array([0.3, -0.2, 0.5]), np.array([0.1, 0.4, 0.0]), 0.02
    axis = np.array([0.0, 0.6, 0.8])
    r = mean - position
    xi_mu = r / np.linalg.norm(r)
    for sharpness in (0.0, 0.5, 2.0, 50.0):
        axis_out, lam, scale = vs.vsgl_separable_lobe(position, mean, variance, axis, sharpness)
        direct = (sg_evaluate(-xi_mu, axis, sharpness) * sg_evaluate(omega, xi_mu, r @ r / variance)
                  / (2 * np.pi * variance))
        np.testing.assert_allclose(scale * sg_evaluate(omega, axis_out, lam), direct, rtol=1e-12)
    # At the mean: −ξv stands in for ξµ, as in Eq. 12's product.
    axis_out, lam, scale = vs.vsgl_separable_lobe(mean, mean, variance, axis, 2.0)
    assert lam == 0.0 and np.allclose(axis_out, -axis) and np.isclose(scale, 1 / (2 * np.pi * variance))


def test_separable_far_field_is_the_point_light_and_eq_12():
    """000 app. C.1 derives Eq. 12 for small σv or a large distance: at 100 σv the separable diffuse
    is the point light Iv(−ξµ) ⟨ξµ, n⟩ Rd/(π d²) (A(λσ)/(2πσv²) = (1 − e^(−2λσ))/d²) and Eq. 12's
    pulled-out cosine agrees with it within 2 % for λv ≤ 10 (the exponents differ by
    λv²(1 − ⟨ξµ, −ξv⟩²)/(2λσ) to first order; for sharper lobes they agree farther away)."""
    rng = np.random.default_rng(5)
    unit = lambda v: v / np.linalg.norm(v, axis=-1, keepdims=True)
    axis, normal, offset = (unit(rng.normal(size=(2000, 3))) for _ in range(3))
    variance = 0.01
    distance = 100 * np.sqrt(variance)
    position = -offset * distance
    lit = np.sum(offset * normal, -1) > 0.2
    for sharpness in (0.0, 0.5, 2.0, 10.0):
        xi_mu, lam_sigma, scale = vs.vsgl_separable_lobe(position, np.zeros(3), variance, axis, sharpness)
        separable = scale * vs.vsgl_diffuse_factor(xi_mu, lam_sigma, normal, "separable")
        point = (sg_evaluate(-offset, axis, sharpness) * np.maximum(np.sum(offset * normal, -1), 0.0)
                 / (np.pi * distance**2))
        np.testing.assert_allclose(separable, point, rtol=1e-12, atol=1e-300)
        axis_in, lam_in, scale_in = vs.vsgl_incoming_sg(position, np.zeros(3), variance, axis, sharpness)
        eq12 = scale_in * vs.vsgl_diffuse_factor(axis_in, lam_in, normal, "cosine")
        ratio = separable[lit] / eq12[lit]
        assert np.all(np.abs(ratio - 1.0) < 0.02), (sharpness, ratio.min(), ratio.max())


def test_separable_cosine_pulled_out_against_quadrature(scene):
    """The separable diffuse pulls the cosine out of the positional lobe's integral (000 app. C):
    against a quadrature of the separable radiance times the cosine (receivers above the floor patch)
    it costs 3.4 % at N = 16 and 0.2 % at N = 256, about what pulling it out of Eq. 12's lobe does."""
    vpls, rsm, _ = scene
    rec = receivers(0.3)
    for count in (16, 256):
        vsgls = generate_vsgls(rsm, count)
        exact = diffuse_quadrature(vsgls, *rec, samples=40_000, incoming="separable")
        separable, _ = vs.shade(vsgls, *rec, diffuse_mode="separable")
        error = relative_error(separable, exact)
        print(f"\nN = {count}: separable, cosine pulled out vs quadrature {error:.4f}")
        assert error < 0.05


def corner_vpls(size=16, extent=0.5):
    """A room's corner: a floor strip z = 0 (0 < x < extent) and a wall strip x = 0 (0 < z < extent),
    each half of a size² RSM, lit by a 10 W point light at (0.8, 0.1, 0.9); Lambert, Rd = 0.7."""
    u = (np.arange(size) + 0.5) / size * extent
    a, b = np.meshgrid(u, (np.arange(size) + 0.5) / size - 0.5, indexing="ij")
    floor = (np.arange(size)[:, None] < size // 2)[..., None]
    t = np.where(floor[..., 0], 2 * a, 2 * a - extent)
    position = np.where(floor, np.stack([t, b, 0 * t], -1), np.stack([0 * t, b, t], -1))
    normal = np.where(floor, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]) * np.ones_like(position)
    incoming = np.array([0.8, 0.1, 0.9]) - position
    d2 = np.sum(incoming * incoming, -1)
    incoming /= np.sqrt(d2)[..., None]
    cos = np.maximum(np.sum(incoming * normal, -1), 0.0)
    flux = (10 / (4 * np.pi) * cos / d2 * extent / size**2)[..., None] * np.ones(3)
    return vs.VPLs(position, normal, flux, np.full(position.shape, 0.7), np.zeros(position.shape),
                   np.full((size, size), 0.5), incoming)


def test_separable_keeps_the_light_of_a_cluster_spanning_a_corner():
    """One VSGL of a corner's floor and wall (its mean between them, ξv diagonal, λv broad): Eq. 12's
    product tilts each receiver's incoming lobe towards −ξv, behind the cluster's walls, and its
    pulled-out cosine loses 28 % of what the same VPLs with SG lobes give (brute force) on receivers
    across the room (opposite wall, ceiling, floor and wall beyond the cluster: 20-23 % of theirs
    left); the separable radiance keeps the lobe on ξµ and loses 13 %. At N = 16 both are close."""
    vpls = corner_vpls()
    rsm = vpls.rsm()
    points, normals = [], []
    for y in np.linspace(-0.4, 0.4, 3):
        for s in np.linspace(0.2, 0.9, 4):
            points += [[1.0, y, s], [s, y, 1.0], [s + 0.6, y, 0.0], [0.0, y, s + 0.6]]
            normals += [[-1.0, 0, 0], [0, 0, -1.0], [0, 0, 1.0], [1.0, 0, 0]]
    points, normals = np.array(points), np.array(normals)
    m = len(points)
    rec = (points, normals, normals, np.ones((m, 3)), np.zeros((m, 3)), np.full(m, 0.5))
    brute, _ = vs.brute_force_shading(vpls, *rec, vpl_lobes="sg")
    one = generate_vsgls(rsm, 1, seed=1)
    eq12, _ = vs.shade(one, *rec, diffuse_mode="cosine")
    separable, _ = vs.shade(one, *rec, diffuse_mode="separable")
    print(f"\ncorner VSGL / brute force: Eq. 12 {eq12.sum() / brute.sum():.3f}, separable "
          f"{separable.sum() / brute.sum():.3f}")
    assert eq12.sum() < 0.75 * brute.sum()
    assert 0.85 * brute.sum() < separable.sum() < 1.05 * brute.sum()
    assert relative_error(separable, brute) < 0.6 * relative_error(eq12, brute)
    sixteen = generate_vsgls(rsm, 16, seed=1)
    for mode in ("cosine", "separable"):
        assert relative_error(vs.shade(sixteen, *rec, diffuse_mode=mode)[0], brute) < 0.05


def test_separable_shading_converges_to_brute_force(scene):
    """On the floor patch the separable diffuse is the point light at N = M (σv² at its floor), as
    Eq. 12's is (with 000 Eq. 6's SG emission the SG VPLs', with the flat clusters' Lambertian
    emission the exact VPLs' diffuse), and about as close to the exact VPLs after clustering (Σ|Δ|/Σ:
    11.9 % with the SG emission, 11.3 % with Lambert's, against Eq. 12's 10.0 % at N = 16; 5.6 %,
    5.1 % and 5.7 % at N = 64); the specular is Eq. 12's, unchanged."""
    vpls, rsm, texel_vsgls = scene
    rec = receivers(0.3)
    exact, _ = vs.brute_force_shading(vpls, *rec)
    sg_vpls, _ = vs.brute_force_shading(vpls, *rec, vpl_lobes="sg")
    texel_d, texel_s = vs.shade(texel_vsgls, *rec, diffuse_mode="separable", diffuse_emission="sg")
    np.testing.assert_allclose(texel_d, sg_vpls, rtol=1e-4)
    # With the flat clusters' Lambertian emission (the default) a texel's diffuse lobe is its exact VPL's.
    matte = dataclasses.replace(vpls, specular_f0=np.zeros_like(vpls.specular_f0))
    matte_exact, _ = vs.brute_force_shading(matte, *rec)
    np.testing.assert_allclose(vs.shade(vs.per_texel_vsgls(matte.rsm()), *rec, diffuse_mode="separable")[0],
                               matte_exact, rtol=5e-3)
    np.testing.assert_array_equal(texel_s, vs.shade(texel_vsgls, *rec, diffuse_mode="cosine")[1])
    for count in (16, 64):
        vsgls = generate_vsgls(rsm, count)
        separable = vs.shade(vsgls, *rec, diffuse_mode="separable", diffuse_emission="sg")[0]
        lambert = vs.shade(vsgls, *rec, diffuse_mode="separable")[0]
        cosine = vs.shade(vsgls, *rec, diffuse_mode="cosine")[0]
        print(f"\nN = {count} vs exact VPLs: separable {relative_error(separable, exact):.4f}, "
              f"with Lambert's lobes {relative_error(lambert, exact):.4f}, Eq. 12 {relative_error(cosine, exact):.4f}")
        assert relative_error(separable, exact) < min(0.13, relative_error(cosine, exact) + 0.03)
        assert relative_error(lambert, exact) < relative_error(separable, exact)


def test_separable_shading_takes_the_visibility():
    """Visibility weights the separable diffuse of each lobe as it weights Eq. 12's."""
    vpls = floor_vpls(8)
    vsgls = generate_vsgls(vpls.rsm(), 4)
    rec = receivers(0.3)
    visibility = np.random.default_rng(2).uniform(size=(len(rec[0]), 4, 2))
    _, _, terms = vs.shade(vsgls, *rec, diffuse_mode="separable", per_term=True)
    seen_d, seen_s = vs.shade(vsgls, *rec, diffuse_mode="separable", visibility=visibility)
    np.testing.assert_allclose(seen_d, np.sum(terms[..., 0, :] * visibility[..., None], axis=(1, 2)), rtol=1e-12)
    np.testing.assert_allclose(seen_s, np.sum(terms[..., 1, :] * visibility[..., None], axis=(1, 2)), rtol=1e-12)


@pytest.mark.parametrize("alpha", [0.1, 0.3, 1.0])
def test_separable_specular_is_worse_on_sharp_receivers(alpha):
    """Specular mode "separable" (the diffuse's idea on the receiver's ASG: the positional lobe
    G(ω; ξµ, λσ) convolved with it, the emission taken at −ξµ) against Eq. 12's product, on the
    floor patch made diffuse-only (Φ Rd alone, as the demo's gold sees its floor), receivers on the
    wall and ceiling. At N = M both are the point light. Clustered (N = 16) the separable form keeps
    the emission of the mean's direction over the whole positional lobe, which straddles the flat
    cluster's plane, where the product's emission lobe G(ω; −ξv, λv) fades towards grazing: the
    sharp receivers' lobes, aimed at the floor near grazing, then get too much (measured Σ|Δ|/Σ
    against the exact VPLs, both with the flat clusters' Lambertian emission: 0.53 against 0.30 at
    α = 0.1, 0.25 against 0.22 at α = 0.3), the broad ones a little less error (0.26 against 0.28 at
    α = 1)
    (benchmarks/specular_receiver_split.py on the suite: docs/accuracy.md)."""
    vpls = floor_vpls()
    vpls = vs.VPLs(vpls.position, vpls.normal, vpls.flux, vpls.diffuse_reflectance,
                   np.zeros_like(vpls.specular_f0), vpls.roughness, vpls.incoming)
    rec = receivers(alpha)
    exact = vs.brute_force_shading(vpls, *rec)[1]
    texel_vsgls = vs.per_texel_vsgls(vpls.rsm())
    np.testing.assert_allclose(vs.shade(texel_vsgls, *rec, diffuse_mode="separable", specular_mode="separable")[1],
                               vs.shade(texel_vsgls, *rec, diffuse_mode="separable")[1], rtol=1e-4)
    vsgls = generate_vsgls(vpls.rsm(), 16)
    product = vs.shade(vsgls, *rec, diffuse_mode="separable")[1]
    separable = vs.shade(vsgls, *rec, diffuse_mode="separable", specular_mode="separable")[1]
    assert np.all(np.isfinite(separable)) and np.all(separable >= 0.0)
    e_product, e_separable = relative_error(product, exact), relative_error(separable, exact)
    print(f"\nα = {alpha}, N = 16 vs exact VPLs: product {e_product:.3f}, separable {e_separable:.3f}")
    if alpha < 0.5:
        assert e_separable > e_product + 0.02
    else:
        assert e_separable < e_product + 0.01
    with pytest.raises(ValueError):
        vs.shade(vsgls, *rec, specular_mode="cosine")


def two_material_vpls(size=16):
    """The floor of ``floor_vpls`` made diffuse-only, with a specular-only (gold) block on its
    right quarter raised to z = 0.6: clusters at the seam mix two surfaces of different lobes."""
    vpls = floor_vpls(size)
    block = (np.arange(size) >= 3 * size // 4)[:, None] & np.ones(size, bool)[None, :]
    position = vpls.position.copy()
    position[block, 2] = 0.6
    rd = np.where(block[..., None], 0.0, vpls.diffuse_reflectance)
    f0 = np.where(block[..., None], [0.9, 0.65, 0.25], 0.0)
    return vs.VPLs(position, vpls.normal, vpls.flux, rd, f0, vpls.roughness, vpls.incoming)


def block_side_receivers(alpha):
    """12 glossy points on the side of the block (x = 0.2, normal -x, z in [0.05, 0.5]) that face
    the floor next to it, viewed from across the floor."""
    y, z = np.meshgrid(np.linspace(-0.3, 0.3, 4), np.linspace(0.05, 0.5, 3), indexing="ij")
    points = np.stack([np.full(y.size, 0.2), y.ravel(), z.ravel()], -1)
    normals = np.tile([-1.0, 0.0, 0.0], (len(points), 1))
    view = np.array([-1.5, 0.3, 0.8]) - points
    view /= np.linalg.norm(view, axis=-1, keepdims=True)
    count = len(points)
    return points, normals, view, np.full((count, 3), 0.0), np.full((count, 3), 0.9), np.full(count, alpha)


@pytest.mark.parametrize("alpha", [0.1, 0.3])
def test_per_lobe_positions_keep_a_diffuse_floor_where_it_is(alpha):
    """Clusters mixing a diffuse floor with a specular block: the shared position (000 app. B.2)
    lifts the floor's light towards the block, behind a glossy receiver on the block's side that
    faces the floor; per-lobe positions keep it on the floor. Against the N = M limit (every texel
    its own VSGL), mean over 8 lattice rotations at N = 16. Measured Σ|Δ|/Σ: α = 0.1 0.58 vs 0.78,
    α = 0.3 0.45 vs 0.58; the light kept, Σ/Σ: 0.67 vs 0.62 and 0.56 vs 0.46 (the rest is N = 16
    clusters seen from 0.05-0.5 m)."""
    vpls = two_material_vpls()
    rsm = vpls.rsm()
    rec = block_side_receivers(alpha)
    texel = vs.shade(vs.per_texel_vsgls(rsm), *rec, diffuse_mode="cosine")
    exact = texel[0] + texel[1]
    errors, means = {}, {}
    for positions in ("per-lobe", "shared"):
        error = mean = 0.0
        for seed in range(8):
            d, s = vs.shade(generate_vsgls(rsm, 16, seed=seed, positional_distribution=positions), *rec, diffuse_mode="cosine")
            error += relative_error(d + s, exact) / 8
            mean += float((d + s).sum() / exact.sum()) / 8
        errors[positions], means[positions] = error, mean
    print(f"\nα = {alpha}, N = 16 against per-texel VSGLs: Σ|Δ|/Σ {errors}, Σ/Σ {means}")
    assert errors["per-lobe"] < 0.85 * errors["shared"]
    assert means["per-lobe"] > means["shared"]


def test_diffuse_emission_of_flat_and_bent_clusters():
    """vsgl_diffuse_emission: a flat cluster (λv = 2, r̄ = 1) emits Lambert's lobe, its flux the
    cluster's P = cv A(λv)/(1 + e^(−λd)) and nothing below its horizon; a bent one (r̄ ≤ 0.95) keeps
    000 Eq. 6's SG; in between the blend is continuous in λv; finite and ≥ 0 from λv = 0 to 1e6 and
    μ = −1 … 1."""
    mu = np.linspace(-1.0, 1.0, 2001)
    flat = vs.vsgl_diffuse_emission(mu, 2.0)
    flux = sg.sg_integral(2.0) / sg.DIFFUSE_HEMISPHERE_SCALE
    np.testing.assert_allclose(flat, flux * np.maximum(mu, 0.0) / np.pi, rtol=1e-12)
    # ∫ I dω = 2π ∫ I(μ) dμ = P (the trapezoid rule on 2001 points).
    assert 2.0 * np.pi * np.trapz(flat, mu) == pytest.approx(flux, rel=1e-5)
    for lam in (0.0, 0.5, 1.0, 1.5):
        assert vs.mean_normal_length(lam) <= vs.FLAT_CLUSTER[0]
        np.testing.assert_allclose(vs.vsgl_diffuse_emission(mu, lam), np.exp(lam * (mu - 1.0)), rtol=1e-12)
    lams = np.linspace(1.5, 2.0, 501)
    values = vs.vsgl_diffuse_emission(0.3, lams)
    assert np.max(np.abs(np.diff(values))) < 0.01 * values.max()
    extremes = vs.vsgl_diffuse_emission(mu[:, None], np.array([0.0, 1e-6, 2.0, 2.0001, 10.0, 1e6])[None, :])
    assert np.all(np.isfinite(extremes)) and np.all(extremes >= 0.0)


def test_diffuse_emission_ratio_is_the_emission_over_the_sg():
    """vsgl_diffuse_emission_ratio = vsgl_diffuse_emission / e^(λv (μ − 1)) without dividing: equal to
    the quotient across the SG → Lambert blend, 1 for a cluster that keeps the SG, 0 at and below a
    flat cluster's horizon; finite, ≥ 0 and bounded for λv 0 … 1e6 and μ −1 … 1."""
    mu = np.linspace(-1.0, 1.0, 401)
    for lam in (1.6, 1.8, 1.9, 2.0, 2.0001):
        quotient = vs.vsgl_diffuse_emission(mu, lam) / np.exp(lam * (mu - 1.0))
        np.testing.assert_allclose(vs.vsgl_diffuse_emission_ratio(mu, lam), quotient, rtol=1e-12, atol=1e-15)
    for lam in (0.0, 0.5, 1.5):
        np.testing.assert_array_equal(vs.vsgl_diffuse_emission_ratio(mu, lam), 1.0)
    flat = vs.vsgl_diffuse_emission_ratio(mu, 2.0)
    assert np.all(flat[mu <= 0.0] == 0.0)
    # Lambert's lobe over the SG at λv = 2: 1.17 at 60° from the normal, 0.87 along it, 0.52 at 84°.
    assert vs.vsgl_diffuse_emission_ratio(0.5, 2.0) == pytest.approx(1.1752, rel=1e-3)
    assert vs.vsgl_diffuse_emission_ratio(1.0, 2.0) == pytest.approx(0.8646, rel=1e-3)
    assert vs.vsgl_diffuse_emission_ratio(0.1, 2.0) == pytest.approx(0.5231, rel=1e-3)
    extremes = vs.vsgl_diffuse_emission_ratio(mu[:, None], np.array([0.0, 1e-6, 2.0, 2.0001, 10.0, 1e6])[None, :])
    assert np.all(np.isfinite(extremes)) and np.all(extremes >= 0.0) and np.all(extremes < 200.0)


def mirror_receivers(alpha, elevation):
    """27 glossy specular-only points 0.6 m from 9 targets on the floor patch of ``floor_vpls``, each
    oriented so that its mirror direction of the view hits its target at ``elevation`` above the floor
    (from three azimuths): a sharp receiver looking at a lit floor, as the demo's gold sphere does."""
    points, normals, views = [], [], []
    for tx in (-0.25, 0.0, 0.25):
        for ty in (-0.25, 0.0, 0.25):
            for azimuth in (0.3, 2.0, 4.0):
                up = np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth),
                               np.sin(elevation)])
                view = np.array([np.cos(0.7) * np.cos(azimuth + 0.4), np.cos(0.7) * np.sin(azimuth + 0.4),
                                 np.sin(0.7)])
                normal = view - up
                points.append(np.array([tx, ty, 0.0]) + 0.6 * up)
                normals.append(normal / np.linalg.norm(normal))
                views.append(view)
    count = len(points)
    return (np.array(points), np.array(normals), np.array(views), np.zeros((count, 3)),
            np.full((count, 3), 0.9), np.full(count, alpha))


def test_flat_cluster_specular_sees_lamberts_emission():
    """Sharp receivers looking at the floor patch made diffuse-only (Φ Rd alone), their mirror
    directions meeting it at 14°, 29° and 52° of elevation, α = 0.1, 0.2, 0.4: Eq. 12's product with a
    flat cluster's Lambertian emission at the direction the receiver gathers from is closer to the
    exact VPLs (Lambert emitters, exact GGX receiver) than with 000 Eq. 6's SG, on average over the
    nine cases, per texel and clustered. Measured mean Σ|Δ|/Σ, SG → Lambert: per texel 0.227 → 0.190,
    N = 64 0.296 → 0.280, N = 16 0.445 → 0.426. The SG is better in 6 of 27 cases: by 0.06 per texel
    at 29°, α = 0.1 (the receiver's ASG overestimates there and the SG's deficit hides it), by 0.02-0.03
    clustered at 14° (grazing, where the SG emits more than Lambert), by 0.001 in the last."""
    vpls = floor_vpls()
    vpls = dataclasses.replace(vpls, specular_f0=np.zeros_like(vpls.specular_f0))
    rsm = vpls.rsm()
    tables = {"per texel": vs.per_texel_vsgls(rsm), "N = 64": generate_vsgls(rsm, 64), "N = 16": generate_vsgls(rsm, 16)}
    errors = {name: {"sg": [], "lambert": []} for name in tables}
    for elevation in (0.25, 0.5, 0.9):
        for alpha in (0.1, 0.2, 0.4):
            rec = mirror_receivers(alpha, elevation)
            exact = vs.brute_force_shading(vpls, *rec)[1]
            assert exact.sum() > 0.0
            for name, table in tables.items():
                for emission in ("sg", "lambert"):
                    specular = vs.shade(table, *rec, diffuse_mode="separable", diffuse_emission=emission)[1]
                    assert np.all(np.isfinite(specular)) and np.all(specular >= 0.0)
                    errors[name][emission].append(relative_error(specular, exact))
    for name, pair in errors.items():
        sg_error, lambert_error = np.mean(pair["sg"]), np.mean(pair["lambert"])
        print(f"\n{name}: mean Σ|Δ|/Σ against the exact VPLs, SG {sg_error:.3f}, Lambert {lambert_error:.3f}")
        assert lambert_error < sg_error - 0.01
        assert np.all(np.array(pair["lambert"]) < np.array(pair["sg"]) + 0.07)
