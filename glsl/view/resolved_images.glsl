// The resolve's outputs (glsl/view/resolve.frag.glsl, resolve_weighted.frag.glsl): each image of a
// view render upsampled with one pixel's weights (lib/bilateral.glsl), times `weight`; rgb =
// radiance (Blender's units), a = the guide's coverage. Reads the render's low_* images and writes
// the out_* outputs of the shader that includes it.

void write_resolved(JBUWeights jw, float coverage)
{
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
  vec3 caustics = all(lessThan(abs(ic.rgb), vec3(1e30))) ? ic.rgb : vec3(0.0);
  vec3 reflectors = all(lessThan(abs(ir.rgb), vec3(1e30))) ? ir.rgb : vec3(0.0);
  out_direct = vec4(direct, coverage) * weight;
  out_indirect_diffuse = vec4(diffuse, coverage) * weight;
  out_indirect_specular = vec4(specular, coverage) * weight;
  out_indirect_caustics = vec4(caustics, coverage) * weight;
  out_indirect_glossy_reflectors = vec4(reflectors, coverage) * weight;
}

void write_uncovered()
{
  out_direct = vec4(0.0);
  out_indirect_diffuse = vec4(0.0);
  out_indirect_specular = vec4(0.0);
  out_indirect_caustics = vec4(0.0);
  out_indirect_glossy_reflectors = vec4(0.0);
}
