// @require lib/principled.glsl
//
// Glossy VPLs from RSM texels (004 section 3; light-paths.md: the sharp specular reflectors' row).
// Twin: vsgl_addon/reference/vpl_culling.py glossy_vpl_from_texel (same name, same semantics, float32).

// Smallest GGX alpha a VPL's lobe takes (reference VPL_ALPHA_MIN): the range the spheroid bounds and
// the shading are tested on; a mirror texel (alpha 1e-6) shines as an alpha 1e-3 lobe.
const float VPL_ALPHA_MIN = 1e-3;

// w_i, unit, from the surface towards the light: light.w = 1 a point at light.xyz, 0 a sun whose
// direction towards it is light.xyz (reference incoming_from_light).
vec3 incoming_from_light(vec4 light, vec3 position)
{
  vec3 towards = light.w > 0.5 ? light.xyz - position : light.xyz;
  return safe_normalize(towards, vec3(0.0, 0.0, 1.0));
}

// The texel (its RSM position, normal + Principled roughness and Phi Rs slots) as a glossy VPL's four
// table records: (q, max(alpha, VPL_ALPHA_MIN)), (n, max channel of Phi Rs), (w_i, 0), (Phi Rs, 0).
// True where GGX alpha < alpha_c and the texel reflects some specular flux.
bool glossy_vpl_from_texel(vec4 position, vec4 normal, vec4 flux_specular, vec4 light, float caustic_roughness,
                           out vec4 record0, out vec4 record1, out vec4 record2, out vec4 record3)
{
  float alpha = principled_alpha(normal.w);
  float scalar_flux = max(max(flux_specular.r, flux_specular.g), flux_specular.b);
  record0 = vec4(position.xyz, max(alpha, VPL_ALPHA_MIN));
  record1 = vec4(normal.xyz, scalar_flux);
  record2 = vec4(incoming_from_light(light, position.xyz), 0.0);
  record3 = vec4(flux_specular.rgb, 0.0);
  return alpha < caustic_roughness && scalar_flux > 0.0;
}
