// @require lib/principled.glsl
//
// The per-pixel reflectances VSGL shading needs, from the camera G-buffer (passes/gbuffer.py
// layout): Rd = base (1 - metallic)(1 - E_spec(mu_o)) (Cycles' Diffuse Color, principled.glsl) and
// the Schlick F0 of the specular lobe (dielectric F0 from IOR and Specular IOR Level, base colour
// for metals) that 000 app. C's C(xi_in) uses. Python side: vsgl_addon/passes/shading_inputs.py.
// camera: (position, 1) perspective or (direction towards the camera, 0) orthographic.

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy);
  vec4 position = texelFetch(gbuffer_position, texel, 0);
  vec4 normal_roughness = texelFetch(gbuffer_normal, texel, 0);
  vec4 base_metallic = texelFetch(gbuffer_base_color, texel, 0);
  vec4 material = texelFetch(gbuffer_material, texel, 0);
  diffuse_reflectance = vec4(0.0);
  specular_f0 = vec4(0.0);
  if (!(position.w > 0.0)) {
    return;
  }
  vec3 to_camera = camera.w > 0.0 ? camera.xyz - position.xyz : camera.xyz;
  vec3 view = safe_normalize(to_camera, vec3(0.0, 0.0, 1.0));
  vec3 normal = safe_normalize(normal_roughness.xyz, vec3(0.0, 0.0, 1.0));
  float mu_o = clamp(dot(normal, view), 0.0, 1.0);
  PrincipledTerms terms = principled_terms(base_metallic.rgb, base_metallic.a, material.x, material.y,
                                           normal_roughness.w, mu_o);
  diffuse_reflectance = vec4(terms.diffuse, 1.0);
  specular_f0 = vec4(mix(vec3(terms.f0_dielectric), terms.f0_metal, terms.metallic), 1.0);
}
