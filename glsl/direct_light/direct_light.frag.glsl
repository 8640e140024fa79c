// @require direct_light/light_at_surface.glsl
// @require lib/shadow.glsl
// @require direct_light/light_visibility.glsl
// @require lib/light_links.glsl
//
// Direct light of one light, full screen over the camera G-buffer (vsgl_addon/passes/gbuffer.py
// layout), added (blending ONE, ONE) into two RGBA32F targets: diffuse and glossy direct radiance
// (W/(m^2 sr), RGB; alpha 0). Python side: vsgl_addon/passes/direct_light.py.
//
// light_constants (RGBA32F, 1 row): 0 (light position, view count), 1 (light axis, 0),
// 2 light params (lib/light_emission.glsl), 3 (light colour, 0), 4 (diffuse factor, specular
// factor, light index, light-links rows: lib/light_links.glsl), 5-7 rows of world -> light local (mat3), then per RSM view k (k < 6) 5 texels from
// 8 + 5k: the rows of its view-projection matrix, then (perspective 1 / ortho 0, P00, P22, P23).
// camera: (position, 1) perspective or (direction towards the camera, 0) orthographic.
// shadow_params: (RSM size, normal offset in texels, depth bias in texels, shadows on 1 / off 0).

void main()
{
  ivec2 pixel = ivec2(gl_FragCoord.xy);
  GBufferTexel g = gbuffer_load(pixel);
  direct_diffuse = vec4(0.0);
  direct_glossy = vec4(0.0);
  if (g.coverage < 0.5) {
    return;
  }
  vec4 factors = light_constant(4);
  // Light linking: an object outside the light's receivers gets none of its light.
  if (light_links_fetch(light_links, int(factors.w + 0.5), int(factors.z + 0.5), g.object_index).x < 0.5) {
    return;
  }
  vec3 normal = g.normal;
  vec3 outgoing = camera.w > 0.5 ? camera.xyz - g.position : camera.xyz;
  outgoing = safe_normalize(outgoing, normal);

  vec4 light0 = light_constant(0);
  vec3 light_position = light0.xyz;
  int view_count = int(light0.w + 0.5);
  vec3 light_axis = light_constant(1).xyz;
  vec4 params = light_constant(2);
  vec3 color = light_constant(3).rgb;
  mat3 light_to_local = transpose(mat3(light_constant(5).xyz, light_constant(6).xyz,
                                       light_constant(7).xyz));

  vec3 incoming;
  float irradiance = direct_light_irradiance(params, light_position, light_axis, light_to_local,
                                             g.position, normal, incoming);
  if (!(irradiance > 0.0)) {
    return;
  }
  if (shadow_params.w > 0.5) {
    irradiance *= direct_light_visibility(g.position, normal, incoming, view_count);
    if (!(irradiance > 0.0)) {
      return;
    }
  }
  PrincipledTerms terms = principled_terms(g.base_color, g.metallic, g.specular_ior_level, g.ior,
                                           g.roughness, dot(normal, outgoing));
  vec3 diffuse, glossy;
  direct_light_radiance(terms, incoming, outgoing, normal, irradiance, diffuse, glossy);
  direct_diffuse = vec4(diffuse * color * factors.x, 0.0);
  direct_glossy = vec4(glossy * color * factors.y, 0.0);
}
