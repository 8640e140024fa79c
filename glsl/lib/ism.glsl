// Imperfect shadow maps (Ritschel et al. 2008; 000 sec. 5 gives every VSGL one): the octahedral
// projection of the whole sphere of directions into one square tile, as
// vsgl_addon/reference/ism.py (same names; why octahedral is said there). Depth is the radial
// distance from the map's origin.

// Octahedral coordinates in [-1, 1]^2 of a direction d (need not be unit): d / |d|_1, the lower
// hemisphere folded over the diamond's edges.
vec2 octahedral_encode(vec3 d)
{
  // Only x and y are divided: the fold needs z's sign alone, which the division keeps.
  vec2 xy = d.xy / max(abs(d.x) + abs(d.y) + abs(d.z), 1e-30);
  vec2 sign_xy = vec2(xy.x >= 0.0 ? 1.0 : -1.0, xy.y >= 0.0 ? 1.0 : -1.0);
  return d.z < 0.0 ? (1.0 - abs(xy.yx)) * sign_xy : xy;
}

// Unit direction of octahedral coordinates uv in [-1, 1]^2.
vec3 octahedral_decode(vec2 uv)
{
  float z = 1.0 - abs(uv.x) - abs(uv.y);
  vec2 sign_uv = vec2(uv.x >= 0.0 ? 1.0 : -1.0, uv.y >= 0.0 ? 1.0 : -1.0);
  vec2 xy = z < 0.0 ? (1.0 - abs(uv.yx)) * sign_uv : uv;
  return normalize(vec3(xy, z));
}

// Texel (column, row) of direction d in a size x size octahedral map.
ivec2 ism_texel(vec3 d, int size)
{
  vec2 cell = floor((octahedral_encode(d) * 0.5 + 0.5) * float(size));
  return clamp(ivec2(cell), ivec2(0), ivec2(size - 1));
}

// A lobe's shadow origin: its mean moved ISM_SHADOW_ORIGIN_SIGMAS sigma_v along its unit axis
// (reference shadow_origin: the mean of a curved cluster lies behind its own surface). It is the
// define ISM_ORIGIN_SIGMAS of every shader that requires this file, the reference's
// SHADOW_ORIGIN_SIGMAS (vsgl_addon/shaders.py LIBRARY_DEFINES), so the maps' origins
// (ism_origins.comp.glsl) and the lookups centred on them agree.
const float ISM_SHADOW_ORIGIN_SIGMAS = float(ISM_ORIGIN_SIGMAS);

vec3 ism_shadow_origin(vec3 mean, float variance, vec3 axis)
{
  return mean + ISM_SHADOW_ORIGIN_SIGMAS * sqrt(max(variance, 0.0)) * axis;
}

// Largest tan of the receiver's incidence the slope-scaled bias follows (reference ISM_MAX_SLOPE).
const float ISM_MAX_SLOPE = 8.0;

// Depth bias at radial distance: `slope` texel footprints (a texel spans about sqrt(4 pi) / size
// rad) times (1 + tan of the receiver's incidence), plus `floor_metres` (reference ism_bias).
float ism_bias(float distance, int size, float tan_incidence, float slope, float floor_metres)
{
  return slope * distance * 3.5449077018110318 / float(size) * (1.0 + min(tan_incidence, ISM_MAX_SLOPE)) +
         floor_metres;
}

// The lookup's receiver offset along its normal in filter footprints (0: none), the depth bias
// left with it in texel footprints, and the offset away from the origin of a receiver facing away
// from it (0: none): the defines ISM_NORMAL_OFFSET, ISM_NORMAL_OFFSET_DEPTH and ISM_BACK_OFFSET of
// every shader that requires this file (reference NORMAL_OFFSET, NORMAL_OFFSET_DEPTH, BACK_OFFSET).
const float ISM_RECEIVER_OFFSET = float(ISM_NORMAL_OFFSET);
const float ISM_RECEIVER_DEPTH = float(ISM_NORMAL_OFFSET_DEPTH);
// The lookups' receiver offset and depth bias left: the constants above, or, for the maps that keep
// their surfaces' depth (ism_use_surface_offset; vsgl_addon/passes/ism.py ISMAtlas.surfaces), the
// defines ISM_SURFACE_OFFSET and ISM_SURFACE_OFFSET_DEPTH (reference SURFACE_NORMAL_OFFSET,
// SURFACE_NORMAL_OFFSET_DEPTH). The same for every pixel of a draw, so its branches do not diverge.
float ism_offset_scale = ISM_RECEIVER_OFFSET;
float ism_offset_depth = ISM_RECEIVER_DEPTH;

void ism_use_surface_offset(bool surfaces)
{
  ism_offset_scale = surfaces ? float(ISM_SURFACE_OFFSET) : ISM_RECEIVER_OFFSET;
  ism_offset_depth = surfaces ? float(ISM_SURFACE_OFFSET_DEPTH) : ISM_RECEIVER_DEPTH;
}
const float ISM_RECEIVER_BACK_OFFSET = float(ISM_BACK_OFFSET);
// The bilinear lookup's bias at most ISM_SPREAD_BIAS times its four texels' depth spread plus
// ISM_RECEIVER_DEPTH texel footprints; 0: no such cap (the define ISM_SPREAD, reference SPREAD_BIAS).
const float ISM_SPREAD_BIAS = float(ISM_SPREAD);

// Where the receiver moves off its own surface (reference lookup_offsets; the offsets are compile-time
// constants): `offset` (receiver - origin) moved along the unit `normal` (facing the camera) and
// `distance` its new length, the depth bias left returned; -1 where the receiver stays and the
// caller's slope-scaled depth bias applies. A receiver facing the origin moves towards it by
// ISM_RECEIVER_OFFSET * footprint texel footprints times the sine of its incidence (against its own
// plane a depth margin without a cap; against an occluder in front at most half of it nearer); one
// facing away moves ISM_RECEIVER_BACK_OFFSET * footprint texel footprints away from it (its own
// surface then hides the origin, where a depth bias lets a VSGL behind a thin wall through).
float ism_receiver_offset(inout vec3 offset, inout float distance, vec3 normal, float texel_angle, float footprint)
{
  float towards = dot(normal, -offset);
  bool back = ISM_RECEIVER_BACK_OFFSET > 0.0 && towards < 0.0;
  if (!back && !(ism_offset_scale > 0.0)) {
    return -1.0;
  }
  float texel = footprint * distance * texel_angle;
  float cos_theta = clamp(abs(towards) / max(distance, 1e-30), 0.0, 1.0);
  float front = ism_offset_scale * texel * sqrt(max(1.0 - cos_theta * cos_theta, 0.0));
  offset += (back ? ISM_RECEIVER_BACK_OFFSET * texel : towards >= 0.0 ? front : -front) * normal;
  distance = length(offset);
  return back ? 1e-3 : ism_offset_depth * distance * texel_angle + 1e-3;
}

// The texel across an edge of an octahedral map: the mirror image about the edge's midpoint
// (reference octahedral_wrap).
ivec2 octahedral_wrap(ivec2 texel, int size)
{
  for (int i = 0; i < 2; i++) {
    if (texel.x < 0 || texel.x >= size) {
      texel.x = texel.x < 0 ? -1 - texel.x : 2 * size - 1 - texel.x;
      texel.y = size - 1 - texel.y;
    }
    if (texel.y < 0 || texel.y >= size) {
      texel.y = texel.y < 0 ? -1 - texel.y : 2 * size - 1 - texel.y;
      texel.x = size - 1 - texel.x;
    }
  }
  return texel;
}

// Percentage-closer visibility of the origin of the map in tile `tile` (texels, of side `size`) of
// the filled atlas (r = depth, a huge depth where no point landed: vsgl_addon/passes/ism.py
// UNKNOWN_DEPTH, so such a texel hides nothing) from `receiver` with unit
// `normal`: the share of the (2 radius + 1)^2 texels around the receiver's whose stored depth is
// not nearer than the receiver less the bias, which spans the filter's footprint (reference
// ism_pcf).
float ism_pcf(sampler2D atlas, ivec2 tile, int size, vec3 origin, vec3 receiver, vec3 normal, int radius)
{
  vec3 offset = receiver - origin;
  float distance = length(offset);
  float bias = ism_receiver_offset(offset, distance, normal, 3.5449077018110318 / float(size), 1.0 + float(radius));
  if (bias < 0.0) {
    float cos_theta = clamp(abs(dot(normal, -offset)) / max(distance, 1e-30), 0.0, 1.0);
    float tan_theta = sqrt(max(1.0 - cos_theta * cos_theta, 0.0)) / max(cos_theta, 1e-3);
    bias = ism_bias(distance, size, tan_theta, 1.0 + float(radius), 1e-3);
  }
  ivec2 centre = ism_texel(offset, size);
  float lit = 0.0;
  for (int dy = -radius; dy <= radius; dy++) {
    for (int dx = -radius; dx <= radius; dx++) {
      vec4 stored = texelFetch(atlas, tile + octahedral_wrap(centre + ivec2(dx, dy), size), 0);
      lit += distance <= stored.r + bias ? 1.0 : 0.0;
    }
  }
  return lit / float((2 * radius + 1) * (2 * radius + 1));
}

// What ism_lookup_at needs of the map and atlas sizes, made once per pixel (not once per lookup).
struct ISMLookup {
  int size;
  float size_f;          // float(size)
  float inv_size;        // 1 / size: exact, the maps' sides are powers of two (passes/ism.py)
  float texel_angle;     // sqrt(4 pi) / size, a texel's span in radians (ism_bias)
  float last_corner;     // float(max(size - 2, 0)): the last 2x2 block inside the square
  float last_texel;      // float(size - 1)
  float blocks;          // 1, or 0 for a 1^2 map (its one texel)
  vec2 inv_atlas_size;   // 1 / the atlas's size in texels
};

ISMLookup ism_lookup_constants(sampler2D atlas, int size)
{
  ISMLookup c;
  c.size = size;
  c.size_f = float(size);
  c.inv_size = 1.0 / float(size);
  c.texel_angle = 3.5449077018110318 / float(size);
  c.last_corner = float(max(size - 2, 0));
  c.last_texel = float(size - 1);
  c.blocks = size > 1 ? 1.0 : 0.0;
  c.inv_atlas_size = 1.0 / vec2(textureSize(atlas, 0));
  return c;
}

// The lookup of the shading pass, one code path for its two filters (llvmpipe runs both sides of a
// branch that differs between neighbouring pixels, and the body of any branch): `filtered` the
// bilinear percentage-closer visibility (reference ism_pcf_bilinear): the test of ism_pcf on the four
// texels around the receiver's continuous position in the map, weighted bilinearly, so the result
// varies smoothly across texels, with the bias of two texels' footprint; else the test of the one
// texel holding the receiver's direction (reference ism_pcf at radius 0, the bias of one texel):
// the same block with weights 0 or 1. With ISM_RECEIVER_OFFSET > 0 the receiver moves along its
// normal instead, with a small depth bias left (ism_receiver_offset). The block is kept inside the square (clamped at its edges,
// not wrapped across the folds: see the reference) and read by one textureGather of the four texels
// around their shared corner (gather order: (0, 1), (1, 1), (1, 0), (0, 0)).
// tile_corner: the map's tile's first texel + 1 (the gather's corner is between texels), `offset`
// receiver - origin and `distance` its length. ism_bias and ism_texel's arithmetic, with the
// division by the power-of-two size a multiplication (the same floats).
float ism_lookup_at(sampler2D atlas, ISMLookup c, vec2 tile_corner, vec3 offset, float distance, vec3 normal,
                    bool filtered)
{
  float bias = ism_receiver_offset(offset, distance, normal, c.texel_angle, filtered ? 2.0 : 1.0);
  if (bias < 0.0) {
    float cos_theta = clamp(abs(dot(normal, -offset)) / max(distance, 1e-30), 0.0, 1.0);
    float tan_theta = sqrt(max(1.0 - cos_theta * cos_theta, 0.0)) / max(cos_theta, 1e-3);
    bias = (filtered ? 2.0 : 1.0) * distance * 3.5449077018110318 * c.inv_size *
           (1.0 + min(tan_theta, ISM_MAX_SLOPE)) + 1e-3;
  }
  vec2 cell = (octahedral_encode(offset) * 0.5 + 0.5) * c.size_f - 0.5;
  vec2 corner = clamp(floor(cell), vec2(0.0), vec2(c.last_corner));
  // Nearest: floor(cell + 0.5), the texel holding the direction (ism_texel), is corner or corner + 1.
  vec2 f = filtered ? clamp(cell - corner, 0.0, 1.0) : clamp(floor(cell + 0.5), 0.0, c.last_texel) - corner;
  f *= c.blocks;
  vec4 depth = textureGather(atlas, (tile_corner + corner) * c.inv_atlas_size, 0).wzxy;  // (c00, c10, c01, c11)
  if (ISM_SPREAD_BIAS > 0.0 && filtered && c.blocks > 0.0) {
    // reference ism_pcf_bilinear: the map's own spread bounds the bias.
    float spread = max(max(depth.x, depth.y), max(depth.z, depth.w)) - min(min(depth.x, depth.y), min(depth.z, depth.w));
    bias = min(bias, ISM_SPREAD_BIAS * spread + ISM_RECEIVER_DEPTH * distance * c.texel_angle + 1e-3);
  }
  vec4 lit = vec4(lessThanEqual(vec4(distance), depth + bias));
  return mix(mix(lit.x, lit.y, f.x), mix(lit.z, lit.w, f.x), f.y);
}

// ism_lookup_at of the map in tile `tile` (texels, of side `size`) from `origin`.
float ism_lookup(sampler2D atlas, vec2 inv_atlas_size, ivec2 tile, int size, vec3 origin, vec3 receiver, vec3 normal,
                 bool filtered)
{
  ISMLookup c = ism_lookup_constants(atlas, size);
  c.inv_atlas_size = inv_atlas_size;
  vec3 offset = receiver - origin;
  return ism_lookup_at(atlas, c, vec2(tile) + 1.0, offset, length(offset), normal, filtered);
}

// Bilinear percentage-closer visibility (reference ism_pcf_bilinear; see ism_lookup): a filter of
// about two texels.
float ism_pcf_bilinear(sampler2D atlas, ivec2 tile, int size, vec3 origin, vec3 receiver, vec3 normal)
{
  return ism_lookup(atlas, 1.0 / vec2(textureSize(atlas, 0)), tile, size, origin, receiver, normal, true);
}

// ism_pcf at radius 0 (one texel; see ism_lookup).
float ism_visible_nearest(sampler2D atlas, ivec2 tile, int size, vec3 origin, vec3 receiver, vec3 normal)
{
  return ism_lookup(atlas, 1.0 / vec2(textureSize(atlas, 0)), tile, size, origin, receiver, normal, false);
}
