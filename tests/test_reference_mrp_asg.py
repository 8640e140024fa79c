# SPDX-License-Identifier: GPL-3.0-or-later
"""vsgl_addon.reference.mrp_asg (001 Eqs. 6–37, formulas.md §8) against quadrature of Eq. 3 over
one rectangle lit by one light, exact GGX at both ends."""

from __future__ import annotations

import itertools
import math
import types

import numpy as np
import pytest

from vsgl_addon.reference import asg, ggx, mrp_asg as mrp

Z = np.array([0.0, 0.0, 1.0])


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def make_light(kind="POINT", position=(-1.0, 0.2, 1.5), power=1000.0, direction=(0.5, 0.0, -1.0)):
    direction = unit(direction)
    # A spot pointing at the origin, wide enough to cover the peaks used here.
    matrix = np.eye(4)
    if kind in ("SPOT", "AREA"):
        direction = unit(-np.asarray(position))
        z = -direction
        x = unit(np.cross([0.0, 1.0, 0.0], z))
        matrix[:3, :3] = np.stack((x, np.cross(z, x), z), axis=1)
    return types.SimpleNamespace(type=kind, position=np.array(position, float), direction=direction,
                                 power=power, matrix_world=matrix, spot_size=math.radians(120.0),
                                 spot_blend=0.2)


def make_rect(roughness, half=2.0, f0=0.9, center=(0.0, 0.0, 0.0)):
    return dict(center=np.array(center, float), normal=Z.copy(), axis_u=np.array([1.0, 0.0, 0.0]),
                axis_v=np.array([0.0, 1.0, 0.0]), half_u=half, half_v=half, roughness=roughness,
                f0=f0)


def peak_of(position, rect, light):
    if light.type == "SUN":
        return mrp.mrp_peak_distant(position, rect["center"], rect["normal"], -light.direction)
    return mrp.mrp_peak_local(position, rect["center"], rect["normal"], light.position)


def facing_receiver(position, rect, light, tilt=0.3, offset=0.0):
    """A receiver whose mirror direction points at the peak (rotated by ``offset`` about y)."""
    p = np.array(position, float)
    peak, _ = peak_of(p, rect, light)
    w = unit(peak - p)
    n = unit([math.sin(tilt), 0.2, -math.cos(tilt)])
    n = n if np.dot(n, w) > 0 else -n
    o = 2.0 * np.dot(w, n) * n - w
    c, s = math.cos(offset), math.sin(offset)
    return p, n, unit([c * o[0] + s * o[2], o[1], -s * o[0] + c * o[2]])


# --- Specular peak (Eq. 12) ------------------------------------------------------------------------


def test_peak_half_vector_is_the_normal():
    rng = np.random.default_rng(1)
    center = np.array([0.3, -0.2, 0.1])
    normal = unit([0.1, 0.2, 1.0])
    x = center + rng.uniform(-0.5, 0.5, size=(50, 3)) + 2.0 * normal
    light = center + rng.uniform(-0.5, 0.5, size=(50, 3)) + 2.5 * normal
    peak, valid = mrp.mrp_peak_local(x, center, normal, light)
    assert valid.all()
    half = unit(unit(light - peak) + unit(x - peak))
    np.testing.assert_allclose(half, np.broadcast_to(normal, half.shape), atol=1e-12)
    np.testing.assert_allclose((peak - center) @ normal, 0.0, atol=1e-12)
    incoming = unit(rng.normal(size=(50, 3)) * 0.3 + normal)
    peak, valid = mrp.mrp_peak_distant(x, center, normal, incoming)
    assert valid.all()
    half = unit(incoming + unit(x - peak))
    np.testing.assert_allclose(half, np.broadcast_to(normal, half.shape), atol=1e-12)


def test_no_peak_cases():
    # Light behind the plane, receiver behind it, receiver in it, light grazing (i.n = 0).
    x = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.5, 0.0, 0.0], [0.0, 0.0, 1.0]])
    lights = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    peak, valid = mrp.mrp_peak_local(x, np.zeros(3), Z, lights)
    assert not valid.any() and np.isfinite(peak).all()
    incoming = unit([[0.0, 0.0, -1.0], [0.0, 1.0, 1.0], [0.0, 1.0, 1.0], [1.0, 0.0, 0.0]])
    peak, valid = mrp.mrp_peak_distant(x, np.zeros(3), Z, incoming)
    assert not valid.any() and np.isfinite(peak).all()


# --- Radiance at the peak: Blender's units versus 001 Eq. 17 ---------------------------------------


@pytest.mark.parametrize("kind", ["POINT", "SPOT", "AREA", "SUN"])
def test_peak_radiance_units_by_quadrature(kind):
    """The solid-angle integral C (Eq. 13) of a sharp reflector's radiance over R, by quadrature,
    against the disk integral A·E from L_y in Blender's form and in 001 Eq. 17's form: Blender's
    matches within 3 % (a disk larger than the highlight), Eq. 17 is off by orders of magnitude
    (it has no light intensity)."""
    light = make_light(kind)
    rect = make_rect(0.02, half=20.0)
    x = np.array([1.0, 0.0, 0.8])
    truth = mrp.brute_force_rectangle(x, -Z, Z, 0.5, 0.9, rect, light, receiver_brdf=False)
    peak, valid = peak_of(x, rect, light)
    assert valid
    irradiance, incoming, light_distance = mrp.light_irradiance_at(light, peak)
    cos_sigma = float(incoming @ Z)
    d = float(np.linalg.norm(peak - x))
    spread = 1.0 + d / light_distance
    disk = mrp.mrp_disk_integral(cos_sigma, 0.02, 1.0 / d, spread)
    blender = disk * mrp.mrp_peak_radiance(cos_sigma, 0.02, 0.9, irradiance)
    paper = disk * mrp.mrp_peak_radiance_paper(cos_sigma, 0.02, 0.9)
    assert truth > 0.0
    assert abs(blender / truth - 1.0) < 0.03
    assert not 0.1 < paper / truth < 10.0


# --- Disk integral (Eqs. 25–27) --------------------------------------------------------------------


def test_disk_integral_closed_form_matches_its_integral():
    """π/k (1 − e^(−kt)) is 2π ∫_0^α e^(−k sin²θ) cos θ sin θ dθ with sin²α = t (Eq. 26), for
    k > 0, k → 0 and k < 0."""
    theta_nodes, weights = np.polynomial.legendre.leggauss(200)
    for cos_sigma, roughness, extent in itertools.product((1.0, 0.6, 0.05), (0.02, 0.3, 0.8, 1.0),
                                                          (1e-3, 0.3, 3.0)):
        got = mrp.mrp_disk_integral(cos_sigma, roughness, extent, fit="paper")
        k = mrp.K_SLOPE * cos_sigma / roughness ** 2 - mrp.K_OFFSET
        q = extent ** 2 * cos_sigma ** 2
        alpha = math.asin(math.sqrt(q / (1.0 + q)))
        theta = 0.5 * alpha * (theta_nodes + 1.0)
        integrand = np.exp(-k * np.sin(theta) ** 2) * np.cos(theta) * np.sin(theta)
        expected = 2.0 * math.pi * 0.5 * alpha * np.sum(weights * integrand)
        np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-300)


def test_disk_integral_finite_at_k_zero_and_negative():
    # k = 0 exactly: 0.288 c / m² = 0.673.
    roughness = math.sqrt(0.288 / 0.673)
    t = mrp.mrp_disk_integral(1.0, roughness, 2.0, fit="paper")
    np.testing.assert_allclose(t, math.pi * 4.0 / 5.0, rtol=1e-9)
    for fit in mrp.K_FITS:
        values = mrp.mrp_disk_integral(np.linspace(0.0, 1.0, 11)[:, None], np.array([1e-3, 0.5, 1.0]),
                                       np.array([[0.0], [1e-6], [1e6]])[..., None], 3.0, fit)
        assert np.isfinite(values).all() and (values >= 0.0).all()


def test_lobe_extent_is_where_the_disk_integrand_falls_to_1_over_e():
    """At ρ_lobe the disk integral's integrand e^(−k t) is 1/e (k t = 1) for every k > 1, and the
    disk of DISK_LOBE_SCALE footprints holds most of the lobe: E(ρ)/E(∞) = (1 − e^(−kt))/(1 − e^(−k))."""
    for cos_sigma, roughness, spread in itertools.product((1.0, 0.6, 0.2), (0.005, 0.02, 0.05, 0.1), (1.0, 2.0)):
        extent = float(mrp.mrp_lobe_extent(cos_sigma, roughness, spread))
        k = (1.0 / (4.0 * roughness ** 2 * cos_sigma) - mrp.K_OFFSET) * spread ** 2
        q = extent ** 2 * cos_sigma ** 2
        np.testing.assert_allclose(k * q / (1.0 + q), 1.0, rtol=1e-9)
        scaled = mrp.DISK_LOBE_SCALE * extent
        share = (mrp.mrp_disk_integral(cos_sigma, roughness, scaled, spread)
                 / mrp.mrp_disk_integral(cos_sigma, roughness, mrp.EXTENT_MAX, spread))
        assert 0.85 < share < 1.0
    # A lobe wider than the hemisphere (k <= 1) has no footprint: the largest extent.
    assert mrp.mrp_lobe_extent(1.0, 1.0) == mrp.EXTENT_MAX


@pytest.mark.parametrize("distance, sigma", [(3.0, 30.0), (1.0, 80.0)])
def test_lobe_disk_keeps_the_highlight_a_fixed_disk_loses(distance, sigma):
    """A far receiver and grazing light (16 receivers each, r_d 0.1 m): the fixed disk (001) loses
    half the light or more (relative RMSE 0.52 and 0.59 against the quadrature of Eq. 3, means 0.48
    and 0.41); the disk of at least DISK_LOBE_SCALE lobe footprints keeps most of it (0.04 and
    0.27, means 0.96 and 0.74)."""
    s = math.radians(sigma)
    rect = make_rect(0.05)
    light = make_light("POINT", position=2.0 * np.array([-math.sin(s), 0.0, math.cos(s)]))
    rng = np.random.default_rng(5)
    mirror = np.array([math.sin(s), 0.0, math.cos(s)])
    truth, fixed, lobe = [], [], []
    for _ in range(16):
        p = distance * mirror + rng.uniform(-0.1, 0.1, 3) * distance
        p[2] = max(p[2], 0.02 * distance)
        x, n, o = facing_receiver(p, rect, light)
        truth.append(mrp.brute_force_rectangle(x, n, o, 0.2, 0.9, rect, light))
        fixed.append(float(mrp.mrp_shade(x, n, o, 0.2, 0.9, rect, light, 0.1, disk="fixed")))
        lobe.append(float(mrp.mrp_shade(x, n, o, 0.2, 0.9, rect, light, 0.1)))
    truth, fixed, lobe = np.array(truth), np.array(fixed), np.array(lobe)

    def rel_rmse(values):
        return float(np.sqrt(np.mean((values - truth) ** 2)) / np.mean(truth))

    assert rel_rmse(fixed) > 0.5 and fixed.mean() < 0.5 * truth.mean()
    assert rel_rmse(lobe) < 0.6 * rel_rmse(fixed) and 0.7 < lobe.mean() / truth.mean() < 1.25


# --- Area ratio (Eq. 36) ---------------------------------------------------------------------------


def _intersection_area(x0, y0, a, b, r, samples=400_000, seed=3):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-1.0, 1.0, size=(samples, 2)) * r
    inside = (np.hypot(p[:, 0], p[:, 1]) <= r) & (np.abs(p[:, 0] + x0) <= a) & (np.abs(p[:, 1] + y0) <= b)
    return 4.0 * r * r * inside.mean()


def test_area_ratio():
    c = np.zeros(3)
    u, v = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    # Disk inside: 1 ("square"), 4/π (Eq. 36 as printed). Half disk: 1/2 exactly. Outside: 0.
    assert mrp.mrp_area_ratio([0.1, 0, 0], c, u, v, 1.0, 1.0, 0.3) == pytest.approx(1.0)
    assert mrp.mrp_area_ratio([0.1, 0, 0], c, u, v, 1.0, 1.0, 0.3, "paper") == pytest.approx(4 / math.pi)
    assert mrp.mrp_area_ratio([1.0, 0, 0], c, u, v, 1.0, 1.0, 0.3) == pytest.approx(0.5)
    assert mrp.mrp_area_ratio([1.31, 0, 0], c, u, v, 1.0, 1.0, 0.3) == 0.0
    assert mrp.mrp_area_ratio([1.25, 1.25, 0], c, u, v, 1.0, 1.0, 0.3) == 0.0  # corner, no overlap
    # J bounds I: between the true ratio S_I/(π r²) and S_I·... at a corner.
    for x0, y0 in ((1.0, 1.0), (0.9, 1.1), (1.1, 0.95)):
        true = _intersection_area(x0, y0, 1.0, 1.0, 0.3) / (math.pi * 0.09)
        got = mrp.mrp_area_ratio([x0, y0, 0], c, u, v, 1.0, 1.0, 0.3, "paper")
        assert got >= true - 0.01
    assert np.isfinite(mrp.mrp_area_ratio([0, 0, 0], c, u, v, 1.0, 1.0, 0.0))


# --- ASG light (Eqs. 18, 28–35) --------------------------------------------------------------------


def test_bandwidth_meets_epsilon_at_the_extent():
    """Eq. 31: the ASG drops to ε = 0.05 at θ = arctan(l) along its axis."""
    for l in (0.01, 0.1, 0.5, 1.0, 5.0, 15.0):
        lam = mrp.mrp_bandwidth(l)
        theta = math.atan(l)
        value = math.cos(theta) * math.exp(-lam * math.sin(theta) ** 2)
        assert value == pytest.approx(0.05, rel=2e-3)
    wide = mrp.mrp_bandwidth(np.array([0.0, 1e-9, 30.0, 1e6, np.inf]))
    assert np.isfinite(wide).all() and (wide >= mrp.BANDWIDTH_FLOOR).all()


def test_asg_frame_and_amplitude():
    rng = np.random.default_rng(5)
    normal = unit([0.1, -0.2, 1.0])
    x = rng.normal(size=(40, 3)) + 2.0 * normal
    peak = rng.normal(size=(40, 3)) * 0.5
    peak -= (peak @ normal)[:, None] * normal
    m, n, z, d, cos_n = mrp.mrp_asg_frame(x, peak, normal)
    for a, b in ((m, n), (n, z), (z, m)):
        np.testing.assert_allclose(np.sum(a * b, -1), 0.0, atol=1e-12)
    np.testing.assert_allclose(z, unit(peak - x), atol=1e-12)
    np.testing.assert_allclose(m @ normal, 0.0, atol=1e-12)  # m = v lies in R's plane
    np.testing.assert_allclose(cos_n, unit(x - peak) @ normal, atol=1e-12)
    # Normal incidence and the receiver at the peak: still a unit frame.
    m, n, z, d, _ = mrp.mrp_asg_frame(np.array([[0, 0, 1.0], [0, 0, 0.0]]), np.zeros((2, 3)), Z)
    assert np.isfinite(m).all() and np.allclose(np.linalg.norm(m, axis=-1), 1.0)
    # Eq. 35: the ASG's (Eq. 34) integral is C.
    lam, mu = mrp.mrp_bandwidth(0.2), mrp.mrp_bandwidth(0.1)
    amplitude = math.sqrt(lam * mu) / math.pi * 7.0
    assert asg.asg_integral(lam, mu, amplitude) == pytest.approx(7.0)


def test_receiver_terms_match_ggx_at_the_mirror_direction():
    """M (−r·n_x) · SG amplitude at its axis is GGX f·cos at the mirror direction (Eqs. 6, 8, 10)."""
    normal = unit([0.2, 0.1, 1.0])
    for theta, alpha in itertools.product((0.0, 0.5, 1.2), (1e-3, 0.1, 0.7, 1.0)):
        view = unit(np.cos(theta) * normal + np.sin(theta) * unit(np.cross(normal, [0, 1.0, 0])))
        axis, sharpness, amplitude = mrp.mrp_receiver_sg(view, normal, alpha)
        expected = ggx.microfacet_brdf(axis, view, normal, alpha, 0.04) * (axis @ normal)
        got = mrp.mrp_receiver_factor(axis, view, normal, alpha, 0.04) * amplitude
        np.testing.assert_allclose(got, expected, rtol=1e-9)
        assert sharpness == pytest.approx(2.0 / alpha ** 2 / (4.0 * max(abs(view @ normal), 1e-4)))


# --- The whole of Eq. 3 ----------------------------------------------------------------------------


def test_brute_force_rectangle_against_monte_carlo():
    """The refined quadrature of Eq. 3 against plain Monte Carlo on R (rough ends, where MC
    converges)."""
    light = make_light("POINT")
    rect = make_rect(0.4, half=1.0)
    x, n, o = facing_receiver([1.0, 0.0, 0.8], rect, light)
    truth = mrp.brute_force_rectangle(x, n, o, 0.5, 0.9, rect, light)
    rng = np.random.default_rng(7)
    uv = rng.uniform(-1.0, 1.0, size=(400_000, 2))
    y = uv[:, :1] * rect["axis_u"] + uv[:, 1:] * rect["axis_v"]
    r = unit(x - y)
    dist = np.linalg.norm(x - y, axis=-1)
    irradiance, incoming, _ = mrp.light_irradiance_at(light, y)
    f_r = ggx.microfacet_brdf(incoming, r, Z, 0.4, 0.9)
    f_x = ggx.microfacet_brdf(-r, o, n, 0.5, 0.9)
    values = (f_r * np.maximum(incoming @ Z, 0) * irradiance * f_x * np.maximum(-r @ n, 0)
              * np.maximum(r @ Z, 0) / dist ** 2) * 4.0
    mc, err = values.mean(), values.std() / math.sqrt(len(values))
    assert abs(mc - truth) < 4.0 * err + 1e-3 * truth


CASES = [  # (reflector α, receiver α, disk radius, light), MRP-ASG / truth must lie in the band
    (0.02, 0.2, 0.1, "POINT"), (0.02, 0.5, 0.2, "SPOT"), (0.05, 0.2, 0.2, "SUN"),
    (0.1, 0.5, 0.3, "POINT"), (0.02, 0.05, 0.05, "AREA"),
]


@pytest.mark.parametrize("alpha_r, alpha_x, radius, kind", CASES)
def test_mrp_asg_against_eq3(alpha_r, alpha_x, radius, kind):
    """Within the accuracy the paper's approximations allow (a factor 1.5 either way where the disk
    suits the highlight; docs/accuracy.md has the table), and Eq. 17's units off by > 100×."""
    light = make_light(kind)
    rect = make_rect(alpha_r)
    x, n, o = facing_receiver([1.0, 0.0, 0.8], rect, light)
    truth = mrp.brute_force_rectangle(x, n, o, alpha_x, 0.9, rect, light)
    got = float(mrp.mrp_shade(x, n, o, alpha_x, 0.9, rect, light, radius))
    sg_mode = float(mrp.mrp_shade(x, n, o, alpha_x, 0.9, rect, light, radius, mode="sg"))
    paper_units = float(mrp.mrp_shade(x, n, o, alpha_x, 0.9, rect, light, radius, peak_form="paper"))
    assert 1 / 1.5 < got / truth < 1.5
    assert 1 / 2.0 < sg_mode / truth < 2.0
    assert paper_units / truth < 0.01


def test_shadowed_peak_is_dark():
    light = make_light("POINT")
    rect = make_rect(0.05)
    x, n, o = facing_receiver([1.0, 0.0, 0.8], rect, light)
    assert float(mrp.mrp_shade(x, n, o, 0.2, 0.9, rect, light, 0.2, visibility=0.0)) == 0.0


def test_extremes_are_finite():
    """r_d → 0 and huge, α = 1e-3 and 1, σ → 90°, peaks on the edge and outside (A → 0), the
    receiver in the proxy's plane and behind it, grazing views: no NaN, no Inf, never negative."""
    rng = np.random.default_rng(11)
    count = 4000
    positions = rng.uniform(-3.0, 3.0, size=(count, 3))
    positions[:200, 2] = 0.0  # in the plane
    positions[200:400, 2] = rng.uniform(-1e-7, 1e-7, 200)
    normals = unit(rng.normal(size=(count, 3)))
    views = unit(rng.normal(size=(count, 3)))
    views[400:600] = unit(np.cross(normals[400:600], [0.3, 0.1, 1.0]))  # grazing
    for kind, alpha_r, alpha_x, radius, mode in itertools.product(
            ("POINT", "SUN"), (1e-3, 1.0), (1e-3, 1.0), (0.0, 1e-6, 1e6), mrp.MODES):
        light = make_light(kind, position=(-1.0, 0.2, 1e-6) if alpha_r == 1.0 else (-1.0, 0.2, 1.5),
                           direction=(1.0, 0.0, -1e-7))  # σ → 90° for the sun
        rect = make_rect(alpha_r, half=1.0)
        value = mrp.mrp_shade(positions, normals, views, alpha_x, 0.9, rect, light, radius, mode=mode)
        assert np.isfinite(value).all() and (value >= 0.0).all(), (kind, alpha_r, alpha_x, radius, mode)
        if mode == "asg":
            value = mrp.mrp_shade(positions, normals, views, alpha_x, 0.9, rect, light, radius, receiver="quadrature")
            assert np.isfinite(value).all() and (value >= 0.0).all(), (kind, alpha_r, alpha_x, radius, "quadrature")


def test_receiver_ndf_lobes_keep_peak_and_integral_and_fit_ggx():
    """RECEIVER_NDF_LOBES: weights summing to 1 (D(0) = 1/πα²), Σ w/c = 1 (∫ D cos dω = 1 as Eq. 8's
    single SG), and in u = θ/α a squared error against GGX's (1 + u²)⁻² under 1/20 of the single SG's."""
    lobes = mrp.RECEIVER_NDF_LOBES
    assert sum(w for w, _ in lobes) == pytest.approx(1.0, abs=1e-12)
    assert sum(w / c for w, c in lobes) == pytest.approx(1.0, abs=1e-12)
    u = np.linspace(0.0, 15.0, 6001)
    ggx_shape = (1.0 + u * u) ** -2.0
    two = sum(w * np.exp(-c * u * u) for w, c in lobes)
    one = np.exp(-u * u)
    assert np.sum((two - ggx_shape) ** 2 * u) < np.sum((one - ggx_shape) ** 2 * u) / 20.0
    # And the NDF itself: 1/(πα²) Σ w e^(-c λ_h (1 - cos θ)) against GGX at α 0.05 within 3 % of the
    # peak everywhere (the single SG is off by 10 %).
    alpha = 0.05
    theta = np.linspace(0.0, 0.5, 2001)
    exact = alpha ** 2 / (np.pi * (np.cos(theta) ** 2 * (alpha ** 2 - 1.0) + 1.0) ** 2)
    lam = 2.0 / alpha ** 2
    approx = sum(w * np.exp(-c * lam * (1.0 - np.cos(theta))) for w, c in lobes) / (np.pi * alpha ** 2)
    single = np.exp(-lam * (1.0 - np.cos(theta))) / (np.pi * alpha ** 2)
    peak = 1.0 / (np.pi * alpha ** 2)
    assert np.max(np.abs(approx - exact)) < 0.03 * peak < np.max(np.abs(single - exact)) * 0.3


def test_gaussian_lobes_integral_is_eq11_for_an_sg():
    """With one lobe isotropic (an SG of sharpness λ, η = λ/2 about its axis) the tangent-plane
    integral is Eq. 11's SG × ASG convolution (asg.sg_asg_convolution) near the axes."""
    z = unit([0.1, -0.2, 1.0])
    m = unit(np.cross(z, [1.0, 0.0, 0.0]))
    n = np.cross(z, m)
    p = unit(z + 0.02 * m - 0.01 * n)
    tp = asg.asg_any_tangent(p)
    lam = 400.0
    value, _ = mrp.gaussian_lobes_integral(z, [(tp, np.cross(p, tp), lam / 2.0, lam / 2.0), (m, n, 900.0, 300.0)])
    expected = asg.sg_asg_convolution(p, lam, m, n, z, 900.0, 300.0)
    assert value == pytest.approx(float(expected), rel=2e-3)


@pytest.mark.parametrize("alpha_x", [0.05, 0.09])
def test_asg_receiver_closer_to_quadrature_at_grazing_views(alpha_x):
    """Receivers at o·n ≈ 0.3 looking up to ~2 α off the mirror direction of the peak (a sphere's
    flank, as the demo's gold sphere): the receiver's NDF warped as 003's ASG has less squared error
    against quadrature of Eq. 3 than Eq. 8's isotropic warp (2.9× and 2.0× in
    benchmarks/results/mrp_asg_stages.md's configuration)."""
    rng = np.random.default_rng(3)
    rect, light = make_rect(0.05), make_light("POINT", position=(-1.0, 0.0, 1.7))
    truth, sg_mode, asg_mode = [], [], []
    for _ in range(12):
        p = np.array([0.5, 0.0, 0.87]) + rng.uniform(-0.1, 0.1, 3)
        peak, _ = peak_of(p, rect, light)
        w = unit(peak - p)
        side = unit(np.cross(w, Z))
        n = unit(0.3 * w + 0.95 * side)
        o = unit(2.0 * (w @ n) * n - w + rng.normal(size=3) * 1.5 * alpha_x)
        if o @ n < 0.05:
            continue
        truth.append(mrp.brute_force_rectangle(p, n, o, alpha_x, 0.9, rect, light, order=8, smallest=1e-3))
        sg_mode.append(float(mrp.mrp_shade(p, n, o, alpha_x, 0.9, rect, light, 0.1, receiver="sg")))
        asg_mode.append(float(mrp.mrp_shade(p, n, o, alpha_x, 0.9, rect, light, 0.1, receiver="asg")))
    truth, sg_mode, asg_mode = map(np.array, (truth, sg_mode, asg_mode))
    assert len(truth) >= 8 and truth.max() > 0.0
    assert np.sum((asg_mode - truth) ** 2) < 0.7 * np.sum((sg_mode - truth) ** 2)
    assert np.isfinite(asg_mode).all()


def _asg_against_exact_receiver(light, position, normal, view, alpha, f0, size=801):
    """∫ Ga(ω) f_x(ω, o) ⟨ω, n_x⟩ dω by a dense tangent-plane grid around the narrower lobe (the
    ASG's axis, 6/√λ_min wide, or the receiver's mirror direction, 12 α/√(o·n) wide; at most 1.5)."""
    lam, mu = float(light["bandwidth_m"]), float(light["bandwidth_n"])
    asg_half = 6.0 / math.sqrt(max(min(lam, mu), 1e-6))
    cos_o = max(float(view @ normal), 1e-3)
    receiver_half = 12.0 * alpha / math.sqrt(cos_o)
    if asg_half <= receiver_half:
        axis, half = light["z"], asg_half
    else:
        axis, half = unit(2.0 * cos_o * normal - view), receiver_half
    t1 = asg.asg_any_tangent(axis)
    t2 = np.cross(axis, t1)
    t = np.linspace(-min(half, 1.5), min(half, 1.5), size)
    a, b = np.meshgrid(t, t, indexing="ij")
    w = axis + a[..., None] * t1 + b[..., None] * t2
    length = np.linalg.norm(w, axis=-1)
    w = w / length[..., None]
    value = (float(light["amplitude"]) * asg.asg_evaluate(w, light["m"], light["n"], light["z"], lam, mu)
             * ggx.microfacet_brdf(w, np.broadcast_to(view, w.shape), np.broadcast_to(normal, w.shape), alpha, f0)
             * np.maximum(w @ normal, 0.0))
    return float(np.sum(value * (t[1] - t[0]) ** 2 / length ** 3))


@pytest.mark.parametrize("alpha_x, tilt, spread", [(0.09, "grazing", 1.5), (0.2, "grazing", 1.5),
                                                   (0.2, "facing", 0.05), (0.05, "facing", 0.05)])
def test_receiver_quadrature_against_a_dense_grid(alpha_x, tilt, spread):
    """mrp_receiver_quadrature (4 × 4 Gauss–Hermite nodes on the ASG light, 3 × 4 on the GGX lobe,
    balance heuristic) against a dense grid of the same integral. On a sphere's flank (views at
    o·n ≈ 0.3, up to 1.5 α off the peak's mirror direction, as the demo's gold sphere) 0.06 / 0.11
    relative RMSE at α 0.09 / 0.2, where Eq. 8's isotropic SG receiver with Eq. 11 is 0.59 / 1.11
    off; facing the peak (views within 0.05 α of the mirror direction) 0.015 / 0.036 at α 0.05 / 0.2,
    where Eq. 11 is 0.022 / 0.005. Finite and ≥ 0 throughout."""
    rng = np.random.default_rng(3)
    rect, light = make_rect(0.05), make_light("POINT", position=(-1.0, 0.0, 1.7))
    exact, quad, eq11 = [], [], []
    while len(exact) < 10:
        p = np.array([0.5, 0.0, 0.87]) + rng.uniform(-0.1, 0.1, 3)
        peak, _ = peak_of(p, rect, light)
        w = unit(peak - p)
        if tilt == "grazing":
            n = unit(0.3 * w + 0.95 * unit(np.cross(w, Z)))
        else:
            n = unit(w + 0.6 * unit([0.3, 0.2, 0.5]))
        o = unit(2.0 * (w @ n) * n - w + rng.normal(size=3) * spread * alpha_x)
        if o @ n < 0.05:
            continue
        a = mrp.mrp_asg_light(p, rect, light, 0.1)
        args = (a["m"], a["n"], a["z"], a["bandwidth_m"], a["bandwidth_n"], a["amplitude"])
        exact.append(_asg_against_exact_receiver(a, p, n, o, alpha_x, 0.9))
        quad.append(float(mrp.mrp_receiver_quadrature(o, n, alpha_x, 0.9, *args)))
        eq11.append(float(mrp.mrp_convolve(o, n, alpha_x, *args) * mrp.mrp_receiver_factor(a["z"], o, n, alpha_x, 0.9)))
    exact, quad, eq11 = map(np.array, (exact, quad, eq11))

    def rel_rmse(values):
        return float(np.sqrt(np.mean((values - exact) ** 2)) / np.mean(exact))

    assert np.isfinite(quad).all() and (quad >= 0.0).all()
    if tilt == "grazing":
        assert rel_rmse(quad) < 0.15 and rel_rmse(quad) < 0.2 * rel_rmse(eq11)
    else:
        assert rel_rmse(quad) < 0.05 and rel_rmse(eq11) < 0.03
    # The same through mrp_shade (its receiver option), which adds nothing but the validity mask.
    x, n, o = facing_receiver([1.0, 0.0, 0.8], rect, light)
    a = mrp.mrp_asg_light(x, rect, light, 0.1)
    assert float(mrp.mrp_shade(x, n, o, alpha_x, 0.9, rect, light, 0.1, receiver="quadrature")) == pytest.approx(
        float(mrp.mrp_receiver_quadrature(o, n, alpha_x, 0.9, a["m"], a["n"], a["z"], a["bandwidth_m"],
                                          a["bandwidth_n"], a["amplitude"])), rel=1e-12)
