// @require lib/bilateral.glsl
// @require view/resolved_images.glsl
// One view sample (vsgl_addon/view_gpu.py) into the viewport's accumulation images: each image of a
// view render, upsampled to the guide's pixels by the joint bilateral filter (the identity when the
// render has the guide's resolution), times `weight`; the filter's weights are computed once per
// pixel for all six images. The render's eight textures are read as images (jbu_weights' image
// overloads; Blender binds at most 8 images per shader), the full-resolution guides as samplers
// (one texel each per pixel). Outputs rgb = radiance (Blender's units),
// a = the guide's coverage, all times `weight` (added by blending when accumulating).
void main()
{
  vec4 position;
  vec3 normal;
  jbu_guide_texel(guide_position, guide_normal, uv, position, normal);
  float coverage = clamp(position.a, 0.0, 1.0);
  if (coverage <= 0.0) {
    write_uncovered();
    return;
  }
  float footprint = jbu_footprint(camera, position.xyz, projection_11, float(imageSize(low_position).y));
  // One set of weights for the six images: they share the render's low-resolution guide.
  write_resolved(jbu_weights(low_position, low_normal, uv, position.xyz, normal, footprint, sigma_position,
                             normal_power),
                 coverage);
}
