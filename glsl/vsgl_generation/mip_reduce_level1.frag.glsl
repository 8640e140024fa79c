// @require lib/mip_level0.glsl
//
// Level 1 of every plane in one draw into the atlas (glsl/lib/mip_atlas.glsl), the viewport set to
// the level-1 column [0, H) x [0, 6 H) with H = `plane_side`: plane p's level 1 is rows
// [p H, (p + 1) H). Each texel is the mean of its 2x2 children in the plane's level-0 texture
// `level0_plane<p>` (reference `mipmap.build_mip_chain`, same order of additions:
// 0.25 (((m00 + m01) + m10) + m11)). One draw per RSM view, not one per plane (a frame of 32 point
// lights drew 950 of them; its light passes' time measured the same within noise either way, so
// the gain is in draw calls, not in llvmpipe's time). A fragment pass: render targets are
// the fast write path (on llvmpipe several times faster than compute image stores); the higher,
// smaller levels are reduced by mip_reduce.comp.glsl.

void main()
{
  ivec2 target = ivec2(gl_FragCoord.xy);
  int plane = min(target.y / plane_side, 5);
  ivec2 child = 2 * ivec2(target.x, target.y - plane * plane_side);
  vec4 m00 = level0_fetch(plane, child);
  vec4 m01 = level0_fetch(plane, child + ivec2(1, 0));
  vec4 m10 = level0_fetch(plane, child + ivec2(0, 1));
  vec4 m11 = level0_fetch(plane, child + ivec2(1, 1));
  precise vec4 sum = ((m00 + m01) + m10) + m11;
  precise vec4 mean = 0.25 * sum;
  level1_out = mean;
}
