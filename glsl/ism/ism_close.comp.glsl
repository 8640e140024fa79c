// @require lib/ism.glsl
//
// Imperfect shadow maps, gap closing (twin: reference/ism.py close_gaps): between the splat and
// pull-push, a texel whose nearest depths within ISM_GAP_REACH texels on both sides along a row,
// column or diagonal are nearer than (1 - ISM_GAP_MARGIN) times its own takes the farther of those
// two (the least over the four lines): holes in a near occluder, through which the points behind
// it show, close; silhouettes, with the background on one side only, stay. One invocation per
// texel of the R32UI atlas (tiles of side ism_size, octahedral wrap inside each), written into a
// second R32UI atlas. Empty texels (0xFFFFFFFF) are infinitely far.
float ism_close_depth(ivec2 tile, ivec2 local, int size)
{
  uint bits = imageLoad(ism_splatted, tile + octahedral_wrap(local, size)).r;
  return bits == 0xFFFFFFFFu ? 3.0e38 : uintBitsToFloat(bits);
}

void main()
{
  ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
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
    for (int k = 1; k <= min(ISM_GAP_REACH, size); k++) {  // the fold's mirror reaches at most a side
      before = min(before, ism_close_depth(tile, local - k * directions[d], size));
      after = min(after, ism_close_depth(tile, local + k * directions[d], size));
    }
    float farther = max(before, after);
    if (farther < (1.0 - ISM_GAP_MARGIN) * own) {
      best = min(best, farther);
    }
  }
  imageStore(ism_closed, texel, uvec4(best < own ? floatBitsToUint(best) : own_bits));
}
