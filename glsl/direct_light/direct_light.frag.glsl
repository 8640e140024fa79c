// @require direct_light/light_at_surface.glsl
// @require lib/shadow.glsl
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

const int DIRECT_LIGHT_MAX_VIEWS = 6;

vec4 light_constant(int index)
{
  return texelFetch(light_constants, ivec2(index, 0), 0);
}

float view_depth_texel(int k, ivec2 texel)
{
  // Samplers cannot be indexed dynamically in every GLSL version: a switch.
  if (k == 0) return texelFetch(rsm_depth_0, texel, 0).r;
  if (k == 1) return texelFetch(rsm_depth_1, texel, 0).r;
  if (k == 2) return texelFetch(rsm_depth_2, texel, 0).r;
  if (k == 3) return texelFetch(rsm_depth_3, texel, 0).r;
  if (k == 4) return texelFetch(rsm_depth_4, texel, 0).r;
  return texelFetch(rsm_depth_5, texel, 0).r;
}

// 1 when the RSM of the light sees `position` (or nothing in front of it), 0 in shadow; the first
// view whose frustum contains the point decides (lib/shadow.glsl). Normal offset and depth bias
// scale with the view's texel footprint at the point. 0 when no view contains the point (outside a
// spot cone, behind an area light).
float direct_light_visibility(vec3 position, vec3 normal, vec3 incoming, int view_count)
{
  float size = shadow_params.x;
  float tan_theta = shadow_tan_incidence(normal, incoming);
  for (int k = 0; k < DIRECT_LIGHT_MAX_VIEWS; k++) {
    if (k >= view_count) {
      break;
    }
    int base = 8 + 5 * k;
    mat4 view_projection = transpose(mat4(light_constant(base), light_constant(base + 1),
                                          light_constant(base + 2), light_constant(base + 3)));
    vec4 projection = light_constant(base + 4);
    ivec2 texel;
    float receiver, bias;
    if (!shadow_map_lookup(view_projection, projection, size, shadow_params.y, shadow_params.z,
                           tan_theta, position, normal, texel, receiver, bias)) {
      continue;
    }
    return shadow_map_test(view_depth_texel(k, texel), projection, receiver, bias);
  }
  return 0.0;
}

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
