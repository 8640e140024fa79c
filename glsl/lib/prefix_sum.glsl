// Inclusive prefix sum over one work group of PREFIX_SUM_SIZE invocations (Hillis and Steele 1986),
// in the shared array `prefix_sum_values[PREFIX_SUM_SIZE]` the shader's interface declares (Blender
// 5.2 keeps `shared` only in typedef_source). Every invocation of the group must call it (barriers).
// Exact in uint (the VPL extraction's stream compaction keeps the texels' order with it).

uint workgroup_inclusive_sum(uint value, uint local)
{
  prefix_sum_values[local] = value;
  barrier();
  for (uint step = 1u; step < uint(PREFIX_SUM_SIZE); step <<= 1u) {
    uint earlier = local >= step ? prefix_sum_values[local - step] : 0u;
    barrier();
    prefix_sum_values[local] += earlier;
    barrier();
  }
  return prefix_sum_values[local];
}
