// @require lib/principled.glsl
//
// The per-pixel reflectances VSGL shading needs, from the camera G-buffer (one GBufferTexel per
// pixel, fetched by the generated gbuffer_load; vsgl_addon/layouts.py GBUFFER):
// Rd = base (1 - metallic)(1 - E_spec(mu_o)) (Cycles' Diffuse Color, principled.glsl) and
// the Schlick F0 of the specular lobe (dielectric F0 from IOR and Specular IOR Level, base colour
// for metals) that 000 app. C's C(xi_in) uses, written as one ShadingInputs per pixel by the
// generated shading_inputs_store (vsgl_addon/layouts.py SHADING_INPUTS).
// Python side: vsgl_addon/passes/shading_inputs.py.
// camera: (position, 1) perspective or (direction towards the camera, 0) orthographic.

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy);
  GBufferTexel g = gbuffer_load(texel);
  ShadingInputs inputs;
  inputs.diffuse_reflectance = vec3(0.0);
  inputs.diffuse_coverage = 0.0;
  inputs.specular_f0 = vec3(0.0);
  inputs.specular_coverage = 0.0;
  if (!(g.coverage > 0.0)) {
    shading_inputs_store(inputs);
    return;
  }
  vec3 to_camera = camera.w > 0.0 ? camera.xyz - g.position : camera.xyz;
  vec3 view = safe_normalize(to_camera, vec3(0.0, 0.0, 1.0));
  vec3 normal = safe_normalize(g.normal, vec3(0.0, 0.0, 1.0));
  float mu_o = clamp(dot(normal, view), 0.0, 1.0);
  PrincipledTerms terms = principled_terms(g.base_color, g.metallic, g.specular_ior_level, g.ior,
                                           g.roughness, mu_o);
  inputs.diffuse_reflectance = terms.diffuse;
  inputs.diffuse_coverage = 1.0;
  inputs.specular_f0 = mix(vec3(terms.f0_dielectric), terms.f0_metal, terms.metallic);
  inputs.specular_coverage = 1.0;
  shading_inputs_store(inputs);
}
