// @require lib/ism.glsl
//
// Imperfect shadow maps, gap closing (twin: reference/ism.py close_gaps): between the splat and
// pull-push, a texel whose nearest depths within ISM_GAP_REACH texels on both sides along a row,
// column or diagonal are nearer than (1 - ISM_GAP_MARGIN) times its own takes the farther of those
// two (the least over the four lines): holes in a near occluder, through which the points behind
// it show, close; silhouettes, with the background on one side only, stay. One invocation per
// texel of the R32UI atlas (tiles of side ism_size, octahedral wrap inside each), written into a
// second R32UI atlas. Empty texels (0xFFFFFFFF) are infinitely far. With ism_continued != 0, each
// side's surface is continued to the texel as a plane before the comparison (reference close_gaps
// ``continued``).
float ism_close_depth(ivec2 tile, ivec2 local, int size)
{
  uint bits = imageLoad(ism_splatted, tile + octahedral_wrap(local, size)).r;
  return bits == 0xFFFFFFFFu ? 3.0e38 : uintBitsToFloat(bits);
}

// |q| of the texel's centre, q = d / |d|_1 its direction's point on the octahedron (reference
// close_gaps' scale).
float ism_close_scale(ivec2 local, int size)
{
  vec3 d = octahedral_decode((vec2(octahedral_wrap(local, size)) + 0.5) / float(size) * 2.0 - 1.0);
  return 1.0 / (abs(d.x) + abs(d.y) + abs(d.z));
}

// The depth at `local` of the surface seen `at` and at + 1 texels away along `step`, continued as a
// plane (reference _plane_continued: |q| / depth is linear in the texel coordinates on a face of
// the octahedron); 3e38 where it turns away or the texel beyond is empty.
float ism_plane_continued(ivec2 tile, ivec2 local, ivec2 step, int at, int size)
{
  float near_depth = ism_close_depth(tile, local + at * step, size);
  float beyond_depth = ism_close_depth(tile, local + (at + 1) * step, size);
  if (near_depth >= 3.0e38 || beyond_depth >= 3.0e38) {
    return 3.0e38;
  }
  float near_w = ism_close_scale(local + at * step, size) / near_depth;
  float beyond_w = ism_close_scale(local + (at + 1) * step, size) / beyond_depth;
  float w = near_w + float(at) * (near_w - beyond_w);
  return w > 0.0 ? ism_close_scale(local, size) / w : 3.0e38;
}

void main()
{
  ivec2 texel = ivec2(gl_GlobalInvocationID.xy) + ivec2(0, ism_first_row);  // a band of rows per dispatch
  if (any(greaterThanEqual(texel, imageSize(ism_closed)))) {
    return;
  }
  int size = ism_size;
  ivec2 tile = (texel / size) * size;
  ivec2 local = texel - tile;
  uint own_bits = imageLoad(ism_splatted, texel).r;
  float own = own_bits == 0xFFFFFFFFu ? 3.0e38 : uintBitsToFloat(own_bits);
  float best = 3.0e38;
  ivec2 directions[4] = ivec2[4](ivec2(1, 0), ivec2(0, 1), ivec2(1, 1), ivec2(1, -1));
  for (int d = 0; d < 4; d++) {
    float before = 3.0e38;
    float after = 3.0e38;
    int before_at = 0;
    int after_at = 0;
    for (int k = 1; k <= min(ISM_GAP_REACH, size); k++) {  // the fold's mirror reaches at most a side
      float b = ism_close_depth(tile, local - k * directions[d], size);
      float a = ism_close_depth(tile, local + k * directions[d], size);
      before_at = b < before ? k : before_at;
      after_at = a < after ? k : after_at;
      before = min(before, b);
      after = min(after, a);
    }
    float farther = max(before, after);
    // Each side's surface continued to this texel: a concave corner of continuous surfaces is no gap.
    float surfaces = farther;
    if (ism_continued != 0) {
      surfaces = max(max(before, before_at > 0 ? ism_plane_continued(tile, local, -directions[d], before_at, size) : 3.0e38),
                     max(after, after_at > 0 ? ism_plane_continued(tile, local, directions[d], after_at, size) : 3.0e38));
    }
    if (surfaces < (1.0 - ISM_GAP_MARGIN) * own) {
      best = min(best, farther);
    }
  }
  imageStore(ism_closed, texel, uvec4(best < own ? floatBitsToUint(best) : own_bits));
}
