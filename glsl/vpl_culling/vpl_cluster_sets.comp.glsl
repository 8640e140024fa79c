// @require lib/prefix_sum.glsl
//
// The point sets of the VPL clusters' maps (twin: reference/vpl_clusters.py vpl_cluster_origins), in
// one work group after vpl_clusters.comp.glsl has filled every view's columns of ism_origins: map m
// splats set (first map + occupied maps before m) mod point sets (Ritschel et al. 2008 give
// neighbouring maps different subsets; counting only occupied maps gives each the set it has in a
// compacted list of clusters). Invocation i takes a contiguous range of maps and one work-group sum
// (lib/prefix_sum.glsl) gives the range its first rank. cluster_set_params = (maps, first map, point sets).
void main()
{
  uint local = gl_LocalInvocationIndex;
  int maps = cluster_set_params.x;
  int per = (maps + PREFIX_SUM_SIZE - 1) / PREFIX_SUM_SIZE;
  int first = int(local) * per;
  int last = min(first + per, maps);
  uint occupied = 0u;
  for (int m = first; m < last; m++) {
    occupied += imageLoad(ism_origins, ivec2(m, 1)).y > 0.5 ? 1u : 0u;
  }
  uint rank = workgroup_inclusive_sum(occupied, local) - occupied;
  for (int m = first; m < last; m++) {
    vec4 origin = imageLoad(ism_origins, ivec2(m, 0));
    origin.w = float((uint(cluster_set_params.y) + rank) % uint(cluster_set_params.z));
    imageStore(ism_origins, ivec2(m, 0), origin);
    rank += imageLoad(ism_origins, ivec2(m, 1)).y > 0.5 ? 1u : 0u;
  }
}
