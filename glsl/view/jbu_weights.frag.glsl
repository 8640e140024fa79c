// @require lib/bilateral.glsl
// The joint bilateral upsampler's weights (lib/bilateral.glsl, jbu_weights) at every pixel of a
// viewport's full-resolution guide, for the view renders of `low_position`'s size: what
// glsl/view/resolve.frag.glsl computes per pixel before applying them. They depend on the two
// guides alone, so a viewport keeps them while its view and triangles stay (vsgl_addon/view_gpu.py,
// ViewGuide): the coarse image after a light, material or setting change is then
// resolve_weighted.frag.glsl alone. Outputs out_taps = (base.x, base.y, weight sum, coverage),
// out_weights = the four texels' weights; an uncovered pixel (coverage 0) gets no weight.
void main()
{
  vec4 position;
  vec3 normal;
  jbu_guide_texel(guide_position, guide_normal, uv, position, normal);
  float coverage = clamp(position.a, 0.0, 1.0);
  if (coverage <= 0.0) {
    out_taps = vec4(0.0, 0.0, 1.0, 0.0);
    out_weights = vec4(0.0);
    return;
  }
  float footprint = jbu_footprint(camera, position.xyz, projection_11, float(imageSize(low_position).y));
  JBUWeights jw = jbu_weights(low_position, low_normal, uv, position.xyz, normal, footprint, sigma_position,
                              normal_power);
  // The base texel's integer coordinates are exact in float32 (sides up to 16384).
  out_taps = vec4(vec2(jw.base), jw.weight_sum, coverage);
  out_weights = jw.weights;
}
