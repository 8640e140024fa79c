// @require lib/bilateral.glsl
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
    out_direct = vec4(0.0);
    out_indirect_diffuse = vec4(0.0);
    out_indirect_specular = vec4(0.0);
    out_indirect_caustics = vec4(0.0);
    out_indirect_glossy_reflectors = vec4(0.0);
    return;
  }
  float footprint = jbu_footprint(camera, position.xyz, projection_11, float(imageSize(low_position).y));
  // One set of weights for the six images: they share the render's low-resolution guide.
  JBUWeights jw = jbu_weights(low_position, low_normal, uv, position.xyz, normal, footprint, sigma_position,
                              normal_power);
  vec4 dd = jbu_apply(jw, low_direct_diffuse);
  vec4 ds = jbu_apply(jw, low_direct_specular);
  vec4 id = jbu_apply(jw, low_indirect_diffuse);
  vec4 is = jbu_apply(jw, low_indirect_specular);
  vec4 ic = jbu_apply(jw, low_indirect_caustics);
  vec4 ir = jbu_apply(jw, low_indirect_glossy_reflectors);
  // No NaN or Inf may reach a pixel.
  vec3 direct = dd.rgb + ds.rgb;
  direct = all(lessThan(abs(direct), vec3(1e30))) ? direct : vec3(0.0);
  vec3 diffuse = all(lessThan(abs(id.rgb), vec3(1e30))) ? id.rgb : vec3(0.0);
  vec3 specular = all(lessThan(abs(is.rgb), vec3(1e30))) ? is.rgb : vec3(0.0);
  out_direct = vec4(direct, coverage) * weight;
  out_indirect_diffuse = vec4(diffuse, coverage) * weight;
  out_indirect_specular = vec4(specular, coverage) * weight;
  vec3 caustics = all(lessThan(abs(ic.rgb), vec3(1e30))) ? ic.rgb : vec3(0.0);
  out_indirect_caustics = vec4(caustics, coverage) * weight;
  vec3 reflectors = all(lessThan(abs(ir.rgb), vec3(1e30))) ? ir.rgb : vec3(0.0);
  out_indirect_glossy_reflectors = vec4(reflectors, coverage) * weight;
}
