// @require lib/bilateral.glsl
// @require view/resolved_images.glsl
// glsl/view/resolve.frag.glsl with the weights of jbu_weights.frag.glsl, kept from an earlier
// render of the same size, view and triangles (vsgl_addon/view_gpu.py, ViewGuide): the same
// texels, weights and arithmetic, so the same floats, without the guides' reads and the range
// weights. `taps` and `weights` have the guide's size; the render's six images are read as images.
void main()
{
  ivec2 size = imageSize(taps);
  ivec2 pixel = clamp(ivec2(uv * vec2(size)), ivec2(0), size - 1);
  vec4 tap = imageLoad(taps, pixel);
  float coverage = clamp(tap.w, 0.0, 1.0);
  if (coverage <= 0.0) {
    write_uncovered();
    return;
  }
  JBUWeights jw;
  jw.base = ivec2(tap.xy);
  jw.pick = jw.base;
  jw.weights = imageLoad(weights, pixel);
  jw.weight_sum = tap.z;
  jw.kind = 0;
  write_resolved(jw, coverage);
}
