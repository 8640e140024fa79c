// Cross-bilateral filter guided by the G-buffer's position and normal (004 section 6: it removes
// the N x N interleaving pattern, radius 8 there). Twin: vsgl_addon/reference/bilateral.py.
// Weight of neighbour q for pixel p (both covered, position.w > 0):
//   exp(-|q - p|^2 / (2 s^2)), s = radius / 2 (space)
//   * exp(-(n_p . (x_q - x_p) / (sigma_plane * |x_p - eye|))^2) (off p's tangent plane, relative to depth)
//   * (n_p . n_q)^normal_power where n_p . n_q > 0, else 0 (normals)
// Uncovered pixels pass through as 0; the centre's weight is 1, so the sum is never 0.
vec3 cross_bilateral(sampler2D image, sampler2D guide_position, sampler2D guide_normal, ivec2 pixel, int radius,
                     vec3 eye, float sigma_plane, float normal_power)
{
  ivec2 size = textureSize(image, 0);
  vec4 centre = texelFetch(guide_position, pixel, 0);
  if (centre.w <= 0.0) {
    return vec3(0.0);
  }
  vec3 n = texelFetch(guide_normal, pixel, 0).xyz;
  float scale = sigma_plane * max(length(centre.xyz - eye), 1e-30);
  float inv_space = 1.0 / (0.5 * float(max(radius, 1)) * 0.5 * float(max(radius, 1)) * 2.0);
  vec3 sum = vec3(0.0);
  float weight_sum = 0.0;
  for (int dy = -radius; dy <= radius; dy++) {
    for (int dx = -radius; dx <= radius; dx++) {
      ivec2 q = pixel + ivec2(dx, dy);
      if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) {
        continue;
      }
      vec4 position = texelFetch(guide_position, q, 0);
      if (position.w <= 0.0) {
        continue;
      }
      float plane = dot(n, position.xyz - centre.xyz) / scale;
      float facing = max(dot(n, texelFetch(guide_normal, q, 0).xyz), 0.0);
      // pow(0, 0) is undefined in GLSL: a neighbour facing away or edge-on gets no weight.
      float w = facing > 0.0 ? exp(-float(dx * dx + dy * dy) * inv_space - plane * plane) * pow(facing, normal_power) : 0.0;
      sum += w * texelFetch(image, q, 0).rgb;
      weight_sum += w;
    }
  }
  return sum / weight_sum;
}
