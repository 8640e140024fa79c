// @require lib/principled.glsl
//
// Blender's lights as seen from a surface point (formulas.md sec. 4; Cycles 5.0, measured in
// tests/test_direct_light.py): the irradiance a white light of the light's power puts on a surface,
// and the direction towards the light. Float64 twin: vsgl_addon/reference/direct_light.py (same
// names). Light parameters `params` = (type code, cos half spot angle, 1 / ((1 - cos) spot_blend)
// or -1 for a hard edge, intensity scale): point and spot P / (4 pi) W/sr, area P / pi W/sr on its
// axis, sun S W/m^2 (the layout of vsgl_addon/passes/rsm.py _light_params).

const int DIRECT_LIGHT_POINT = 0;
const int DIRECT_LIGHT_SPOT = 1;
const int DIRECT_LIGHT_SUN = 2;
const int DIRECT_LIGHT_AREA = 3;

// Smallest squared distance to a light (m^2): a point on the light stays finite.
const float DIRECT_LIGHT_MIN_DISTANCE2 = 1e-12;

// Cycles' smoothstepf: 0 below 0, 1 above 1, 3x^2 - 2x^3 between.
float direct_light_smoothstep(float x)
{
  if (x <= 0.0) {
    return 0.0;
  }
  if (x >= 1.0) {
    return 1.0;
  }
  return x * x * (3.0 - 2.0 * x);
}

// Blender's spot cone (Cycles spot_light_attenuation) for a ray leaving the light along
// `direction_world`, in the light's local frame with the object scale divided out.
float direct_light_spot_attenuation(vec3 direction_world, mat3 light_to_local, vec4 params)
{
  vec3 local = safe_normalize(light_to_local * direction_world, vec3(0.0, 0.0, 1.0));
  float cos_axis = -local.z;  // lights point down their local -Z
  if (params.z < 0.0) {
    return cos_axis > params.y ? 1.0 : 0.0;
  }
  return direct_light_smoothstep((cos_axis - params.y) * params.z);
}

// Irradiance (W/m^2 per unit light colour) at `position` with unit `normal` from the light, and
// `incoming`, the unit direction from the point towards the light. Point and spot: I cos / d^2
// with I = P / 4 pi (times the cone); area: a Lambertian point emitter, I = (P / pi) cos(theta_light);
// sun: S cos. Zero for a light below the surface (or exactly in its plane).
float direct_light_irradiance(vec4 params, vec3 light_position, vec3 light_axis,
                              mat3 light_to_local, vec3 position, vec3 normal, out vec3 incoming)
{
  int type = int(params.x + 0.5);
  if (type == DIRECT_LIGHT_SUN) {
    incoming = -light_axis;
    return params.w * max(dot(normal, incoming), 0.0);
  }
  vec3 towards = light_position - position;
  float distance2 = max(dot(towards, towards), DIRECT_LIGHT_MIN_DISTANCE2);
  incoming = safe_normalize(towards, normal);
  float intensity = params.w;
  if (type == DIRECT_LIGHT_SPOT) {
    intensity *= direct_light_spot_attenuation(-incoming, light_to_local, params);
  }
  else if (type == DIRECT_LIGHT_AREA) {
    intensity *= max(-dot(incoming, light_axis), 0.0);
  }
  return intensity * max(dot(normal, incoming), 0.0) / distance2;
}

// Diffuse and glossy radiance (W/(m^2 sr) per unit light colour) towards `outgoing` of a point with
// Principled terms `terms` lit by irradiance `irradiance` from `incoming`: f_d E and f_s E.
void direct_light_radiance(PrincipledTerms terms, vec3 incoming, vec3 outgoing, vec3 normal,
                           float irradiance, out vec3 diffuse, out vec3 glossy)
{
  vec3 fd, fs;
  principled_brdf(terms, incoming, outgoing, normal, fd, fs);
  diffuse = fd * irradiance;
  glossy = fs * irradiance;
}
