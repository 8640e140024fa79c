// @require lib/vpl_extraction.glsl
// @require lib/vpl_clusters.glsl
// @require lib/ism.glsl
//
// The splat's table of the VPL clusters' imperfect shadow maps, one RSM view at a time, on the GPU
// (vsgl_addon/passes/vpl_culling.py cluster_view; twin: reference/vpl_clusters.py
// vpl_cluster_origins): one work group per VPL_CLUSTER_TEXELS^2 block, one invocation per texel, the
// texel a VPL when glossy_vpl_from_texel keeps it (the extraction's test). Three work-group
// reductions in shared memory: the Phi-weighted sums of position and normal (weight max(Phi Rs) +
// VPL_CLUSTER_WEIGHT_FLOOR), then the weighted squared spread about the mean (two passes, as the
// reference: no cancellation), then the highest VPL above the origin along the mean normal.
// Column m = vpl_cluster_map of ism_origins (passes/ism.py MapOrigins): row 0 the origin (a VSGL
// lobe's ism_shadow_origin of the mean, variance per axis, mean normal), w left for
// vpl_cluster_sets.comp.glsl's point set; row 1 (min distance = cluster_params.y sigma, 1 = occupied);
// row 2 the half-space (mean normal, highest VPL's height + cluster_params.z: reference
// cluster_planes). A block without a VPL: min distance VPL_EMPTY_CLUSTER_DISTANCE (no point kept),
// half-space 0, occupied 0.
// cluster_sizes = (RSM side, view index); cluster_light = the light (reference light_vector);
// cluster_params = (caustic roughness, own reflector sigmas, plane slack).
const uint CLUSTER_INVOCATIONS = uint(VPL_CLUSTER_TEXELS * VPL_CLUSTER_TEXELS);

// Sums of (value_a, value_b) over the work group (a tree in shared memory; every invocation calls it).
void cluster_sum(inout vec4 value_a, inout vec4 value_b, uint local)
{
  cluster_sums_a[local] = value_a;
  cluster_sums_b[local] = value_b;
  barrier();
  for (uint width = CLUSTER_INVOCATIONS / 2u; width > 0u; width >>= 1u) {
    if (local < width) {
      cluster_sums_a[local] += cluster_sums_a[local + width];
      cluster_sums_b[local] += cluster_sums_b[local + width];
    }
    barrier();
  }
  value_a = cluster_sums_a[0];
  value_b = cluster_sums_b[0];
  barrier();  // every invocation has read the sums before the next reduction writes
}

void main()
{
  uint local = gl_LocalInvocationIndex;
  int side = cluster_sizes.x;
  ivec2 texel = ivec2(gl_WorkGroupID.xy) * VPL_CLUSTER_TEXELS + ivec2(gl_LocalInvocationID.xy);
  bool inside = texel.x < side && texel.y < side;
  vec4 record0 = vec4(0.0), record1 = vec4(0.0), record2, record3;
  bool kept = false;
  if (inside) {
    kept = glossy_vpl_from_texel(texelFetch(rsm_position, texel, 0), texelFetch(rsm_normal, texel, 0),
                                 texelFetch(rsm_flux_specular, texel, 0), cluster_light, cluster_params.x,
                                 record0, record1, record2, record3);
  }
  float weight = kept ? record1.w + VPL_CLUSTER_WEIGHT_FLOOR : 0.0;
  vec4 sums = vec4(weight * record0.xyz, weight);
  vec4 normal_sum = vec4(weight * record1.xyz, kept ? 1.0 : 0.0);
  cluster_sum(sums, normal_sum, local);
  bool occupied = normal_sum.w > 0.5;
  float total = occupied ? sums.w : 1.0;
  vec3 mean = sums.xyz / total;
  vec3 offset = record0.xyz - mean;
  vec4 spread = vec4(weight * dot(offset, offset), 0.0, 0.0, 0.0);
  vec4 unused = vec4(0.0);
  cluster_sum(spread, unused, local);
  float variance = spread.x / total / 3.0;  // per axis, as a VSGL's sigma_v^2
  vec3 axis = normal_sum.xyz / max(length(normal_sum.xyz), 1e-30);
  vec3 origin = ism_shadow_origin(mean, variance, axis);
  // The highest VPL: a max-reduction on the same tree (no float atomics).
  float height = kept ? dot(record0.xyz - origin, axis) : -VPL_EMPTY_CLUSTER_DISTANCE;
  cluster_sums_a[local] = vec4(height);
  barrier();
  for (uint width = CLUSTER_INVOCATIONS / 2u; width > 0u; width >>= 1u) {
    if (local < width) {
      cluster_sums_a[local] = max(cluster_sums_a[local], cluster_sums_a[local + width]);
    }
    barrier();
  }
  if (local == 0u) {
    int map_index = vpl_cluster_map(texel, cluster_sizes.y, side);
    float sigma = sqrt(max(variance, 0.0));
    imageStore(ism_origins, ivec2(map_index, 0), vec4(occupied ? origin : vec3(0.0), 0.0));
    imageStore(ism_origins, ivec2(map_index, 1),
               vec4(occupied ? cluster_params.y * sigma : VPL_EMPTY_CLUSTER_DISTANCE, occupied ? 1.0 : 0.0, 0.0, 0.0));
    imageStore(ism_origins, ivec2(map_index, 2),
               occupied ? vec4(axis, cluster_sums_a[0].x + cluster_params.z) : vec4(0.0));
  }
}
