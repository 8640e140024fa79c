// @require lib/ism.glsl
// @require lib/vpl_culling.glsl
//
// Tiled stochastic light culling and shading of glossy VPLs (004 section 5; twin:
// reference/vpl_culling.py shade_glossy_vpls with the tile lists of ellipsoid_frustum_overlap).
// One work group per 16x16-pixel tile:
// 1. the tile's view depth range and the bounding box of its covered pixels (shared atomicMin/Max;
//    on the float bits of the non-negative depth, whose uint order is the float order);
// 2. the tile frustum over those receivers (reference tile_receiver_ndc): its side planes through
//    the outermost covered pixels' centre rays, where the receivers lie, widened by PIXEL_MARGIN
//    pixels, not through the tile's pixel edges (a spheroid that passes beside the tile's outermost
//    centres, between its sky pixels or beyond a partial tile's last row lights no receiver), and
//    two depth planes; made in view space from the projection's rows (the clip-space plane
//    P_0 - X P_3 of x_ndc = X, as precise for a one-pixel frustum as for a whole tile) and taken to
//    world space as covectors (p_w = W2V^T p_v; the stretched-plane distance is invariant to the
//    planes' scale), so the spheroid is tested where it was built (Eq. 16; Eq. 17's rotation
//    keeping the depth planes perpendicular is implicit in view space);
// 3. the VPLs in chunks of 256: each invocation tests one VPL's spheroid (Eqs. 13-15) against the
//    frustum, exactly (lib/vpl_culling.glsl ellipsoid_frustum_overlap_exact: Eq. 16's plane test
//    alone keeps spheroids beyond the frustum's edges and corners, 3x the false positives on
//    caustic_panel, benchmarks/results/vpl_bounds.md), and appends it to the chunk's shared list (and to the tile's list in the R32UI image,
//    up to its capacity), then every pixel shades the chunk's list with the exact GGX BRDF at the
//    VPL and its own diffuse lobe, weighted 1/p where p > xi (Eqs. 2-3). Chunking keeps the shared
//    list from overflowing, so the result is exact whatever the list capacity.
// Interleaved sampling (004 section 6): with vpl_interleave.x = N > 1 the pixel shades only the
// VPLs i with i % N^2 = its sub-image ((x % N) + N (y % N) + offset) % N^2, weighted N^2: each
// sub-image sees a different subset, and the mean over the N^2 offsets is the full estimate.
// The chunk's shared list is partitioned by subset (N^2 divides 256, and invocation `local` tests a
// VPL of subset (base + local) % N^2, so each subset owns 256 / N^2 slots) and a pixel loops over
// its own part only: a SIMD group's neighbouring pixels belong to different sub-images, so a loop
// over the whole list with a per-VPL subset test costs all N^2 subsets in every lane, and the
// interleave saved no time (caustic_panel's VPL pass 464-480 ms at N = 1, 2, 4, 8 at 240x180).
// Table rows per VPL (record k of VPL i at texel (i % W, 4 (i / W) + k)): position + roughness,
// normal + scalar flux, incoming, Phi Rs + the VPL's shadow map.
// Strided preview (the viewport's coarse image): with vpl_interleave.w = S > 1 only one VPL of each
// block of S consecutive ones is culled and shaded, i = k S + pcg_hash(k + pcg_hash(seed)) % S
// (i < count), weighted S: a jittered stratified subsample (the extraction's texel order makes the
// blocks small patches of the reflectors; a fixed offset would keep whole RSM columns), whose
// expectation over the jitter is the sum over all VPLs. The interleave subsets are taken over k.
// VPL_VISIBILITY 1: each VPL's light on a pixel is weighted by its cluster's imperfect shadow map
// (lib/ism.glsl, bilinear PCF; vsgl_addon/passes/vpl_culling.py VPL clusters): ism_params = (map side,
// tiles per atlas row), vpl_map_origins texel m = map m's origin.

// Slack of the frustum test: a spheroid touching the tile within float32 rounding stays listed.
const float VPL_PLANE_SLACK = 1e-4;
// reference vpl_culling.PIXEL_MARGIN: the frustum's reach beyond the outermost pixel centres, in pixels.
const float PIXEL_MARGIN = 1.0 / 64.0;

vec4 vpl_record(uint i, int k)
{
  int width = vpl_sizes.x;
  return imageLoad(vpl_table, ivec2(int(i) % width, 4 * (int(i) / width) + k));
}

vec4 camera_row(int k)
{
  return texelFetch(vpl_camera, ivec2(0, k), 0);
}

vec3 unproject(vec4 inverse_projection[4], vec2 ndc, float z)
{
  vec4 p = vec4(ndc, z, 1.0);
  vec4 v = vec4(dot(inverse_projection[0], p), dot(inverse_projection[1], p), dot(inverse_projection[2], p),
                dot(inverse_projection[3], p));
  return v.xyz / v.w;
}

void main()
{
  ivec2 size = imageSize(gbuffer_position);
  ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
  ivec2 tile = ivec2(gl_WorkGroupID.xy);
  uint local = gl_LocalInvocationIndex;
  int tile_index = tile.y * vpl_sizes.z + tile.x;
  // The VPLs in the table: counted on the GPU by the extraction (vpl_extract_scan.comp.glsl), at
  // most the table's capacity (vpl_interleave.z).
  uint count = min(texelFetch(vpl_count, ivec2(0), 0).x, uint(vpl_interleave.z));
  uint seed = uint(vpl_params.z);
  uint frame = uint(vpl_params.w);
  float delta = vpl_params.x;
  vec4 world_to_view[4] = vec4[4](camera_row(0), camera_row(1), camera_row(2), camera_row(3));
  vec4 inverse_projection[4] = vec4[4](camera_row(4), camera_row(5), camera_row(6), camera_row(7));
  vec4 projection_x = camera_row(8);
  vec4 projection_y = camera_row(9);
  vec4 projection_w = camera_row(11);

  if (local == 0u) {
    tile_depth_min = 0x7F7FFFFFu;
    tile_depth_max = 0u;
    tile_covered = 0u;
    tile_total = 0u;
    tile_x_min = 0xFFFFFFFFu;
    tile_y_min = 0xFFFFFFFFu;
    tile_x_max = 0u;
    tile_y_max = 0u;
  }
  barrier();
  bool inside = all(lessThan(pixel, size));
  vec4 position = inside ? imageLoad(gbuffer_position, pixel) : vec4(0.0);
  bool covered = inside && position.w > 0.0;
  vec3 receiver = position.xyz;
  vec3 receiver_normal = covered ? imageLoad(gbuffer_normal, pixel).xyz : vec3(0.0, 0.0, 1.0);
  vec3 albedo = covered ? imageLoad(receiver_albedo, pixel).rgb : vec3(0.0);
  if (covered) {
    vec4 p = vec4(receiver, 1.0);
    float depth = max(-dot(world_to_view[2], p), 0.0);
    atomicMin(tile_depth_min, floatBitsToUint(depth));
    atomicMax(tile_depth_max, floatBitsToUint(depth));
    atomicOr(tile_covered, 1u);
    atomicMin(tile_x_min, uint(pixel.x));
    atomicMin(tile_y_min, uint(pixel.y));
    atomicMax(tile_x_max, uint(pixel.x));
    atomicMax(tile_y_max, uint(pixel.y));
  }
  barrier();
  bool tile_used = tile_covered != 0u;
  float depth_min = uintBitsToFloat(tile_depth_min);
  float depth_max = uintBitsToFloat(tile_depth_max);

  // Tile frustum over the covered pixels' centres. An empty tile tests no VPL (its chunks are
  // skipped below); its box is inverted, so it gets a point to keep the arithmetic finite.
  vec2 ndc_min = (vec2(uvec2(tile_x_min, tile_y_min)) + 0.5 - PIXEL_MARGIN) / vec2(size) * 2.0 - 1.0;
  vec2 ndc_max = (vec2(uvec2(tile_x_max, tile_y_max)) + 0.5 + PIXEL_MARGIN) / vec2(size) * 2.0 - 1.0;
  if (!tile_used) {
    ndc_min = vec2(tile * 16) / vec2(size) * 2.0 - 1.0;
    ndc_max = ndc_min;
  }
  vec2 corner_ndc[4] = vec2[4](ndc_min, vec2(ndc_max.x, ndc_min.y), ndc_max, vec2(ndc_min.x, ndc_max.y));
  vec3 near_[4];
  vec3 far_[4];
  for (int k = 0; k < 4; k++) {
    near_[k] = unproject(inverse_projection, corner_ndc[k], -1.0);
    far_[k] = unproject(inverse_projection, corner_ndc[k], 1.0);
  }
  // Side plane k holds corners k and k + 1; inside where the clip w (> 0 in front) scales the bound.
  vec4 planes[6];
  planes[0] = projection_y - ndc_min.y * projection_w;
  planes[1] = ndc_max.x * projection_w - projection_x;
  planes[2] = ndc_max.y * projection_w - projection_y;
  planes[3] = projection_x - ndc_min.x * projection_w;
  planes[4] = vec4(0.0, 0.0, -1.0, -depth_min);
  planes[5] = vec4(0.0, 0.0, 1.0, depth_max);
  for (int k = 0; k < 6; k++) {
    vec4 p = planes[k];
    planes[k] = p.x * world_to_view[0] + p.y * world_to_view[1] + p.z * world_to_view[2]
                + vec4(0.0, 0.0, 0.0, p.w);
  }
  // The frustum's corners in world space (reference tile_frustum_corners' order): each corner ray at
  // depth_min (0-3) and depth_max (4-7). mat4(rows) is W2V^T, so v * inverse(mat4(rows)) = V2W v.
  mat4 view_to_world_t = inverse(mat4(world_to_view[0], world_to_view[1], world_to_view[2], world_to_view[3]));
  vec3 corners[8];
  for (int k = 0; k < 4; k++) {
    float t0 = (depth_min + near_[k].z) / (near_[k].z - far_[k].z);
    float t1 = (depth_max + near_[k].z) / (near_[k].z - far_[k].z);
    corners[k] = (vec4(mix(near_[k], far_[k], t0), 1.0) * view_to_world_t).xyz;
    corners[k + 4] = (vec4(mix(near_[k], far_[k], t1), 1.0) * view_to_world_t).xyz;
  }

  uint stride = uint(max(vpl_interleave.w, 1));
  uint strided = (count + stride - 1u) / stride;
  uint interleave = uint(max(vpl_interleave.x, 1));
  uint subsets = interleave * interleave;
  uint subset = (uint(pixel.x) % interleave + interleave * (uint(pixel.y) % interleave) + uint(vpl_interleave.y))
                % subsets;
  vec3 radiance = vec3(0.0);
  // tile_used is the same for the whole group (read after a barrier), so an empty tile skips the
  // chunks, barriers included, without breaking uniform control flow.
  uint chunk_end = tile_used ? strided : 0u;
  for (uint base = 0u; base < chunk_end; base += 256u) {
    if (local < subsets) {
      subset_count[local] = 0u;
    }
    barrier();
    uint i = (base + local) * stride + (stride > 1u ? strided_vpl_jitter(base + local, seed, stride) : 0u);
    if (tile_used && base + local < strided && i < count) {
      vec4 r0 = vpl_record(i, 0);
      vec4 r1 = vpl_record(i, 1);
      vec4 r2 = vpl_record(i, 2);
      float xi = vpl_xi(i, seed, frame);
      vec3 c, axes, u, v, w;
      ggx_spheroid(r0.xyz, r1.xyz, r2.xyz, r0.w, r1.w, delta, xi, 1.0, c, axes, u, v, w);
      bool listed = r1.w > 0.0
                    && ellipsoid_frustum_overlap_exact(planes, corners, c, axes, u, v, w, VPL_PLANE_SLACK);
      if (listed) {
        uint q = (base + local) % subsets;
        chunk_list[q * (256u / subsets) + atomicAdd(subset_count[q], 1u)] = i;
        uint slot = atomicAdd(tile_total, 1u);
        if (int(slot) < vpl_sizes.y) {
          imageStore(vpl_tile_lists, ivec2(int(slot), tile_index), uvec4(i));
        }
      }
    }
    barrier();
    if (covered) {
      uint first = subset * (256u / subsets);
      uint listed_count = subset_count[subset];
      for (uint k = 0u; k < listed_count; k++) {
        uint j = chunk_list[first + k];
        vec4 r0 = vpl_record(j, 0);
        vec4 r1 = vpl_record(j, 1);
        vec4 r2 = vpl_record(j, 2);
        float intensity, l2;
        float geometry = glossy_vpl_geometry(receiver, receiver_normal, r0.xyz, r1.xyz, r2.xyz, r0.w, r1.w,
                                             intensity, l2);
        float p = acceptance_probability(intensity, l2, delta);
        if (p > vpl_xi(j, seed, frame)) {
          vec4 r3 = vpl_record(j, 3);
#if VPL_VISIBILITY
          int map = int(r3.w + 0.5);
          vec3 origin = imageLoad(vpl_map_origins, ivec2(map, 0)).xyz;
          ivec2 map_tile = ivec2(map % ism_params.y, map / ism_params.y) * ism_params.x;
          geometry *= ism_pcf_bilinear(ism_atlas, map_tile, ism_params.x, origin, receiver, receiver_normal);
#endif
          radiance += r3.rgb * (geometry / p);
        }
      }
    }
    barrier();
  }
  if (local == 0u) {
    imageStore(vpl_tile_counts, tile, uvec4(tile_total));
  }
  if (inside) {
    imageStore(vpl_radiance, pixel, vec4(albedo * (radiance * (float(subsets * stride) / PI)), 0.0));
  }
}
