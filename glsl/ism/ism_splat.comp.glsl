// @require lib/ism.glsl
//
// Imperfect shadow maps, splat (vsgl_addon/passes/ism.py; twin: reference/ism.py splat): one
// invocation per (point, map), the maps from ism_first_map on (a dispatch per chunk of maps). Map m, with origin and point set from column m of ism_origins (row
// 0: xyz, set; row 1: the map's own minimum distance, so that the points of the reflector a VSGL
// stands for do not shadow its light; row 2: its half-space, see below), keeps in its tile of the R32UI atlas the nearest radial
// distance of the set's points beyond that minimum per texel:
// positive floats order as their bits, so imageAtomicMin of floatBitsToUint is a float minimum.
// Texels no point reaches keep the clear value 0xFFFFFFFF (empty).
void main()
{
  int point = int(gl_GlobalInvocationID.x);
  int map_index = int(gl_GlobalInvocationID.y) + ism_first_map;
  if (point >= ism_params.x || map_index >= ism_params.y) {
    return;
  }
  vec4 origin = imageLoad(ism_origins, ivec2(map_index, 0));
  vec3 offset = imageLoad(scene_points, ivec2(point, int(origin.w + 0.5))).xyz - origin.xyz;
  float distance = length(offset);
  float min_distance = imageLoad(ism_origins, ivec2(map_index, 1)).x;
  if (!(distance > min_distance)) {
    return;  // the origin's own point, or a non-finite one
  }
  // Row 2: the map's half-space (n, c), points with n . offset < c left out (reference keeps_point;
  // (0, 0) keeps all): a flat reflector's own surface and what lies behind it.
  vec4 plane = imageLoad(ism_origins, ivec2(map_index, 2));
  if (dot(plane.xyz, offset) < plane.w) {
    return;
  }
  int size = ism_params.z;
  ivec2 tile = ivec2(map_index % ism_params.w, map_index / ism_params.w) * size;
  ivec2 centre = ism_texel(offset, size);
  uint bits = floatBitsToUint(distance);
  // The texels the point's share of the surface covers (reference splat_radius): single-texel
  // splats leave holes in near occluders that the points behind them fill.
  vec3 normal = imageLoad(scene_point_normals, ivec2(point, int(origin.w + 0.5))).xyz;
  // The local texel's solid angle (2/size)^2 (|d|_1/|d|)^3 (reference texel_solid_angle).
  float l1_ratio = (abs(offset.x) + abs(offset.y) + abs(offset.z)) / distance;
  float texel = 4.0 / float(size * size) * l1_ratio * l1_ratio * l1_ratio;
  float texels = ism_point_area * abs(dot(normal, offset)) / distance / max(distance * distance, 1e-30) / texel;
  int radius = int(clamp(ceil(0.5 * (ISM_SPLAT_SHARE * sqrt(texels) - 1.0)), 0.0, float(ism_max_radius)));
  // Each texel takes the depth where its centre's direction meets the point's tangent plane, within
  // ism_plane_depth point spacings of its distance (reference tangent_plane_depth: an oriented
  // splat); 0: the point's own distance over the whole splat.
  float height = dot(normal, offset);
  float reach = ism_plane_depth * sqrt(max(ism_point_area, 0.0));
  for (int dy = -radius; dy <= radius; dy++) {
    for (int dx = -radius; dx <= radius; dx++) {
      ivec2 local = octahedral_wrap(centre + ivec2(dx, dy), size);
      uint written = bits;
      if (ism_plane_depth > 0.0) {
        vec3 direction = octahedral_decode((vec2(local) + 0.5) / float(size) * 2.0 - 1.0);
        float across = dot(normal, direction);
        float t = across != 0.0 ? height / across : -1.0;
        t = t > 0.0 ? t : distance + reach;
        written = floatBitsToUint(clamp(t, distance - reach, distance + reach));
      }
      imageAtomicMin(ism_atlas, tile + local, written);
    }
  }
}
