// Imperfect shadow maps, push (twin: reference/ism.py pull_push): a level's holes take their
// parent's filled depth, coarsest level first; one invocation per texel. ism_own is this level's
// pulled (mean, valid) (level 0: the splatted R32UI atlas, ism_first_level = 1), ism_parent the
// level above after its push (r = depth, g = known). Writes (depth, known) into ism_filled (RG32F),
// or, ISM_PUSH_FINAL (level 0, R32F), the depth alone with ISM_UNKNOWN_DEPTH where nothing is
// known (vsgl_addon/passes/ism.py UNKNOWN_DEPTH: the lookups then read one channel).
void main()
{
  ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(ism_filled);
  if (any(greaterThanEqual(texel, size))) {
    return;
  }
  float depth = 0.0;
  bool valid = false;
  if (ism_first_level != 0) {
    uint bits = imageLoad(ism_atlas, texel).r;
    valid = bits != 0xFFFFFFFFu;
    depth = valid ? uintBitsToFloat(bits) : 0.0;
  }
  else {
    vec4 own = imageLoad(ism_own, texel);
    valid = own.g > 0.5;
    depth = own.r;
  }
  vec4 parent = imageLoad(ism_parent, texel / 2);
#if ISM_PUSH_FINAL
  float known = valid ? depth : (parent.g > 0.5 ? parent.r : ISM_UNKNOWN_DEPTH);
  imageStore(ism_filled, texel, vec4(known, 0.0, 0.0, 0.0));
#else
  imageStore(ism_filled, texel, valid ? vec4(depth, 1.0, 0.0, 0.0) : parent);
#endif
}
