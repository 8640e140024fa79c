// Imperfect shadow maps (Ritschel et al. 2008; 000 sec. 5 gives every VSGL one): the octahedral
// projection of the whole sphere of directions into one square tile, as
// vsgl_addon/reference/ism.py (same names; why octahedral is said there). Depth is the radial
// distance from the map's origin.

// Octahedral coordinates in [-1, 1]^2 of a direction d (need not be unit): d / |d|_1, the lower
// hemisphere folded over the diamond's edges.
vec2 octahedral_encode(vec3 d)
{
  d /= max(abs(d.x) + abs(d.y) + abs(d.z), 1e-30);
  vec2 xy = d.xy;
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
