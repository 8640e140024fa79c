// Imperfect shadow maps, pull (Ritschel et al. 2008; twin: reference/ism.py pull_push): one level
// of the atlas pyramid from the level below, one invocation per texel. A texel is the mean depth of
// its valid 2x2 children (r) and valid (g = 1) when any child is. The atlas's tiles are aligned
// squares of a power-of-two side, so each level holds every tile's own pyramid. Level 1 reads the
// splatted R32UI atlas (ism_first_level = 1), the others the RG32F level below.
void main()
{
  ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(ism_coarse);
  if (any(greaterThanEqual(texel, size))) {
    return;
  }
  float total = 0.0;
  float count = 0.0;
  for (int dy = 0; dy < 2; dy++) {
    for (int dx = 0; dx < 2; dx++) {
      ivec2 child = 2 * texel + ivec2(dx, dy);
      if (ism_first_level != 0) {
        uint bits = imageLoad(ism_atlas, child).r;
        if (bits != 0xFFFFFFFFu) {
          total += uintBitsToFloat(bits);
          count += 1.0;
        }
      }
      else {
        vec4 below = imageLoad(ism_fine, child);
        if (below.g > 0.5) {
          total += below.r;
          count += 1.0;
        }
      }
    }
  }
  imageStore(ism_coarse, texel, vec4(count > 0.0 ? total / count : 0.0, count > 0.0 ? 1.0 : 0.0, 0.0, 0.0));
}
