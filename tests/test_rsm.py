"""Reflective shadow maps on the GPU (vsgl_addon/passes/rsm.py).

Scenes are built as plain SceneDescriptions in numpy (fast, exact geometry); one test goes through
Blender (scene_builders + extract_scene) to check the units of the extraction meet the pass's.

Flux calibration resolution. The RSM total differs from the analytic power only through coverage
at the plane's silhouette (a texel counts fully or not at all, decided at its centre) and the cos³
midpoint rule per texel (relative error ~ texel size² / 24, below 1e-5 at 256²). Silhouette
errors have zero mean along a straight edge and are bounded by the flux of one texel row along it:
at 256² per face the planes below put under 0.2 % of their flux in silhouette texels, so the 1 %
bound holds with a wide margin (measured errors are printed with -s and listed in the report).

Reflectances. The RSM's Rd and Rs are the Principled model of the direct light for each texel's
incidence (reference/rsm.py principled_reflectances); the flux calibration scenes use a Specular
IOR Level of 0 (no dielectric layer), whose Rd is the base colour exactly in that model
(test_calibration_material_rd_is_its_base_colour), so Σ Φ·Rd / Rd measures the flux alone. The
incidence dependence is tested texel by texel against the numpy model
(test_reflectances_follow_the_incidence) and against Cycles' colour passes seen from the light
(test_reflectances_are_cycles_colour_passes_seen_from_the_light).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from vsgl_addon import views as V
from vsgl_addon.passes import rsm as R
from vsgl_addon.reference import lights
from vsgl_addon.reference import rsm as ref
from vsgl_addon.reference.image import image_sample_linear_repeat
from vsgl_addon.reference.vsgl import RSM, luminance
from vsgl_addon.scene_description import (
    DEFAULT_MATERIAL,
    Camera,
    Geometry,
    Light,
    Material,
    SceneDescription,
)

CALIBRATION_SIZE = 256


# --- Scene helpers -----------------------------------------------------------------------------


def quad_triangles(corners) -> np.ndarray:
    p = np.asarray(corners, np.float64)
    return np.array([[p[0], p[1], p[2]], [p[0], p[2], p[3]]])


def rectangle(half_x, half_y=None, z=0.0, centre=(0.0, 0.0)) -> np.ndarray:
    """Two triangles of an axis-aligned rectangle in the plane z, facing +Z."""
    half_y = half_x if half_y is None else half_y
    cx, cy = centre
    return quad_triangles([(cx - half_x, cy - half_y, z), (cx + half_x, cy - half_y, z),
                           (cx + half_x, cy + half_y, z), (cx - half_x, cy + half_y, z)])


def geometry(triangle_sets, materials=None, normals=None) -> Geometry:
    """Geometry from lists of (k, 3, 3) triangles; flat normals unless ``normals`` are given."""
    tris = np.concatenate([np.asarray(t, np.float64) for t in triangle_sets]).astype(np.float32)
    count = len(tris)
    if normals is None:
        face = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        face /= np.linalg.norm(face, axis=1, keepdims=True)
        normals = np.repeat(face[:, None, :], 3, axis=1)
    lo, hi = tris[..., :2].reshape(-1, 2).min(0), tris[..., :2].reshape(-1, 2).max(0)
    uvs = (tris[..., :2] - lo) / np.where(hi > lo, hi - lo, 1.0)
    if materials is None:
        material_index = np.zeros(count, np.int32)
    else:
        material_index = np.concatenate([np.full(len(t), m, np.int32) for t, m in zip(triangle_sets, materials)])
    return Geometry(tris, np.asarray(normals, np.float32), uvs.astype(np.float32), material_index,
                    np.zeros(count, np.int32))


def material(name="Grey", base_color=(0.5, 0.5, 0.5), roughness=0.5, metallic=0.0,
             specular_ior_level=0.5, ior=1.5, image=None) -> Material:
    return Material(name, np.asarray(base_color, np.float32), roughness, metallic, specular_ior_level,
                    ior, None if image is None else np.asarray(image, np.float32))


def look_rotation(direction, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """3x3 rotation whose -Z is ``direction``."""
    d = np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    up = np.asarray(up, np.float64)
    if abs(up @ d) > 0.99:
        up = np.array([0.0, 1.0, 0.0])
    x = np.cross(d, up)
    x /= np.linalg.norm(x)
    y = np.cross(x, d)
    return np.stack([x, y, -d], axis=1)


def make_light(kind, power=1000.0, position=(0.0, 0.0, 1.0), direction=(0.0, 0.0, -1.0),
               color=(1.0, 1.0, 1.0), scale=(1.0, 1.0, 1.0), **settings) -> Light:
    m = np.eye(4)
    m[:3, :3] = look_rotation(direction) * np.asarray(scale, np.float64)
    m[:3, 3] = position
    fields = dict(name=kind.title(), type=kind, matrix_world=m, position=np.asarray(position, np.float64),
                  direction=np.asarray(direction, np.float64) / np.linalg.norm(direction),
                  color=np.asarray(color, np.float64), power=float(power), energy=float(power),
                  exposure=0.0, normalize=True, radius=0.0, spot_size=0.0, spot_blend=0.0, sun_angle=0.0,
                  shape="SQUARE" if kind == "AREA" else "", size=np.zeros(2), diffuse_factor=1.0,
                  specular_factor=1.0)
    fields.update(settings)
    return Light(**fields)


def make_camera(location, target, kind="PERSP", lens=50.0, ortho_scale=6.0, resolution=(64, 48)) -> Camera:
    m = np.eye(4)
    m[:3, :3] = look_rotation(np.asarray(target, np.float64) - np.asarray(location, np.float64),
                              up=(0.0, 1.0, 0.0))
    m[:3, 3] = location
    return Camera("Camera", m, kind, lens, 36.0, 24.0, "AUTO", ortho_scale, 0.0, 0.0, 0.1, 100.0,
                  resolution, (1.0, 1.0))


def make_scene(triangle_sets, lights, materials=(), material_of_set=None, camera=None) -> SceneDescription:
    geo = geometry(triangle_sets, material_of_set)
    return SceneDescription(geo, (DEFAULT_MATERIAL, *materials), tuple(lights), camera, ("object",))


def render(scene, light_index=0, size=CALIBRATION_SIZE):
    views = R.render_rsm_views(scene, light_index, size)
    arrays = [view.to_numpy() for view in views]
    for view in views:
        view.free()
    return views, arrays


def assert_finite(arrays):
    for a in arrays:
        for name in RSM.__dataclass_fields__:
            assert np.all(np.isfinite(getattr(a.rsm, name))), name
        for name in ("flux", "flux_white", "texel_measure", "roughness", "depth"):
            assert np.all(np.isfinite(getattr(a, name))), name


def total_diffuse(arrays) -> np.ndarray:
    return sum((a.rsm.flux_diffuse.reshape(-1, 3).sum(0) for a in arrays), np.zeros(3))


# --- Analytic power on a square plane of half side a, light at height h above its centre ----------


def point_power_on_square(power, a, h):
    """P/(4π) × solid angle of the square (four corner rectangles, closed form)."""
    return power / (4.0 * math.pi) * 4.0 * math.atan(a * a / (h * math.sqrt(h * h + 2.0 * a * a)))


def lambertian_power_on_square(power, a, h):
    """A Lambertian emitter I = (P/π) cos θ facing the square: P × the point-to-parallel-rectangle
    form factor, four corner rectangles:
    F = 1/(2π) [A/√(1+A²) atan(B/√(1+A²)) + B/√(1+B²) atan(A/√(1+B²))]."""
    x = y = a / h
    f = (x / math.sqrt(1 + x * x) * math.atan(y / math.sqrt(1 + x * x))
         + y / math.sqrt(1 + y * y) * math.atan(x / math.sqrt(1 + y * y))) / (2.0 * math.pi)
    return power * 4.0 * f


def test_closed_forms_match_quadrature():
    a, h, n = 3.0, 1.0, 2000
    x = (np.arange(n) + 0.5) / n * a
    gx, gy = np.meshgrid(x, x)
    r2 = gx * gx + gy * gy + h * h
    solid_angle = 4.0 * np.sum(h / r2**1.5) * (a / n) ** 2
    cosine_weighted = 4.0 * np.sum(h * h / r2**2) * (a / n) ** 2
    assert point_power_on_square(4.0 * math.pi, a, h) == pytest.approx(solid_angle, rel=1e-6)
    assert lambertian_power_on_square(math.pi, a, h) == pytest.approx(cosine_weighted, rel=1e-6)


# --- Flux calibration against Cycles ---------------------------------------------------------------

GREY = (0.5, 0.25, 0.75)  # Rd per channel: the total Φ·Rd / Rd must be the same in all three


def calibration_material(name="Calibration", base_color=GREY):
    """A dielectric with Specular IOR Level 0: no specular layer, so Rd = base colour (Rs = 0) at
    every incidence in the Principled model."""
    return material(name, base_color=base_color, metallic=0.0, specular_ior_level=0.0)


def test_calibration_material_rd_is_its_base_colour():
    cosines = np.linspace(0.0, 1.0, 11)
    for roughness in (0.0, 0.5, 1.0):
        rd, rs = ref.principled_reflectances(np.tile(GREY, (11, 1)), 0.0, 0.0, 1.5, roughness, cosines)
        np.testing.assert_allclose(rd, np.tile(GREY, (11, 1)), rtol=1e-12)
        np.testing.assert_allclose(rs, 0.0, atol=1e-12)


def calibration_scene(light, half=3.0, camera=None):
    grey = calibration_material()
    return make_scene([rectangle(half)], [light], [grey], material_of_set=[1], camera=camera)


def check_power(scene, expected, label):
    views, arrays = render(scene)
    assert_finite(arrays)
    measured = total_diffuse(arrays) / np.asarray(GREY)
    error = measured / expected - 1.0
    print(f"\n{label}: views {[v.spec.name for v in views]}, RSM {measured[0]:.6g} W, "
          f"analytic {expected:.6g} W, error {error[0] * 100:+.4f} %")
    assert np.all(np.abs(error) < 0.01), (label, measured, expected)
    return error[0]


@pytest.mark.gpu
def test_flux_point_light_on_square():
    power, h, a = 1000.0, 1.0, 3.0
    scene = calibration_scene(make_light("POINT", power, (0.0, 0.0, h)), half=a)
    check_power(scene, point_power_on_square(power, a, h), "point")


@pytest.mark.gpu
@pytest.mark.parametrize("spot_size,spot_blend", [(math.radians(60), 0.3), (math.radians(45), 0.0),
                                                  (math.radians(150), 1.0)])
def test_flux_spot_light(spot_size, spot_blend):
    """The plane holds the whole cone: P/(4π) × ∫ Blender's smoothstep cone dω (numerical)."""
    power, h = 1000.0, 1.0
    half = 20.0 if spot_size > math.radians(120) else 3.0  # wider than the cone's footprint
    assert half > h * math.tan(0.5 * spot_size)
    light = make_light("SPOT", power, (0.0, 0.0, h), spot_size=spot_size, spot_blend=spot_blend)
    expected = power / (4.0 * math.pi) * lights.spot_cone_solid_angle(spot_size, spot_blend)
    check_power(calibration_scene(light, half), expected, f"spot {math.degrees(spot_size):.0f}° blend {spot_blend}")


@pytest.mark.gpu
def test_flux_sun_oblique_whole_plane():
    """S × the plane's area projected on the sun's plane (A cos θ); the camera sees all of it."""
    strength, theta = 3.0, math.radians(35.0)
    direction = (math.sin(theta), 0.0, -math.cos(theta))
    camera = make_camera((0.0, 0.0, 20.0), (0.0, 0.0, 0.0))
    scene = calibration_scene(make_light("SUN", strength, (5.0, 1.0, 7.0), direction), half=2.0, camera=camera)
    check_power(scene, strength * 16.0 * math.cos(theta), "sun, whole plane")


@pytest.mark.gpu
def test_flux_sun_fitted_to_camera():
    """An orthographic camera sees a 2 m x 1.5 m window of a 10 m plane: the sun's view is fitted
    to it, and the RSM's flux is S × that window's area."""
    strength = 2.0
    camera = make_camera((0.3, -0.2, 5.0), (0.3, -0.2, 0.0), kind="ORTHO", ortho_scale=2.0)
    scene = calibration_scene(make_light("SUN", strength, (0.0, 0.0, 3.0)), half=5.0, camera=camera)
    views, _ = render(scene, size=8)
    assert len(views) == 1 and not views[0].spec.perspective
    hx, hy = views[0].spec.half_extent
    assert (2 * hx, 2 * hy) == pytest.approx((2.0, 1.5), rel=1e-3)
    check_power(scene, strength * 2.0 * 1.5, "sun fitted to the camera")


@pytest.mark.gpu
def test_flux_area_light_on_square():
    power, h, a = 500.0, 1.0, 3.0
    light = make_light("AREA", power, (0.0, 0.0, h), size=np.array([0.1, 0.1]))
    views, _ = render(calibration_scene(light, a), size=4)
    assert "+Z" not in [v.spec.name for v in views]  # behind the emitter: skipped
    check_power(calibration_scene(light, a), lambertian_power_on_square(power, a, h), "area")


@pytest.mark.gpu
def test_flux_point_light_tilted_plane_and_colour():
    """A plane tilted 40° and off-centre (seen by several cube faces), a coloured light: the flux
    per channel scales with the colour, and the total matches the solid-angle quadrature."""
    power, color = 800.0, (1.0, 0.5, 0.25)
    tilt = math.radians(40.0)
    rotation = np.array([[1, 0, 0], [0, math.cos(tilt), -math.sin(tilt)], [0, math.sin(tilt), math.cos(tilt)]])
    tris = rectangle(1.5) @ rotation.T + np.array([0.7, 0.2, -1.2])
    grey = calibration_material()
    scene = make_scene([tris], [make_light("POINT", power, (0.0, 0.0, 0.0), color=color)], [grey], [1])
    # Solid angle of the tilted square by quadrature over its surface.
    n = 1500
    s = (np.arange(n) + 0.5) / n * 3.0 - 1.5
    gu, gv = np.meshgrid(s, s)
    points = np.stack([gu, gv, np.zeros_like(gu)], -1) @ rotation.T + np.array([0.7, 0.2, -1.2])
    normal = rotation @ np.array([0.0, 0.0, 1.0])
    r = np.linalg.norm(points, axis=-1)
    omega = np.sum(np.abs(points @ normal) / r**3) * (3.0 / n) ** 2
    _, arrays = render(scene)
    measured = total_diffuse(arrays) / np.asarray(GREY)
    expected = power / (4.0 * math.pi) * omega * np.asarray(color)
    print(f"\npoint, tilted plane: {measured} vs {expected}")
    np.testing.assert_allclose(measured, expected, rtol=0.01)


# --- Texel values --------------------------------------------------------------------------------

#: Φ·Rd and Φ·Rs of the GPU against the float64 model at the read-back position and normal: the
#: GPU's Principled terms are the same quadratures in float32 (test_principled.py bounds them by
#: 5e-3 over extreme directions); measured here within 2.1e-6 (point light, 5 materials).
REFLECTANCE_RTOL = 2e-5


def model_fluxes(light, a, lit, base, metallic, level, ior, roughness):
    """(Φ·Rd, Φ·Rs) of the texels ``lit`` of RSMArrays ``a`` by the float64 model
    (reference/rsm.py principled_reflectances) at each texel's incidence ω' from the read-back
    position and normal."""
    incoming = ref.incoming_directions(light, a.rsm.position[lit])
    cos_incidence = np.sum(incoming * a.rsm.normal[lit], axis=-1)
    rd, rs = ref.principled_reflectances(base, metallic, level, ior, roughness, cos_incidence)
    flux = a.flux[lit]
    return flux * rd, flux * rs


def assert_reflected_flux(a, lit, expected_diffuse, expected_specular, rtol=REFLECTANCE_RTOL):
    scale = a.flux[lit].max()
    np.testing.assert_allclose(a.rsm.flux_diffuse[lit], expected_diffuse, rtol=rtol, atol=1e-6 * scale)
    np.testing.assert_allclose(a.rsm.flux_specular[lit], expected_specular, rtol=rtol, atol=1e-6 * scale)



@pytest.mark.gpu
def test_spot_centre_texel_hits_the_known_point_and_red_plane():
    red = material("Red", base_color=(0.8, 0.0, 0.0), roughness=0.3)
    light = make_light("SPOT", 1000.0, (0.2, -0.1, 2.0), direction=(0.0, 0.0, -1.0),
                       spot_size=math.radians(40), spot_blend=0.2)
    scene = make_scene([rectangle(4.0, z=-0.5)], [light], [red], [1])
    (view,), (a,) = render(scene, size=64)
    assert view.spec.name == "spot"
    centre = a.rsm.position[31:33, 31:33].reshape(-1, 3).mean(0)
    np.testing.assert_allclose(centre, (0.2, -0.1, -0.5), atol=2.5 * 2.5 * math.tan(math.radians(20)) / 64)
    lit = a.coverage
    assert lit.all()  # the plane fills the view
    np.testing.assert_allclose(a.rsm.position[..., 2], -0.5, atol=1e-6)
    np.testing.assert_allclose(a.rsm.normal[lit], np.tile([0.0, 0.0, 1.0], (lit.sum(), 1)), atol=1e-6)
    np.testing.assert_allclose(a.roughness[lit], 0.3, atol=1e-7)
    assert a.rsm.flux_diffuse[..., 0].max() > 0.0
    assert np.all(a.rsm.flux_diffuse[..., 1:] == 0.0)
    # Rs of a dielectric: the dielectric lobe's albedo (F0 of IOR 1.5 = 0.04, Fresnel rising
    # towards grazing, multiple scattering) in every channel, red or not; Rd = 0.8 (1 − Rs).
    diffuse, specular = model_fluxes(light, a, lit, red.base_color, 0.0, 0.5, 1.5, 0.3)
    assert_reflected_flux(a, lit, diffuse, specular)
    np.testing.assert_array_equal(a.rsm.flux_specular[..., 0], a.rsm.flux_specular[..., 2])
    inside = lit & (a.flux_white > 0.0)  # in the cone
    rs = a.rsm.flux_specular[inside][:, 0] / a.flux[inside][:, 0]
    assert 0.04 < rs.min() < rs.max() < 0.06
    np.testing.assert_allclose(a.rsm.flux_diffuse[inside][:, 0], 0.8 * a.flux[inside][:, 0] * (1.0 - rs),
                               rtol=1e-5)
    # Depth of the centre texel: the plane's distance along the axis through the projection.
    clip = view.spec.projection_matrix @ np.array([0.0, 0.0, -2.5, 1.0])
    assert a.depth[32, 32] == pytest.approx(0.5 * clip[2] / clip[3] + 0.5, abs=1e-5)


@pytest.mark.gpu
def test_metallic_plane_has_no_diffuse_and_specular_is_the_metal_albedo():
    """Metallic 1: no diffuse; Rs is the metallic lobe's albedo for the incidence (Schlick from the
    base colour, multiple scattering), at least the base colour (F0) per channel."""
    gold = material("Gold", base_color=(1.0, 0.8, 0.3), roughness=0.2, metallic=1.0)
    light = make_light("SPOT", 100.0, (0.0, 0.0, 1.0), spot_size=1.0, spot_blend=0.1)
    scene = make_scene([rectangle(3.0)], [light], [gold], [1])
    _, (a,) = render(scene, size=32)
    assert np.all(a.rsm.flux_diffuse == 0.0)
    lit = a.coverage & (a.flux_white > 0.0)
    diffuse, specular = model_fluxes(light, a, lit, gold.base_color, 1.0, 0.5, 1.5, 0.2)
    assert_reflected_flux(a, lit, diffuse, specular)
    rs = a.rsm.flux_specular[lit] / a.flux[lit]
    assert np.all(rs >= np.array([1.0, 0.8, 0.3]) * (1.0 - 1e-4)) and np.all(rs <= 1.0 + 1e-6)
    assert a.rsm.flux_specular.sum() > 0.0


@pytest.mark.gpu
def test_texel_quantities_match_the_numpy_reference():
    """Every texel of a spot and an area light on two materials (one with an image texture): flux,
    Φ·Rd, Φ·Rs and the warped specular lobe equal the reference computed from the read-back
    position and normal."""
    image = np.zeros((4, 4, 4), np.float32)
    image[..., 0] = np.linspace(0.1, 0.9, 16).reshape(4, 4)
    image[..., 1] = 0.5
    image[..., 2] = np.linspace(0.9, 0.1, 16).reshape(4, 4).T
    image[..., 3] = 1.0
    textured = material("Textured", roughness=0.6, metallic=0.25, specular_ior_level=0.8, ior=1.45, image=image)
    rough = material("Rough", base_color=(0.2, 0.6, 0.3), roughness=1.0, specular_ior_level=0.3, ior=2.0)
    left = rectangle(1.5, centre=(-1.5, 0.0))
    right = rectangle(1.5, centre=(1.5, 0.0), z=-0.3)
    materials = {1: textured, 2: rough}
    for light in (make_light("SPOT", 700.0, (0.3, 0.2, 2.0), direction=(0.2, 0.1, -1.0),
                             color=(1.0, 0.9, 0.7), spot_size=math.radians(80), spot_blend=0.4),
                  make_light("AREA", 300.0, (0.0, 0.5, 1.5), direction=(0.3, -0.2, -1.0))):
        scene = make_scene([left, right], [light], [textured, rough], [1, 2])
        views, arrays = render(scene, size=64)
        for view, a in zip(views, arrays):
            lit = a.coverage
            if not lit.any():
                continue
            spec = view.spec
            rays = ref.texel_rays(64, spec.half_extent, spec.view_to_world)
            measure = ref.texel_solid_angles(64, spec.half_extent)
            np.testing.assert_allclose(a.texel_measure[lit], measure[lit], rtol=2e-6)
            flux_white = lights.light_intensity(light, rays) * measure
            np.testing.assert_allclose(a.flux_white[lit], flux_white[lit], rtol=1e-4,
                                       atol=1e-5 * flux_white.max())
            position = a.rsm.position[lit]
            on_right = position[:, 0] > 0.0
            base = np.where(on_right[:, None], rough.base_color, 0.0)
            # The image sampled bilinearly with repeat at the UV of the texel (UV from x, y).
            uv = np.stack([(position[:, 0] + 3.0) / 6.0, (position[:, 1] + 1.5) / 3.0], -1)
            base = np.where(on_right[:, None], base, image_sample_linear_repeat(image, uv))
            metallic = np.where(on_right, rough.metallic, textured.metallic)
            level = np.where(on_right, rough.specular_ior_level, textured.specular_ior_level)
            ior = np.where(on_right, rough.ior, textured.ior)
            roughness = np.where(on_right, 1.0, 0.6)
            diffuse, specular = model_fluxes(light, a, lit, base, metallic, level, ior, roughness)
            assert_reflected_flux(a, lit, diffuse, specular)
            np.testing.assert_allclose(a.roughness[lit], roughness, atol=1e-7)
            incoming = ref.incoming_directions(light, position)
            axis, sharpness = ref.specular_lobes(incoming, a.rsm.normal[lit], roughness)
            np.testing.assert_allclose(a.rsm.specular_axis[lit], axis, atol=2e-6)
            np.testing.assert_allclose(a.rsm.specular_sharpness[lit], sharpness, rtol=1e-5)
            # Normals face the light (both planes face +Z, the lights are above).
            np.testing.assert_allclose(a.rsm.normal[lit], np.tile([0, 0, 1.0], (lit.sum(), 1)), atol=1e-6)
            assert np.all(a.rsm.flux_diffuse[~lit] == 0.0) and np.all(a.flux[~lit] == 0.0)


REFLECTANCE_MATERIALS = {
    "dielectric": material("Dielectric", base_color=(0.8, 0.5, 0.2), roughness=0.3),
    "smooth": material("Smooth", base_color=(0.2, 0.6, 0.9), roughness=0.05, specular_ior_level=1.0,
                       ior=1.8),
    "rough": material("Rough", base_color=(0.9, 0.9, 0.9), roughness=1.0, ior=1.33),
    "metal": material("Metal", base_color=(0.9, 0.6, 0.3), roughness=0.4, metallic=1.0),
    "half_metal": material("HalfMetal", base_color=(0.7, 0.7, 0.2), roughness=0.2, metallic=0.5,
                           specular_ior_level=0.8, ior=1.6),
}


@pytest.mark.gpu
@pytest.mark.parametrize("kind", ["POINT", "SUN"])
@pytest.mark.parametrize("name", list(REFLECTANCE_MATERIALS))
def test_reflectances_follow_the_incidence(kind, name):
    """Φ·Rd and Φ·Rs of every texel are the Principled model (the direct light's, calibrated against
    Cycles) for that texel's incidence ω': a point light 0.5 m above a 12 m plane lights it from
    normal incidence to 85°, a sun at 70° from the normal at one oblique angle. Rd falls and Rs
    rises towards grazing for a dielectric; the totals Σ Φ·Rd, Σ Φ·Rs equal the model's."""
    m = REFLECTANCE_MATERIALS[name]
    if kind == "POINT":
        light = make_light("POINT", 500.0, (0.3, -0.2, 0.5), color=(1.0, 0.9, 0.7))
    else:
        theta = math.radians(70.0)
        light = make_light("SUN", 4.0, (0.0, 0.0, 5.0), direction=(math.sin(theta), 0.0, -math.cos(theta)),
                           color=(1.0, 0.9, 0.7))
    scene = make_scene([rectangle(6.0)], [light], [m], [1])
    _, arrays = render(scene, size=64)
    totals = np.zeros((2, 2, 3))  # (GPU, model) x (diffuse, specular)
    cosines = []
    for a in arrays:
        lit = a.coverage & (a.flux_white > 0.0)
        if not lit.any():
            continue
        diffuse, specular = model_fluxes(light, a, lit, m.base_color, m.metallic, m.specular_ior_level,
                                         m.ior, m.roughness)
        assert_reflected_flux(a, lit, diffuse, specular)
        totals[0] += a.rsm.flux_diffuse[lit].sum(0), a.rsm.flux_specular[lit].sum(0)
        totals[1] += diffuse.sum(0), specular.sum(0)
        cosines.append(np.sum(ref.incoming_directions(light, a.rsm.position[lit]) * a.rsm.normal[lit], -1))
        if m.metallic == 0.0:
            # The diffuse base gets what the dielectric layer does not reflect (its albedo is Rs).
            rs = a.rsm.flux_specular[lit][:, 0] / a.flux[lit][:, 0]
            np.testing.assert_allclose(a.rsm.flux_diffuse[lit], a.flux[lit] * m.base_color
                                       * (1.0 - rs)[:, None], rtol=1e-5, atol=1e-7 * a.flux[lit].max())
    cosines = np.concatenate(cosines)
    print(f"\n{kind} {name}: cos ω' {cosines.min():.3f}..{cosines.max():.3f}; GPU/model totals "
          f"diffuse {totals[0, 0] / np.maximum(totals[1, 0], 1e-30)}, "
          f"specular {totals[0, 1] / totals[1, 1]}")
    np.testing.assert_allclose(totals[0], totals[1], rtol=1e-3, atol=1e-9 * totals.max())
    if kind == "POINT":
        assert cosines.min() < 0.1 and cosines.max() > 0.999
        if m.metallic == 0.0:
            # The incidence matters: Rs at grazing well above Rs at normal incidence.
            rs_normal, rs_grazing = ref.principled_reflectances(m.base_color, 0.0, m.specular_ior_level, m.ior,
                                                                m.roughness, np.array([1.0, 0.1]))[1][:, 0]
            assert rs_grazing > 1.5 * rs_normal


@pytest.mark.gpu
def test_reflectances_are_cycles_colour_passes_seen_from_the_light():
    """Cycles' Diffuse Color and Glossy Color passes of a camera placed at a spot light and sharing
    its frustum hold the Principled reflectances for the view direction, here ω' of each texel: the
    RSM's Φ·Rd/Φ and Φ·Rs/Φ must be them (a plane lit at 20° to 80° from its normal). Bounds as
    test_principled.py's test_colour_passes_match_cycles (mean 1 % / max 3 % diffuse, mean 5 %
    glossy, which Cycles' tabulated albedos and 4 samples leave)."""
    import scene_builders as sb
    from cycles_truth import render_cycles
    from vsgl_addon.scene import extract_scene

    sb.reset()
    sb.plane(size=20.0, material=sb.principled("M", base_color=(0.8, 0.5, 0.2), roughness=0.3, metallic=0.3,
                                               specular_ior_level=0.5, ior=1.5))
    location, target = (0.0, -2.5, 1.2), (0.0, 0.6, 0.0)
    # A 36 mm sensor behind an 18 mm lens: a 90° square field, the spot's cone of 90°.
    sb.spot_light(power=300.0, location=location, look_at_point=target, spot_size=math.radians(90),
                  spot_blend=0.0)
    sb.camera(location=location, look_at_point=target, lens=18.0, resolution=(48, 48))
    scene = extract_scene(sb.depsgraph())
    index = next(i for i, light in enumerate(scene.lights) if light.type == "SPOT")
    (view,), (a,) = render(scene, index, size=48)
    passes = render_cycles(samples=4, filter_width=0.01)
    lit = a.coverage & (a.flux_white > 0.0)
    # The camera pixel of each texel's position (the frustums coincide: texel centre = pixel centre).
    camera = scene.camera
    clip = np.c_[a.rsm.position[lit], np.ones(lit.sum())] @ (camera.projection_matrix() @ camera.view_matrix()).T
    pixel = np.floor((clip[:, :2] / clip[:, 3:] * 0.5 + 0.5) * 48).astype(int)
    rows, columns = np.nonzero(lit)
    np.testing.assert_array_equal(pixel, np.c_[columns, rows])
    diffuse_colour = passes["DiffCol"][::-1][lit]
    glossy_colour = passes["GlossCol"][::-1][lit]
    rd = a.rsm.flux_diffuse[lit] / a.flux[lit]
    rs = a.rsm.flux_specular[lit] / a.flux[lit]
    cosines = np.sum(ref.incoming_directions(scene.lights[index], a.rsm.position[lit]) * a.rsm.normal[lit], -1)
    rel_d = np.abs(rd - diffuse_colour) / diffuse_colour
    rel_s = np.abs(rs - glossy_colour) / glossy_colour
    # For comparison, the reflectances at normal incidence without layering: base (1 − m), F0 mix.
    base, metallic = np.array([0.8, 0.5, 0.2]), 0.3
    plain_d = np.mean(np.abs(base * (1 - metallic) - diffuse_colour) / diffuse_colour)
    plain_s = np.mean(np.abs(0.04 * (1 - metallic) + base * metallic - glossy_colour) / glossy_colour)
    print(f"\ncos ω' {cosines.min():.2f}..{cosines.max():.2f}, {lit.sum()} texels: Diffuse Color mean rel err "
          f"{rel_d.mean():.4f}, max {rel_d.max():.4f}; Glossy Color mean {rel_s.mean():.4f}, max {rel_s.max():.4f} "
          f"(base (1 - m) and the F0 mix: {plain_d:.4f}, {plain_s:.4f})")
    assert cosines.min() < 0.3 and cosines.max() > 0.9
    assert rel_d.mean() < 0.01 and rel_d.max() < 0.03
    assert rel_s.mean() < 0.05


@pytest.mark.gpu
def test_back_side_normal_is_flipped_towards_the_light():
    """A plane facing away from the light (two-sided surface): the normal faces the light."""
    tris = rectangle(2.0)[:, [0, 2, 1]]  # reversed winding: faces -Z
    normals = np.tile([0.0, 0.0, -1.0], (2, 3, 1))
    geo = geometry([tris], [1], normals=normals)
    scene = SceneDescription(geo, (DEFAULT_MATERIAL, material()), (make_light("POINT", 100.0, (0, 0, 1.0)),),
                             None, ("o",))
    _, arrays = render(scene, size=16)
    for a in arrays:
        assert np.all(a.rsm.normal[a.coverage][:, 2] == 1.0)


# --- Extremes ------------------------------------------------------------------------------------


@pytest.mark.gpu
@pytest.mark.parametrize("kind", ["POINT", "SPOT", "AREA", "SUN"])
def test_light_that_hits_nothing_is_cheap_and_empty(kind, monkeypatch):
    """Geometry outside every view (behind the spot or area light; no geometry for the point light;
    a sun whose camera looks away from the scene): no views, no draw, zero flux."""
    if kind == "SUN":
        camera = make_camera((0.0, 0.0, 50.0), (0.0, 0.0, 100.0))  # looks away from the plane
        scene = make_scene([rectangle(1.0)], [make_light("SUN", 3.0, (0, 0, 5.0))], camera=camera)
    elif kind == "POINT":
        # Every direction is some cube face's: only an empty scene is missed by a point light.
        scene = SceneDescription(Geometry.empty(), (DEFAULT_MATERIAL,), (make_light("POINT", 100.0),), None, ())
    else:
        # The plane is behind the light (which points down, the plane is above it).
        scene = make_scene([rectangle(1.0, z=5.0)], [make_light(kind, 100.0, (0, 0, 1.0),
                                                                spot_size=math.radians(45), spot_blend=0.1)])
    drawn = []
    monkeypatch.setattr(R, "_render", lambda *args: drawn.append(args))
    views = R.render_rsm_views(scene, 0, 256)
    assert views == [] and drawn == []  # no view, no draw call
    assert R.total_flux(views)["flux"].tolist() == [0.0, 0.0, 0.0]


@pytest.mark.gpu
def test_spot_cone_missing_the_plane_gives_zero_flux_without_nan():
    """The plane is inside the view's frustum corner but outside the round cone: rendered, all
    flux 0, nothing NaN."""
    light = make_light("SPOT", 100.0, (0.0, 0.0, 1.0), spot_size=math.radians(40), spot_blend=0.0)
    corner = math.tan(math.radians(20)) * 0.95
    tris = rectangle(0.02, centre=(corner, corner), z=0.0)
    _, arrays = render(make_scene([tris], [light]), size=64)
    assert len(arrays) == 1 and arrays[0].coverage.any()
    assert_finite(arrays)
    assert total_diffuse(arrays).sum() == 0.0


@pytest.mark.gpu
def test_single_lit_texel():
    light = make_light("SPOT", 100.0, (0.0, 0.0, 1.0), spot_size=math.radians(30), spot_blend=0.0)
    tiny = rectangle(1e-4, centre=(0.0, 0.0))  # far below one texel of a 32² view at 1 m (~1.7 cm)
    # Place it at a texel centre: texel (16, 16)'s centre is at tan(15°) (1/32) from the axis.
    offset = math.tan(math.radians(15)) / 32
    tiny = tiny + np.array([offset, offset, 0.0])
    _, (a,) = render(make_scene([tiny], [light]), size=32)
    assert a.coverage.sum() == 1
    assert a.coverage[16, 16]
    assert_finite([a])
    assert a.flux_white[16, 16] == pytest.approx(100.0 / (4 * math.pi) * a.texel_measure[16, 16], rel=1e-6)


@pytest.mark.gpu
@pytest.mark.parametrize("size", [1, 16, 64, 512])
def test_sizes(size):
    light = make_light("SPOT", 1000.0, (0.0, 0.0, 1.0), spot_size=math.radians(60), spot_blend=0.3)
    scene = calibration_scene(light, half=3.0)
    views, arrays = render(scene, size=size)
    assert arrays[0].rsm.position.shape == (size, size, 3)
    assert_finite(arrays)
    expected = 1000.0 / (4 * math.pi) * lights.spot_cone_solid_angle(math.radians(60), 0.3)
    measured = total_diffuse(arrays)[0] / GREY[0]
    if size >= 64:
        assert measured == pytest.approx(expected, rel=0.01)
    # Whatever the size, the flux of the full view (its solid angle) is right: the RSM covers it all.
    measure = sum(a.texel_measure.sum() for a in arrays)
    hx, hy = views[0].spec.half_extent
    full = 4.0 * math.asin(hx * hy / math.sqrt((1 + hx * hx) * (1 + hy * hy)))  # solid angle of the view
    assert measure == pytest.approx(full, rel=1e-5)


@pytest.mark.gpu
@pytest.mark.parametrize("roughness", [0.0, 1e-3, 1.0])
@pytest.mark.parametrize("grazing", [False, True])
def test_roughness_extremes_and_grazing_light(roughness, grazing):
    """Roughness 0, 1e-3, 1, and a light 0.5° above the plane: lobes finite and as the reference."""
    m = material("M", roughness=roughness)
    if grazing:
        elevation = math.radians(0.5)
        light = make_light("SPOT", 100.0, (-3.0 * math.cos(elevation), 0.0, 3.0 * math.sin(elevation)),
                           direction=(math.cos(elevation), 0.0, -math.sin(elevation)),
                           spot_size=math.radians(10), spot_blend=0.2)
    else:
        light = make_light("POINT", 100.0, (0.0, 0.0, 1.0))
    scene = make_scene([rectangle(2.0)], [light], [m], [1])
    _, arrays = render(scene, size=64)
    assert_finite(arrays)
    assert any(a.coverage.any() for a in arrays)
    for a in arrays:
        lit = a.coverage
        if not lit.any():
            continue
        incoming = ref.incoming_directions(light, a.rsm.position[lit])
        axis, sharpness = ref.specular_lobes(incoming, a.rsm.normal[lit], roughness)
        np.testing.assert_allclose(a.rsm.specular_sharpness[lit], sharpness, rtol=2e-3 if grazing else 1e-5)
        np.testing.assert_allclose(a.rsm.specular_axis[lit], axis, atol=1e-5)
        assert np.all(a.rsm.specular_sharpness[lit] > 0.0)


@pytest.mark.gpu
def test_views_are_proper_rotations_and_cover_the_sphere():
    scene = calibration_scene(make_light("POINT", 1.0, (0.0, 0.0, 1.0)))
    specs = V.light_view_specs(scene, scene.lights[0])
    assert sorted(s.name for s in specs) == sorted(["+X", "-X", "+Y", "-Y", "+Z", "-Z"])
    forward = []
    for spec in specs:
        rotation = spec.view_matrix[:3, :3]
        np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(rotation) == pytest.approx(1.0)
        forward.append(-rotation[2])
    np.testing.assert_allclose(np.abs(np.sum(forward, axis=0)), 0.0, atol=1e-12)
    # The +Z face sees nothing of a plane below the light: culled before rendering.
    views = R.render_rsm_views(scene, 0, 4)
    assert "+Z" not in [v.spec.name for v in views] and len(views) == 5


@pytest.mark.gpu
def test_rsm_textures_layout_for_vsgl_generation():
    """The textures are the RSMTextures VSGL generation reads: same RSM as to_numpy."""
    scene = calibration_scene(make_light("SPOT", 10.0, spot_size=1.0, spot_blend=0.2))
    (view,) = R.render_rsm_views(scene, 0, 16)
    textures = view.rsm_textures()
    assert textures.size == 16
    a = view.to_numpy()
    position = R.read_texture(textures.position, 16, 16)
    np.testing.assert_array_equal(position[..., 3], a.rsm.specular_sharpness)
    RSM.coerce(a.rsm)  # valid input of the reference
    assert luminance(a.rsm.flux_diffuse).sum() > 0.0
    view.free()
    assert view.textures == {} and view.framebuffer is None


@pytest.mark.gpu
def test_scene_gpu_is_reused_across_lights(capsys):
    lights = [make_light("SPOT", 100.0, (0, 0, 1.0), spot_size=1.0, spot_blend=0.1),
              make_light("POINT", 100.0, (0, 0, 1.0)), make_light("AREA", 100.0, (0, 0, 1.0))]
    scene = make_scene([rectangle(2.0)], lights)
    scene_gpu = R.SceneGPU(scene)
    counts = [len(R.render_rsm_views(scene_gpu, index, 8)) for index in range(3)]
    assert counts == [1, 5, 5]
    scene_gpu.free()
    assert scene_gpu.batch is None


# --- Through Blender -----------------------------------------------------------------------------


@pytest.mark.gpu
def test_extracted_blender_scene_spot_flux():
    """A spot light and a plane built in Blender and extracted: the RSM's Φ·Rd / Rd is the analytic
    power of the cone (extraction's units meet the pass's)."""
    import scene_builders as sb
    from vsgl_addon.scene import extract_scene

    sb.reset()
    sb.plane(size=8.0, material=sb.principled("Floor", base_color=(0.5, 0.5, 0.5), roughness=0.4,
                                              specular_ior_level=0.0))
    spot_size, blend = math.radians(50), 0.25
    sb.spot_light(power=250.0, location=(0.0, 0.0, 1.5), spot_size=spot_size, spot_blend=blend,
                  color=(1.0, 0.8, 0.6))
    sb.camera(location=(0, -6, 3))
    scene = extract_scene(sb.depsgraph())
    index = next(i for i, light in enumerate(scene.lights) if light.type == "SPOT")
    _, arrays = render(scene, index)
    expected = 250.0 / (4 * math.pi) * lights.spot_cone_solid_angle(spot_size, blend) * np.array([1.0, 0.8, 0.6])
    np.testing.assert_allclose(total_diffuse(arrays) / 0.5, expected, rtol=0.01)


def test_convex_hex_intersection_of_boxes_and_frustum():
    a = V.box_corners((0.0, 0.0, 0.0), (2.0, 2.0, 2.0))
    b = V.box_corners((1.0, -1.0, 0.5), (3.0, 1.5, 1.0))
    points = V.convex_hex_intersection(a, b)
    np.testing.assert_allclose(points.min(0), (1.0, 0.0, 0.5), atol=1e-12)
    np.testing.assert_allclose(points.max(0), (2.0, 1.5, 1.0), atol=1e-12)
    assert len(V.convex_hex_intersection(a, b + 10.0)) == 0
    # A camera frustum cut by a box: every vertex lies in both.
    camera = make_camera((0.0, -5.0, 2.0), (0.0, 0.0, 0.0))
    frustum = V.camera_frustum_corners(camera)
    points = V.convex_hex_intersection(frustum, a - 1.0)
    assert len(points) >= 4
    for corners in (frustum, a - 1.0):
        normals, offsets = V.hex_planes(corners)
        assert np.all(points @ normals.T >= offsets - 1e-7)


@pytest.mark.gpu
def test_flux_spot_with_non_uniform_scale():
    """An elliptical cone (object scale 2 x 1 x 1): the view covers the ellipse and the flux is the
    reference intensity integrated over the plane (quadrature)."""
    power, h = 1000.0, 1.0
    light = make_light("SPOT", power, (0.0, 0.0, h), spot_size=math.radians(50), spot_blend=0.2,
                       scale=(2.0, 1.0, 1.0))
    scene = calibration_scene(light, half=4.0)
    views, _ = render(scene, size=8)
    hx, hy = views[0].spec.half_extent
    assert hx == pytest.approx(2.0 * hy)
    n, half = 2000, 4.0
    s = (np.arange(n) + 0.5) / n * 2 * half - half
    gx, gy = np.meshgrid(s, s)
    offsets = np.stack([gx, gy, -np.full_like(gx, h)], -1)
    r = np.linalg.norm(offsets, axis=-1)
    intensity = lights.light_intensity(light, offsets / r[..., None])
    expected = np.sum(intensity * h / r**3) * (2 * half / n) ** 2
    check_power(scene, expected, "spot, non-uniform scale")


@pytest.mark.gpu
def test_occluder_takes_the_flux_of_its_shadow():
    """A red square 1 m under a point light shadows a grey plane 2 m under it: the RSM holds each
    texel's first hit only (depth test), so the plane's channel loses exactly the occluder's flux."""
    power = 1000.0
    grey = calibration_material("Grey", base_color=(0.5, 0.5, 0.5))
    red = calibration_material("Red", base_color=(1.0, 0.0, 0.0))
    scene = make_scene([rectangle(3.0, z=0.0), rectangle(0.5, z=1.0)],
                       [make_light("POINT", power, (0.0, 0.0, 2.0))], [grey, red], [1, 2])
    _, arrays = render(scene)
    total = sum(a.flux_white.sum() for a in arrays)
    plane = point_power_on_square(power, 3.0, 2.0)
    occluder = point_power_on_square(power, 0.5, 1.0)
    assert total == pytest.approx(plane, rel=0.01)
    diffuse = total_diffuse(arrays)
    assert diffuse[1] / 0.5 == pytest.approx(plane - occluder, rel=0.01)
    assert (diffuse[0] - diffuse[1]) == pytest.approx(occluder, rel=0.01)
    (bottom,) = [a for a in arrays if a.coverage[128, 128] and abs(a.rsm.normal[128, 128, 2]) == 1.0
                 and a.rsm.position[128, 128, 2] > 0.5]
    assert bottom.rsm.position[128, 128, 2] == pytest.approx(1.0, abs=1e-6)


@pytest.mark.gpu
def test_views_feed_vsgl_generation():
    """The view's textures go to VSGL generation as they are (no copy): the RSM total it reads is
    Σ Φ(Rd + Rs) of the read-back RSM."""
    from vsgl_addon.passes.vsgl_generation import VSGLGeneration

    gold = material("Gold", base_color=(1.0, 0.8, 0.3), roughness=0.3, metallic=0.5)
    scene = make_scene([rectangle(3.0)], [make_light("SPOT", 300.0, spot_size=1.0, spot_blend=0.2)],
                       [gold], [1])
    (view,) = R.render_rsm_views(scene, 0, 64)
    generation = VSGLGeneration()
    try:
        generation.build_mip_atlas(view.rsm_textures())
        generation.generate(4, 1.0, "modified")
        total = generation.read_table()["rsm_total_power"]
    finally:
        generation.free()
    a = view.to_numpy()
    expected = (a.rsm.flux_diffuse + a.rsm.flux_specular).reshape(-1, 3).sum(0)
    np.testing.assert_allclose(np.ravel(total), expected, rtol=1e-4)
    view.free()
