"""glsl/lib/principled.glsl against its float64 twin vsgl_addon/reference/principled.py, and the
reference's own properties (Fresnel limits, albedo quadrature against a fine one)."""

from __future__ import annotations

import numpy as np
import pytest

from vsgl_addon.reference import principled as P

from glsl_harness import Accuracy, as_gpu_floats, evaluate_glsl

ROUGHNESS = [1e-3, 0.05, 0.3, 0.6, 1.0]


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_fresnel_limits_and_f0():
    f0 = P.principled_dielectric_f0(1.5, 0.5)
    assert f0 == pytest.approx(0.04)
    assert P.principled_dielectric_f0(1.5, 0.0) == 0.0
    c = np.array([0.0, 1e-6, 0.5, 1.0])
    f = P.fresnel_dielectric_f0(c, f0)
    assert f[0] == pytest.approx(1.0) and f[-1] == pytest.approx(0.04)
    assert np.all(P.fresnel_dielectric_f0(c, 0.0) == 0.0)
    # Exact Fresnel of glass at 60 degrees: Rs 0.177, Rp 0.0017 -> 0.0894.
    assert P.fresnel_dielectric_f0(0.5, f0) == pytest.approx(0.0894, abs=5e-4)


def test_albedo_quadrature_converges():
    mu = np.array([0.1, 0.3, 0.6, 1.0])
    for r in ROUGHNESS:
        rough = np.full(4, r)
        coarse = P.principled_directional_albedos(mu, rough, 0.04, np.array([0.9, 0.5, 0.1]))
        fine = P.principled_directional_albedos(mu, rough, 0.04, np.array([0.9, 0.5, 0.1]), samples=48)
        # The dielectric albedo (what scales the diffuse layer) to 0.01 absolute.
        np.testing.assert_allclose(coarse[1], fine[1], atol=0.01)
        np.testing.assert_allclose(coarse[0], fine[0], atol=0.06)


def _grid():
    rng = np.random.default_rng(7)
    rows = []
    for r in ROUGHNESS:
        for metallic in (0.0, 0.4, 1.0):
            for k in range(40):
                n = _unit(rng.normal(size=3))
                wo = _unit(rng.normal(size=3))
                wi = _unit(rng.normal(size=3))
                wo = wo if wo @ n > 0 else -wo
                wi = wi if wi @ n > 0 else -wi
                if k == 0:  # grazing light, exactly in the surface plane
                    t = _unit(np.cross(n, rng.normal(size=3)))
                    wi = t
                if k == 1:  # grazing view
                    wo = _unit(np.cross(n, rng.normal(size=3)) + 1e-3 * n)
                if k == 2:  # light below the surface
                    wi = -wi
                rows.append((n, wi, wo, r, metallic))
    n, wi, wo, r, m = (np.array(x) for x in zip(*rows))
    return {"normal": n, "incoming": wi, "outgoing": wo, "roughness": r, "metallic": m}


@pytest.mark.gpu
def test_principled_glsl_matches_numpy():
    inputs = _grid()
    count = len(inputs["roughness"])
    rng = np.random.default_rng(3)
    inputs["base"] = rng.uniform(0.0, 1.0, size=(count, 3))
    inputs["params"] = np.c_[rng.uniform(0.0, 1.0, count), rng.uniform(1.0, 2.5, count)]  # level, ior
    gpu_in = {k: as_gpu_floats(v) for k, v in inputs.items()}
    body = """
PrincipledTerms t = principled_terms(base, metallic, params.x, params.y, roughness, dot(normal, outgoing));
vec3 d, s;
principled_brdf(t, incoming, outgoing, normal, d, s);
diffuse = d;
specular = s;
rd = t.diffuse;
albedo = t.specular_albedo;
"""
    out = evaluate_glsl(body, gpu_in, {"diffuse": 3, "specular": 3, "rd": 3, "albedo": 3},
                        libraries=["lib/principled.glsl"])
    mu_o = np.sum(gpu_in["normal"] * gpu_in["outgoing"], axis=-1)
    terms = P.principled_terms(gpu_in["base"], gpu_in["metallic"], gpu_in["params"][:, 0],
                             gpu_in["params"][:, 1], gpu_in["roughness"], mu_o)
    diffuse, specular = P.principled_brdf(gpu_in["incoming"], gpu_in["outgoing"], gpu_in["normal"],
                                          gpu_in["base"], gpu_in["roughness"], gpu_in["metallic"],
                                          gpu_in["params"][:, 0], gpu_in["params"][:, 1])
    for name, reference in (("rd", terms["diffuse"]), ("albedo", terms["specular_albedo"]),
                            ("diffuse", diffuse), ("specular", specular)):
        assert np.all(np.isfinite(out[name])), name
        accuracy = Accuracy(out[name], reference, groups=gpu_in["roughness"], relative=5e-3,
                            absolute=1e-5)
        print(name, accuracy.summary())
        assert accuracy.ok, f"{name}: " + accuracy.report()


@pytest.mark.gpu
def test_principled_no_nan_at_extremes():
    n = np.tile([0.0, 0.0, 1.0], (6, 1))
    wi = np.array([[0, 0, 1], [1, 0, 0], [0, 0, -1], [0.6, 0, 0.8], [-0.6, 0, 0.8], [0, 1, 0]], float)
    wo = np.array([[0, 0, 1], [0, 0, 1], [0, 0, 1], [-0.6, 0, 0.8], [0.6, 0, 0.8], [0, -1, 0]], float)
    for r in (0.0, 1e-3, 1.0):
        out = evaluate_glsl(
            "PrincipledTerms t = principled_terms(vec3(0.8), 0.5, 0.5, 1.45, rough, dot(normal, wo));\n"
            "vec3 d, s; principled_brdf(t, wi, wo, normal, d, s); result = vec4(d.x, s.x, t.diffuse.x, t.specular_albedo.x);",
            {"normal": n, "wi": wi, "wo": wo, "rough": np.full(6, r)}, 4,
            libraries=["lib/principled.glsl"])
        assert np.all(np.isfinite(out)), (r, out)


@pytest.mark.gpu
@pytest.mark.parametrize("material", ["glossy", "metal", "rough_level"])
def test_colour_passes_match_cycles(material):
    """What Cycles' Principled BSDF does, measured: Diffuse Color = base (1 − metallic)(1 − E_spec(μo))
    (the dielectric layer's albedo towards the viewer) and Glossy Color = the specular lobes'
    albedo, per pixel of a plane seen at varying angles."""
    import scene_builders as sb
    from cycles_truth import render_cycles
    from test_direct_light import render_ours

    settings = {"glossy": dict(roughness=0.3, metallic=0.0, specular_ior_level=0.5, ior=1.5),
                "metal": dict(roughness=0.4, metallic=1.0, specular_ior_level=0.5, ior=1.5),
                "rough_level": dict(roughness=0.7, metallic=0.3, specular_ior_level=0.9, ior=1.33)}[material]
    sb.reset()
    sb.plane(size=12, material=sb.principled("M", base_color=(0.8, 0.5, 0.2), **settings))
    sb.point_light(power=500, location=(0, 0, 2))
    sb.camera(location=(0, -4, 1.2), look_at_point=(0, 0, 0), resolution=(64, 48))
    _, _, arrays, camera, scene, _ = render_ours()
    passes = render_cycles(samples=4, filter_width=0.01)
    coverage = arrays["position"][..., 3] > 0.5
    p = arrays["position"][..., :3].astype(np.float64)
    n = arrays["normal"][..., :3].astype(np.float64)
    towards = camera[:3] - p
    mu = np.sum(n * towards, axis=-1) / np.linalg.norm(towards, axis=-1)
    m = scene.materials[1]
    terms = P.principled_terms(np.broadcast_to(m.base_color, p.shape), m.metallic, m.specular_ior_level,
                             m.ior, m.roughness, mu)
    diffuse_colour = passes["DiffCol"][::-1][coverage]
    glossy_colour = passes["GlossCol"][::-1][coverage]
    lines = [f"{material}: mu_o {mu[coverage].min():.2f}..{mu[coverage].max():.2f}"]
    if settings["metallic"] < 1.0:
        rel = np.abs(terms["diffuse"][coverage] - diffuse_colour) / diffuse_colour
        lines.append(f"  Diffuse Color: mean rel err {rel.mean():.4f}, max {rel.max():.4f} "
                     f"(without the layering, base (1 - m): "
                     f"{np.mean(np.abs(np.asarray(m.base_color) * (1 - m.metallic) - diffuse_colour) / diffuse_colour):.4f})")
        assert rel.mean() < 0.01 and rel.max() < 0.03, lines
    rel = np.abs(terms["specular_albedo"][coverage] - glossy_colour) / glossy_colour
    lines.append(f"  Glossy Color: mean rel err {rel.mean():.4f}, max {rel.max():.4f}")
    print("\n".join(lines))
    assert rel.mean() < 0.05, lines
