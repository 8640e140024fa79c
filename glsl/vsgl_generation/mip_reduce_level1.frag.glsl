// Level 1 of one plane, drawn into the atlas (glsl/lib/mip_atlas.glsl) with the viewport set to the
// plane's level-1 region starting at `target_origin`: each texel is the mean of its 2x2 children in
// the plane's level-0 texture `level0_source` (reference `mipmap.build_mip_chain`, same order of
// additions: 0.25 (((m00 + m01) + m10) + m11)). A fragment pass: render targets are the fast write
// path (on llvmpipe several times faster than compute image stores); the higher, smaller levels
// are reduced by mip_reduce.comp.glsl.

void main()
{
  ivec2 child = 2 * (ivec2(gl_FragCoord.xy) - target_origin);
  vec4 m00 = texelFetch(level0_source, child, 0);
  vec4 m01 = texelFetch(level0_source, child + ivec2(1, 0), 0);
  vec4 m10 = texelFetch(level0_source, child + ivec2(0, 1), 0);
  vec4 m11 = texelFetch(level0_source, child + ivec2(1, 1), 0);
  precise vec4 sum = ((m00 + m01) + m10) + m11;
  precise vec4 mean = 0.25 * sum;
  level1_out = mean;
}
