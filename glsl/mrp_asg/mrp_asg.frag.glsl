// @require lib/math.glsl
// @require lib/mrp_asg.glsl
// @require lib/shadow.glsl
// @require direct_light/light_visibility.glsl
//
// Glossy interreflection from rectangle proxies with MRP-ASG (001), one light per draw, full screen
// over the camera G-buffer (position, normal + roughness attachments) and the shading inputs'
// specular F0 (generated loaders of vsgl_addon/layouts.py GBUFFER and SHADING_INPUTS); added by
// blending (ONE, ONE) into one RGBA32F target, alpha 0. Python side: vsgl_addon/passes/mrp_asg.py.
//
// proxy_table: the proxies this light reaches, one ProxyRecord per column (layouts.py PROXY_TABLE),
// mrp_params.y of them. light_constants: the direct light pass's per-light constants
// (passes/direct_light.py light_constants: position and view count, axis, params, colour,
// factors, world -> local rows, then per RSM view its view-projection rows and projection).
// mrp_params = (disk radius r_d in metres, proxy count, mode (lib/mrp_asg.glsl MRP_MODE_*),
// roughness is perceptual 1 / GGX alpha 0). shadow_params = (RSM size, normal offset, depth bias,
// shadows 1 / off 0), as the direct light's. receiver_range = (smallest, largest receiver GGX alpha
// MRP-ASG shades, -, -): other receivers get no light here and alpha 0 (the renderer gives them the
// proxies' light from the VSGLs instead); served receivers have alpha 1 (added over the lights).
//
// Visibility: the light's at each specular peak from its RSM depth, the direct light's test
// (direct_light/light_visibility.glsl: the first view containing the peak decides; a peak outside
// every view is unlit). From the peak to the receiver (001 assumes no occlusion), when
// mirror_params.x = 1: the receiver's shadow-map test in proxy i's tile of the light's mirror shadow
// map atlas (mirror_depth, tiles of mirror_params.y texels side by side; mirror_constants: 5
// texels per tile, view-projection rows then (perspective, P00, P22, P23);
// vsgl_addon/passes/mrp_visibility.py). A receiver outside the tile's frustum (its peak off the
// widened rectangle) is not shadowed there.

float mrp_mirror_visibility(int i, vec3 position, vec3 normal, vec3 peak)
{
  int base = 5 * i;
  mat4 view_projection = transpose(mat4(texelFetch(mirror_constants, ivec2(base, 0), 0),
                                        texelFetch(mirror_constants, ivec2(base + 1, 0), 0),
                                        texelFetch(mirror_constants, ivec2(base + 2, 0), 0),
                                        texelFetch(mirror_constants, ivec2(base + 3, 0), 0)));
  vec4 projection = texelFetch(mirror_constants, ivec2(base + 4, 0), 0);
  float size = mirror_params.y;
  float tan_theta = shadow_tan_incidence(normal, safe_normalize(peak - position, normal));
  ivec2 texel;
  vec2 at;
  float receiver, bias;
  if (!shadow_map_lookup(view_projection, projection, size, shadow_params.y, shadow_params.z, tan_theta,
                         position, normal, texel, at, receiver, bias)) {
    return 1.0;
  }
  float stored = texelFetch(mirror_depth, texel + ivec2(i * int(size + 0.5), 0), 0).r;
  return shadow_map_test(stored, projection, receiver, bias);
}

void main()
{
  ivec2 pixel = ivec2(gl_FragCoord.xy);
  glossy_reflectors = vec4(0.0);
  GBufferTexel g;
  gbuffer_unpack_position(texelFetch(gbuffer_position, pixel, 0), g);
  if (!(g.coverage > 0.0)) {
    return;
  }
  gbuffer_unpack_normal(texelFetch(gbuffer_normal, pixel, 0), g);
  vec3 normal = safe_normalize(g.normal, vec3(0.0, 0.0, 1.0));
  float roughness = mrp_params.w > 0.5 ? g.roughness * g.roughness : g.roughness;
  if (!(roughness >= receiver_range.x && roughness <= receiver_range.y)) {
    return;
  }
  vec3 view = safe_normalize(camera.w > 0.0 ? camera.xyz - g.position : camera.xyz, normal);
  ShadingInputs inputs = shading_inputs_load(pixel);

  vec4 light0 = light_constant(0);
  int view_count = int(light0.w + 0.5);
  vec3 light_axis = light_constant(1).xyz;
  vec4 params = light_constant(2);
  vec3 color = light_constant(3).rgb * light_constant(4).y;  // Blender's glossy factor of the light
  mat3 light_to_local = transpose(mat3(light_constant(5).xyz, light_constant(6).xyz, light_constant(7).xyz));
  bool sun = int(params.x + 0.5) == LIGHT_SUN;

  vec3 sum = vec3(0.0);
  int count = int(mrp_params.y + 0.5);
  for (int i = 0; i < count; i++) {
    ProxyRecord p = proxy_table_load(i);
    vec3 radiance, peak;
    if (!mrp_shade(g.position, normal, view, roughness, inputs.specular_f0, p.center, p.normal, p.axis_u,
                   p.axis_v, p.half_u, p.half_v, p.alpha, p.f0, light0.xyz, light_axis, params,
                   light_to_local, mrp_params.x, int(mrp_params.z + 0.5), radiance, peak)) {
      continue;
    }
    if (shadow_params.w > 0.5 && dot(radiance, radiance) > 0.0) {
      vec3 incoming = sun ? -light_axis : safe_normalize(light0.xyz - peak, p.normal);
      radiance *= direct_light_visibility(peak, p.normal, incoming, view_count);
    }
    if (mirror_params.x > 0.5 && dot(radiance, radiance) > 0.0) {
      radiance *= mrp_mirror_visibility(i, g.position, normal, peak);
    }
    sum += radiance;
  }
  glossy_reflectors = vec4(sum * color, 1.0);
}
