// Adds (by blending) or copies one set of view images into another of the same size, times `weight`
// (vsgl_addon/view_gpu.py: a finished progressive sample into the running sum), read as images.
void main()
{
  ivec2 pixel = ivec2(gl_FragCoord.xy);
  out_direct = imageLoad(source_direct, pixel) * weight;
  out_indirect_diffuse = imageLoad(source_indirect_diffuse, pixel) * weight;
  out_indirect_specular = imageLoad(source_indirect_specular, pixel) * weight;
  out_indirect_caustics = imageLoad(source_indirect_caustics, pixel) * weight;
  out_indirect_glossy_reflectors = imageLoad(source_indirect_glossy_reflectors, pixel) * weight;
}
