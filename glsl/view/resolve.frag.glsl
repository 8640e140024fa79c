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
  ivec2 pixel = clamp(ivec2(uv * vec2(textureSize(guide_position, 0))), ivec2(0),
                      textureSize(guide_position, 0) - 1);
  vec4 position = texelFetch(guide_position, pixel, 0);
  vec3 normal = texelFetch(guide_normal, pixel, 0).xyz;
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
