// @require lib/vpl_extraction.glsl
// @require lib/vpl_clusters.glsl
//
// The glossy VPLs of one RSM view on the GPU (004 section 3; twin: reference/vpl_culling.py
// extract_glossy_vpls), a stream compaction in texel order. Texel t = x + side y (row-major) belongs
// to run t / VPL_EXTRACT_RUN; one invocation walks one run's texels in order, with no shared memory
// and no barrier (llvmpipe pays for each barrier of every work group).
// VPL_EXTRACT_WRITE 0: the run's number of kept texels (glossy_vpl_from_texel) into vpl_run_counts;
// vpl_extract_scan.comp.glsl then turns the counts into each run's first slot.
// VPL_EXTRACT_WRITE 1: each kept texel's records into the culling table from the run's first slot on:
// the CPU's order (flatnonzero), so every VPL keeps its index and its xi. Nothing is resampled: the
// set is as stable as the RSM.
// extract_sizes = (RSM side, table capacity in VPLs, table width W, run table width); record k of
// slot i goes to texel (i % W, 4 (i / W) + k), as passes/vpl_culling.py vpl_table lays it out; run r's
// count and slot are texel (r % run table width, r / run table width). extract_params = (alpha_c, the
// view's index among the frame's VPL views, or -1): with an index, record 3's w is the VPL's shadow
// map (vpl_cluster_map, lib/vpl_clusters.glsl), which the culling's visibility lookup reads.
void main()
{
  int side = extract_sizes.x;
  int run = int(gl_GlobalInvocationID.x);
  int first = run * VPL_EXTRACT_RUN;
  if (first >= side * side) {
    return;
  }
  int last = min(first + VPL_EXTRACT_RUN, side * side);
  ivec2 run_texel = ivec2(run % extract_sizes.w, run / extract_sizes.w);
#if VPL_EXTRACT_WRITE
  uint slot = imageLoad(vpl_run_offsets, run_texel).x;
  int width = extract_sizes.z;
#else
  uint kept = 0u;
#endif
  for (int t = first; t < last; t++) {
    ivec2 texel = ivec2(t % side, t / side);
    vec4 record0, record1, record2, record3;
    if (glossy_vpl_from_texel(texelFetch(rsm_position, texel, 0), texelFetch(rsm_normal, texel, 0),
                              texelFetch(rsm_flux_specular, texel, 0), extract_light, extract_params.x,
                              record0, record1, record2, record3)) {
#if VPL_EXTRACT_WRITE
      if (extract_params.y >= 0.0) {
        record3.w = float(vpl_cluster_map(texel, int(extract_params.y), side));
      }
      if (slot < uint(extract_sizes.y)) {
        ivec2 origin = ivec2(int(slot) % width, 4 * (int(slot) / width));
        imageStore(vpl_table_out, origin, record0);
        imageStore(vpl_table_out, origin + ivec2(0, 1), record1);
        imageStore(vpl_table_out, origin + ivec2(0, 2), record2);
        imageStore(vpl_table_out, origin + ivec2(0, 3), record3);
      }
      slot++;
#else
      kept++;
#endif
    }
  }
#if !VPL_EXTRACT_WRITE
  imageStore(vpl_run_counts, run_texel, uvec4(kept));
#endif
}
