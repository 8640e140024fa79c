// @require lib/mip_level0.glsl
//
// Mip chains of the RSM quantities, read with exact float32 weights (a Python GPUTexture has no mip
// levels, shared/reference/blender-gpu.md). Six planes of four channels each
// (vsgl_addon/passes/vsgl_generation.py):
//   level 0 of plane p: its own RGBA32F texture, the sampler `level0_plane<p>` (S x S, written by a
//   fragment pass: render targets are the fast path on every GPU and on llvmpipe);
//   levels l >= 1 of all planes: one RGBA32F image `mip_atlas`. With H = S / 2 (side of level 1),
//   plane p occupies rows [p H, (p + 1) H); level 1 at (0, p H), level l >= 2 at
//   (H, p H + H - 2H / 2^(l-1)), each level below the previous one in the column right of level 1.
//   Atlas size (H + H/2) x 6 H (1 x 1 when S = 1: no level >= 1).
// Texel (x, y) of a level = (column u, row v) of vsgl_addon/reference/mipmap.py: u runs along x, v
// along y, row 0 uploaded first. Each level-l texel is the mean of its 2x2 children (reference
// build_mip_chain).
//
// Shaders that @require this file declare the samplers level0_plane0 .. level0_plane5 and the
// image mip_atlas in their create-info (on llvmpipe image loads measured ~25 % faster than texel
// fetches through a sampler).

const int MIP_ATLAS_MAX_LEVELS = 15;  // RSM side up to 2^14
const int MIP_PLANES = 6;

// Atlas position of texel (0, 0) of level `level` >= 1 of plane `plane` (RSM side `size`).
ivec2 mip_atlas_origin(int size, int level, int plane)
{
  int half_size = size / 2;
  int y = plane * half_size;
  if (level == 1) {
    return ivec2(0, y);
  }
  return ivec2(half_size, y + half_size - ((2 * half_size) >> (level - 1)));
}

vec4 mip_atlas_fetch(int size, int level, int plane, ivec2 texel)
{
  if (level == 0) {
    return level0_fetch(plane, texel);
  }
  return imageLoad(mip_atlas, mip_atlas_origin(size, level, plane) + texel);
}

// Texel indices and weights of a bilinear lookup at uv in one level of side `width`, CLAMP_TO_EDGE,
// texel centres at (j + 0.5) / width: the reference's `mipmap.bilinear`, in float32.
struct BilinearTap {
  ivec2 a;  // (column, row) of the lower taps, clamped
  ivec2 b;  // (column, row) of the upper taps, clamped
  vec2 f;   // fractions along u and v
};

BilinearTap bilinear_tap(int width, vec2 uv)
{
  vec2 s = uv * float(width) - 0.5;
  vec2 lower = floor(s);
  BilinearTap tap;
  tap.f = s - lower;
  ivec2 i0 = ivec2(lower);
  tap.a = clamp(i0, ivec2(0), ivec2(width - 1));
  tap.b = clamp(i0 + 1, ivec2(0), ivec2(width - 1));
  return tap;
}

// Bilinear lookup of one plane at one level with a precomputed tap (reference order of operations:
// (1 - fx) m(ia, ja) + fx m(ia, jb) per row, then (1 - fy) top + fy bottom).
vec4 mip_atlas_bilinear_tap(int size, int level, int plane, BilinearTap tap)
{
  vec4 m00 = mip_atlas_fetch(size, level, plane, ivec2(tap.a.x, tap.a.y));
  vec4 m01 = mip_atlas_fetch(size, level, plane, ivec2(tap.b.x, tap.a.y));
  vec4 m10 = mip_atlas_fetch(size, level, plane, ivec2(tap.a.x, tap.b.y));
  vec4 m11 = mip_atlas_fetch(size, level, plane, ivec2(tap.b.x, tap.b.y));
  vec4 top = (1.0 - tap.f.x) * m00 + tap.f.x * m01;
  vec4 bottom = (1.0 - tap.f.x) * m10 + tap.f.x * m11;
  return (1.0 - tap.f.y) * top + tap.f.y * bottom;
}

vec4 mip_atlas_bilinear(int size, int level, int plane, vec2 uv)
{
  return mip_atlas_bilinear_tap(size, level, plane, bilinear_tap(size >> level, uv));
}

// Fractional level l clamped to [0, top] as (lower level, upper level, fraction): the reference's
// `mipmap.interpolate_levels`.
void mip_level_split(float level, int top, out int lower, out int upper, out float fraction)
{
  float clamped = clamp(level, 0.0, float(top));
  lower = min(int(floor(clamped)), top);
  upper = min(lower + 1, top);
  fraction = clamped - float(lower);
}
