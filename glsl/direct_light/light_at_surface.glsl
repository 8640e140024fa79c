// @require lib/light_emission.glsl
// @require lib/principled.glsl
//
// Blender's lights as seen from a surface point (formulas.md sec. 4; Cycles 5.0, measured in
// tests/test_direct_light.py): the irradiance a white light of the light's power puts on a surface,
// and the direction towards the light, from the emission model of lib/light_emission.glsl (`params` is its
// light parameters). Float64 twin: vsgl_addon/reference/direct_light.py (same names).

// Smallest squared distance to a light (m^2): a point on the light stays finite.
const float DIRECT_LIGHT_MIN_DISTANCE2 = 1e-12;

// Irradiance (W/m^2 per unit light colour) at `position` with unit `normal` from the light, and
// `incoming`, the unit direction from the point towards the light. Point and spot: I cos / d^2
// with I = P / 4 pi (times the cone); area: a Lambertian point emitter, I = (P / pi) cos(theta_light);
// sun: S cos. Zero for a light below the surface (or exactly in its plane).
float direct_light_irradiance(vec4 params, vec3 light_position, vec3 light_axis,
                              mat3 light_to_local, vec3 position, vec3 normal, out vec3 incoming)
{
  int type = int(params.x + 0.5);
  if (type == LIGHT_SUN) {
    incoming = -light_axis;
    return params.w * max(dot(normal, incoming), 0.0);
  }
  vec3 towards = light_position - position;
  float distance2 = max(dot(towards, towards), DIRECT_LIGHT_MIN_DISTANCE2);
  incoming = safe_normalize(towards, normal);
  return light_intensity(params, -incoming, light_axis, light_to_local) *
         max(dot(normal, incoming), 0.0) / distance2;
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
