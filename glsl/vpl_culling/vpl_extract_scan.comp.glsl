// @require lib/prefix_sum.glsl
//
// The exclusive prefix sum of one RSM view's run counts (vpl_extract.comp.glsl) in one work group:
// run r's first slot = the VPLs before this view (vpl_count) + the kept texels of runs 0 .. r - 1.
// Invocation i sums a contiguous range of runs, one work-group sum (lib/prefix_sum.glsl) gives each
// range its start, and the range is written in order: a fixed number of barriers at any RSM size.
// vpl_count then holds the VPLs so far; it stays on the GPU, where the culling stage reads it.
// scan_sizes = (runs, run table width).
ivec2 run_texel(int run)
{
  return ivec2(run % scan_sizes.y, run / scan_sizes.y);
}

void main()
{
  uint local = gl_LocalInvocationIndex;
  int runs = scan_sizes.x;
  int per = (runs + PREFIX_SUM_SIZE - 1) / PREFIX_SUM_SIZE;
  int first = int(local) * per;
  int last = min(first + per, runs);
  uint sum = 0u;
  for (int r = first; r < last; r++) {
    sum += imageLoad(vpl_run_counts, run_texel(r)).x;
  }
  // The running total enters the sum as invocation 0's addend: one invocation reads it, and its value
  // is in shared memory before the first barrier, so the write at the end (after the barriers) cannot
  // overtake the read on any GPU (image loads are not ordered by barrier() alone).
  uint base = local == 0u ? imageLoad(vpl_count, ivec2(0)).x : 0u;
  uint inclusive = workgroup_inclusive_sum(sum + base, local);
  uint offset = inclusive - sum;
  for (int r = first; r < last; r++) {
    uint count = imageLoad(vpl_run_counts, run_texel(r)).x;
    imageStore(vpl_run_offsets, run_texel(r), uvec4(offset));
    offset += count;
  }
  if (local == uint(PREFIX_SUM_SIZE - 1)) {
    imageStore(vpl_count, ivec2(0), uvec4(inclusive));
  }
}
