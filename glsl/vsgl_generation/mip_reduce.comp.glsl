// @require lib/mip_atlas.glsl
//
// One mip level >= 2 of every plane (invocation z = plane): each texel of level `level` is the mean
// of its 2x2 children in level `level - 1` of the atlas (reference `mipmap.build_mip_chain`, same
// order of additions: 0.25 (((m00 + m01) + m10) + m11)). Successive levels are successive
// dispatches (gpu.compute.dispatch puts a memory barrier between them). Level 1 comes from
// mip_reduce_level1.frag.glsl.

void main()
{
  ivec3 id = ivec3(gl_GlobalInvocationID);
  int width = rsm_size >> level;
  int plane = id.z;
  if (id.x >= width || id.y >= width || plane >= MIP_PLANES) {
    return;
  }
  ivec2 child = 2 * id.xy;
  ivec2 source = mip_atlas_origin(rsm_size, level - 1, plane) + child;
  vec4 m00 = imageLoad(mip_atlas, source);
  vec4 m01 = imageLoad(mip_atlas, source + ivec2(1, 0));
  vec4 m10 = imageLoad(mip_atlas, source + ivec2(0, 1));
  vec4 m11 = imageLoad(mip_atlas, source + ivec2(1, 1));
  precise vec4 sum = ((m00 + m01) + m10) + m11;
  precise vec4 mean = 0.25 * sum;
  imageStore(mip_atlas, mip_atlas_origin(rsm_size, level, plane) + id.xy, mean);
}
