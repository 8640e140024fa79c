// Shadow-map visibility of a point from one light view: the point's depth along the view against
// the depth the view's shadow map stores (the RSM's depth attachment, formulas.md sec. 4; 000 sec. 4
// keeps it "for shadows"). Used by the direct light (glsl/direct_light/direct_light.frag.glsl),
// which picks the view and reads its depth texture. Float64 twin:
// vsgl_addon/reference/direct_light.py (same names).
//
// A view's `projection` is (perspective 1 / orthographic 0, P00, P22, P23) of its OpenGL projection
// matrix P; `size` is its side in texels.

// Largest tan of the incidence angle the slope-scaled bias follows (grazing light stops growing it).
const float SHADOW_MAX_SLOPE = 8.0;

// Linear depth along the view's axis from window depth (perspective or orthographic).
float shadow_linear_depth(float window_depth, vec4 projection)
{
  float ndc = window_depth * 2.0 - 1.0;
  if (projection.x > 0.5) {
    return projection.w / (ndc + projection.z);  // d = P23 / (ndc + P22)
  }
  return (projection.w - ndc) / projection.z;  // d = -z = (P23 - ndc) / P22
}

// tan of the angle between the unit `normal` and the unit direction `incoming` towards the light.
float shadow_tan_incidence(vec3 normal, vec3 incoming)
{
  float cos_theta = clamp(dot(normal, incoming), 0.0, 1.0);
  return sqrt(max(1.0 - cos_theta * cos_theta, 0.0)) / max(cos_theta, 1e-3);
}

// Where `position` (unit `normal`) falls in a view: false when it lies outside the view's frustum.
// Else `texel` is the shadow-map texel to read, of the point pushed along its normal by
// `normal_offset` texels of the view's footprint at the point, `at` that point's continuous
// coordinate in texels (texel centres at integer + 0.5; the filtered test's input), `receiver` its
// linear depth and `bias` the depth tolerance: `depth_bias` texels times (1 + tan theta), tan theta
// capped.
bool shadow_map_lookup(mat4 view_projection, vec4 projection, float size, float normal_offset,
                       float depth_bias, float tan_theta, vec3 position, vec3 normal,
                       out ivec2 texel, out vec2 at, out float receiver, out float bias)
{
  texel = ivec2(0);
  at = vec2(0.0);
  receiver = 0.0;
  bias = 0.0;
  vec4 clip = view_projection * vec4(position, 1.0);
  if (!(clip.w > 0.0)) {
    return false;
  }
  vec3 ndc = clip.xyz / clip.w;
  if (any(greaterThan(abs(ndc), vec3(1.0)))) {
    return false;
  }
  float texel_world = 2.0 * clip.w / (projection.y * size);
  vec3 offset_position = position + normal * (normal_offset * texel_world);
  vec4 offset_clip = view_projection * vec4(offset_position, 1.0);
  vec3 offset_ndc = offset_clip.xyz / max(offset_clip.w, 1e-30);
  at = (offset_ndc.xy * 0.5 + 0.5) * size;
  texel = clamp(ivec2(floor(at)), ivec2(0), ivec2(int(size) - 1));
  receiver = shadow_linear_depth(offset_ndc.z * 0.5 + 0.5, projection);
  bias = depth_bias * texel_world * (1.0 + min(tan_theta, SHADOW_MAX_SLOPE));
  return true;
}

// 1 when nothing the view stored (window depth `stored`, 1 = nothing) lies in front of the
// receiver beyond the bias, 0 in shadow.
float shadow_map_test(float stored, vec4 projection, float receiver, float bias)
{
  if (stored >= 1.0) {
    return 1.0;  // the view saw nothing there: nothing occludes
  }
  float occluder = shadow_linear_depth(stored, projection);
  return receiver <= occluder + bias ? 1.0 : 0.0;
}

// Bilinear percentage-closer filtering (PCF; Reeves, Salesin and Cook 1987, bilinear weights as in
// hardware shadow-map comparison): the 2x2 texels whose centres surround `at` (from
// shadow_map_lookup), each tested against the one receiver depth and the results weighted
// bilinearly. A shadow edge becomes a ramp one texel wide instead of the nearest texel's staircase;
// inside a lit or a shadowed region the result is the nearest texel's. `first`: the lower-left tap
// (the others are +x, +y, +xy; the caller clamps each to the map), `fraction` the weights' (x, y).
ivec2 shadow_pcf_first(vec2 at, out vec2 fraction)
{
  vec2 corner = floor(at - 0.5);
  fraction = (at - 0.5) - corner;
  return ivec2(corner);
}

// The bilinear PCF of the four taps' stored window depths (order: first, +x, +y, +xy).
float shadow_map_test_bilinear(vec4 stored, vec2 fraction, vec4 projection, float receiver, float bias)
{
  float lit_00 = shadow_map_test(stored.x, projection, receiver, bias);
  float lit_10 = shadow_map_test(stored.y, projection, receiver, bias);
  float lit_01 = shadow_map_test(stored.z, projection, receiver, bias);
  float lit_11 = shadow_map_test(stored.w, projection, receiver, bias);
  return mix(mix(lit_00, lit_10, fraction.x), mix(lit_01, lit_11, fraction.x), fraction.y);
}
