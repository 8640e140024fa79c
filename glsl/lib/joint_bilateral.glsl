// Joint (cross) bilateral upsampling (Kopf, Cohen, Lischinski, Uyttendaele, "Joint bilateral
// upsampling", SIGGRAPH 2007, eq. 2): a low-resolution image is resampled at a full-resolution pixel
// with the bilinear weights of its four nearest texels, each times a range weight that compares the
// full-resolution guide (world position and normal) with the guide the low-resolution image was
// rendered with. A texel of another surface (across a silhouette or a crease) gets no weight, so
// edges follow the full-resolution G-buffer instead of the low-resolution texel grid.
// Float64 twin: vsgl_addon/reference/joint_bilateral.py (same names).
//
// Guides: position.rgb world position, position.a coverage (> 0: geometry); normal.rgb unit normal.
// `footprint`: world size of one low-resolution texel at the pixel; positions are compared in units
// of it (sigma_position footprints is one standard deviation). `normal_power`: the normal weight is
// max(n . n_i, 0)^normal_power (> 0).

// Below this total weight the four nearest texels are taken to show other surfaces.
#define JBU_MIN_WEIGHT 1e-3

float jbu_range_weight(vec3 position, vec3 normal, vec4 low_position, vec4 low_normal, float footprint,
                       float sigma_position, float normal_power)
{
  if (low_position.a <= 0.0) {
    return 0.0;
  }
  vec3 d = (position - low_position.xyz) / max(footprint * sigma_position, 1e-30);
  float c = dot(normal, low_normal.xyz);
  float wn = c > 0.0 ? pow(c, normal_power) : 0.0;
  return exp(-0.5 * min(dot(d, d), 1e4)) * wn;
}

// The upsampled value of `low` at texture coordinates `uv` of a pixel whose guide is (position,
// normal). Falls back to the best-matching geometry texel of the 4x4 neighbourhood when the four
// nearest all show other surfaces (a thin feature the low image missed), and to zero when none of
// the sixteen is geometry.
vec4 joint_bilateral_upsample(sampler2D low, sampler2D low_position, sampler2D low_normal, vec2 uv,
                              vec3 position, vec3 normal, float footprint, float sigma_position,
                              float normal_power)
{
  ivec2 size = textureSize(low, 0);
  vec2 q = uv * vec2(size) - 0.5;
  vec2 base_f = floor(q);
  vec2 f = q - base_f;
  ivec2 base = ivec2(base_f);
  ivec2 hi = size - 1;
  vec4 sum = vec4(0.0);
  float weight_sum = 0.0;
  for (int k = 0; k < 4; k++) {
    ivec2 o = ivec2(k & 1, k >> 1);
    ivec2 t = clamp(base + o, ivec2(0), hi);
    float ws = (o.x == 0 ? 1.0 - f.x : f.x) * (o.y == 0 ? 1.0 - f.y : f.y);
    float w = ws * jbu_range_weight(position, normal, texelFetch(low_position, t, 0),
                                    texelFetch(low_normal, t, 0), footprint, sigma_position, normal_power);
    sum += w * texelFetch(low, t, 0);
    weight_sum += w;
  }
  if (weight_sum > JBU_MIN_WEIGHT) {
    return sum / weight_sum;
  }
  float best = 0.0;
  vec4 pick = vec4(0.0);
  for (int j = -1; j <= 2; j++) {
    for (int i = -1; i <= 2; i++) {
      ivec2 t = clamp(base + ivec2(i, j), ivec2(0), hi);
      vec4 p = texelFetch(low_position, t, 0);
      if (p.a <= 0.0) {
        continue;
      }
      // Four times wider in position, plus a tie-break towards the nearest texel.
      vec2 dt = vec2(t) - q;
      float w = jbu_range_weight(position, normal, p, texelFetch(low_normal, t, 0), footprint,
                                 4.0 * sigma_position, normal_power) + 1e-6 / (1.0 + dot(dt, dt));
      if (w > best) {
        best = w;
        pick = texelFetch(low, t, 0);
      }
    }
  }
  return pick;
}

// World size of one low-resolution texel at `position`: the vertical extent of the view over
// `low_height` texels, at the pixel's distance for a perspective camera. `camera` is (position, 1)
// perspective or (direction towards the camera, 0) orthographic; `projection_11` the projection's
// [1][1] (cot of half the vertical field of view, or 2 / the orthographic height).
float jbu_footprint(vec4 camera, vec3 position, float projection_11, float low_height)
{
  float extent = 2.0 / (max(abs(projection_11), 1e-30) * max(low_height, 1.0));
  return camera.w > 0.5 ? distance(camera.xyz, position) * extent : extent;
}
