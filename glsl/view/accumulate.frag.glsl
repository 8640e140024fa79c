// Adds (by blending) or copies one set of view images into another of the same size, times `weight`
// (vsgl_addon/view_gpu.py: a finished progressive sample into the running sum).
void main()
{
  ivec2 pixel = ivec2(gl_FragCoord.xy);
  out_direct = texelFetch(source_direct, pixel, 0) * weight;
  out_indirect_diffuse = texelFetch(source_indirect_diffuse, pixel, 0) * weight;
  out_indirect_specular = texelFetch(source_indirect_specular, pixel, 0) * weight;
  out_indirect_caustics = texelFetch(source_indirect_caustics, pixel, 0) * weight;
  out_indirect_glossy_reflectors = texelFetch(source_indirect_glossy_reflectors, pixel, 0) * weight;
}
