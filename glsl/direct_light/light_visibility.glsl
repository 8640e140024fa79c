// @require lib/shadow.glsl
//
// A light's shadow at a point from its RSM views, read from the direct light pass's per-light
// constants (vsgl_addon/passes/direct_light.py light_constants; layout in
// direct_light/direct_light.frag.glsl). A stage that requires this declares the samplers
// light_constants and rsm_depth_0 .. rsm_depth_5 and the push constant shadow_params
// (RSM size, normal offset in texels, depth bias in texels, shadows on 1 / off 0). Used by the
// direct light and by MRP-ASG at its specular peaks.

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

// The four depths of a bilinear PCF footprint (lib/shadow.glsl shadow_pcf_first), each tap
// clamped to the view's map.
vec4 view_depth_taps(int k, ivec2 first, int size)
{
  ivec2 last = ivec2(size - 1);
  return vec4(view_depth_texel(k, clamp(first, ivec2(0), last)),
              view_depth_texel(k, clamp(first + ivec2(1, 0), ivec2(0), last)),
              view_depth_texel(k, clamp(first + ivec2(0, 1), ivec2(0), last)),
              view_depth_texel(k, clamp(first + ivec2(1, 1), ivec2(0), last)));
}

// 1 when the RSM of the light sees `position` (or nothing in front of it), 0 in shadow, and
// between them within a texel of a shadow edge (bilinear PCF, lib/shadow.glsl); the first view
// whose frustum contains the point decides. Normal offset and depth bias scale with the view's
// texel footprint at the point. 0 when no view contains the point (outside a spot cone, behind an
// area light).
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
    vec2 at, fraction;
    float receiver, bias;
    if (!shadow_map_lookup(view_projection, projection, size, shadow_params.y, shadow_params.z,
                           tan_theta, position, normal, texel, at, receiver, bias)) {
      continue;
    }
    ivec2 first = shadow_pcf_first(at, fraction);
    return shadow_map_test_bilinear(view_depth_taps(k, first, int(size + 0.5)), fraction, projection,
                                    receiver, bias);
  }
  return 0.0;
}
