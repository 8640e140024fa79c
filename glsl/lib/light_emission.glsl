// @require lib/math.glsl
//
// Blender's light emission model (formulas.md sec. 4; Cycles 5.0, kernel/light/ headers), shared by the
// RSM pass (the flux of a texel: glsl/rsm/rsm.frag.glsl) and the direct light pass (the irradiance
// of a point: glsl/direct_light/light_at_surface.glsl), so that the light a VPL re-emits is the light the
// direct pass puts on the same surface. Measured against Cycles in tests/test_direct_light.py, the
// RSM's flux against closed forms in tests/test_rsm.py. Float64 twin: vsgl_addon/reference/lights.py
// (same names, same semantics).
//
// Light parameters `params` (reference light_params) = (type code, cos half spot angle,
// 1 / ((1 - cos) spot_blend) or -1 for a hard edge, intensity scale): point and spot P / (4 pi) W/sr,
// area P / pi W/sr on its axis, sun S W/m^2. Lights point down their local -Z; the radius of point
// and spot lights, the size of area lights and the sun's angle are not modelled (formulas.md sec. 4).

// Light types (params.x): the numbering of the reference's LIGHT_TYPE_CODES.
const int LIGHT_POINT = 0;
const int LIGHT_SPOT = 1;
const int LIGHT_SUN = 2;
const int LIGHT_AREA = 3;

// Cycles' smoothstepf (intern/cycles/util/math_float.h): 0 below 0, 1 above 1, 3x^2 - 2x^3 between.
float light_smoothstep(float x)
{
  if (x <= 0.0) {
    return 0.0;
  }
  if (x >= 1.0) {
    return 1.0;
  }
  return x * x * (3.0 - 2.0 * x);
}

// Blender's spot cone (Cycles, kernel/light/spot.h spot_light_attenuation) for a ray leaving the
// light along `direction_world`: the ray in the light's local frame with the object scale divided
// out (a scaled spot has an elliptical cone), z along the spot axis;
// smoothstep((cos - cos_half_spot) / ((1 - cos_half_spot) spot_blend)), a hard edge for blend 0.
float light_spot_attenuation(vec3 direction_world, mat3 light_to_local, vec4 params)
{
  vec3 local = safe_normalize(light_to_local * direction_world, vec3(0.0, 0.0, 1.0));
  float cos_axis = -local.z;  // lights point down their local -Z
  if (params.z < 0.0) {
    return cos_axis > params.y ? 1.0 : 0.0;
  }
  return light_smoothstep((cos_axis - params.y) * params.z);
}

// Radiant intensity (W/sr per unit light colour) towards the unit `direction` leaving the light:
// point and spot P / (4 pi) (spot: times the cone), area a Lambertian point emitter
// (P / pi) cos(theta) about the unit `light_axis` (Blender's area light seen from afar); for a sun,
// whose intensity is not defined, its irradiance S (W/m^2) on a surface facing it, in any direction.
float light_intensity(vec4 params, vec3 direction, vec3 light_axis, mat3 light_to_local)
{
  int type = int(params.x + 0.5);
  float intensity = params.w;
  if (type == LIGHT_SPOT) {
    intensity *= light_spot_attenuation(direction, light_to_local, params);
  }
  else if (type == LIGHT_AREA) {
    intensity *= max(dot(direction, light_axis), 0.0);
  }
  return intensity;
}
