// @require lib/math.glsl
// @require lib/vsgl_shading.glsl
// @require lib/ism.glsl
//
// Indirect light from VSGLs (000 app. C), one fragment per pixel of the camera G-buffer's position
// and normal attachments and the shading inputs (unpacked by the generated code of
// vsgl_addon/layouts.py GBUFFER and SHADING_INPUTS; vsgl_addon/passes/vsgl_shading.py documents them). For each VSGL of the table (RGBA32F,
// one VSGLRecord per column, loaded as an image by the generated vsgl_table_load: vsgl_addon/layouts.py
// VSGL_TABLE) both lobes are added, each at its own position (glsl/lib/vsgl_shading.glsl), computed once per VSGL when the table's lobes
// share it (VSGL_SHARED_POSITIONS, a compile-time define: the paper's positional distribution, one
// per table, vsgl_addon/passes/vsgl_shading.py VSGLTable.shared_positions). Outputs: indirect
// diffuse = Rd * sum, indirect specular = F0 * sum_s + sum_f (Schlick is linear in F0); alpha =
// coverage, or 0 when `accumulate` is set (later tables are added by blending).
// VSGL_DIFFUSE_MODE is a compile-time define (0: cosine pulled out, 1: 003's SG convolution, 2: the
// clamped-cosine integral of the incoming SG, 3: the separable incoming radiance, cosine pulled out).
//
// VSGL_VISIBILITY 1: each lobe's light is weighted by its visibility from the pixel, a filtered
// lookup in the lobe position's imperfect shadow map (000 sec. 5; lib/ism.glsl, atlas of
// vsgl_addon/passes/ism.py): ism_params = (map side, tiles per atlas row, 1 where the maps keep their
// surfaces' depth and the lookups take the surface normal offset (ISMAtlas.surfaces), -); VSGL_ISM_MAPS, a
// compile-time define, the maps per VSGL (1: map i at the VSGL's diffuse lobe's positional Gaussian
// (vsgl_addon/pipeline.py MAPS_PER_VSGL) for both lobes, or 2: map 2i the diffuse lobe's, 2i + 1 the
// specular lobe's). Map m lies in tile (m mod columns, m div columns); the loop steps the tile with
// its maps instead of dividing (llvmpipe runs integer division lane by lane).
// Each map is centred on its shadow origin (lib/ism.glsl ism_shadow_origin). A VSGL is a Gaussian of positions, not a point: the filter's radius in texels is its spread
// sigma_v seen from the pixel, sigma_v / distance radians, up to VSGL_ISM_MAX_RADIUS.
// Each map leaves out only the points nearest its origin (vsgl_addon/pipeline.py
// VSGL_OWN_REFLECTOR_SIGMAS), so a flat reflector's own surface hides what lies behind it.

#if VSGL_VISIBILITY
// The map at tile_corner (ism_lookup_at) seen from the receiver rc.
float vsgl_visibility(ISMLookup c, vec2 tile_corner, vec3 mean, float variance, vec3 axis, VSGLReceiver rc)
{
  vec3 origin = ism_shadow_origin(mean, variance, axis);
  vec3 offset = rc.position - origin;
  float distance = length(offset);
  float radius = sqrt(max(variance, 0.0)) / max(distance, 1e-30) / c.texel_angle;
  // Under half a texel one texel; else the bilinear filter of about two texels (one code path).
  bool filtered = int(clamp(radius + 0.5, 0.0, float(VSGL_ISM_MAX_RADIUS))) != 0;
  return ism_lookup_at(ism_atlas, c, tile_corner, offset, distance, rc.normal, filtered);
}

// The next map's tile_corner: one tile on, the row's first tile of the next row after its last.
vec2 vsgl_next_tile(vec2 tile_corner, float tile_side, float row_end)
{
  tile_corner.x += tile_side;
  return tile_corner.x < row_end ? tile_corner : vec2(1.0, tile_corner.y + tile_side);
}
#endif

void main()
{
  ivec2 pixel = ivec2(gl_FragCoord.xy);
  GBufferTexel g;
  gbuffer_unpack_position(imageLoad(gbuffer_position, pixel), g);
  float coverage = accumulate != 0 ? 0.0 : g.coverage;
  if (!(g.coverage > 0.0)) {
    indirect_diffuse = vec4(0.0, 0.0, 0.0, coverage);
    indirect_specular = vec4(0.0, 0.0, 0.0, coverage);
    return;
  }
  gbuffer_unpack_normal(imageLoad(gbuffer_normal, pixel), g);
  vec3 normal = safe_normalize(g.normal, vec3(0.0, 0.0, 1.0));
  float roughness = roughness_is_perceptual != 0 ? g.roughness * g.roughness : g.roughness;
  // camera = (position, 1) for a perspective camera, (direction towards it, 0) for an orthographic one.
  vec3 view = safe_normalize(camera.w > 0.0 ? camera.xyz - g.position : camera.xyz, normal);
  VSGLReceiver rc = vsgl_receiver(g.position, normal, view, roughness);
  vec3 diffuse = vec3(0.0);
  vec3 specular = vec3(0.0);
  vec3 fresnel = vec3(0.0);
#if VSGL_VISIBILITY
  ISMLookup ism = ism_lookup_constants(ism_atlas, ism_params.x);
  ism_use_surface_offset(ism_params.z != 0);
  float tile_side = float(ism_params.x);
  float row_end = float(ism_params.x * ism_params.y);  // past the row's last tile_corner.x
  vec2 tile_corner = vec2(1.0);  // map 0's
#endif
  for (int i = 0; i < vsgl_count; i++) {
    VSGLRecord vsgl = vsgl_table_load(i);
    VSGLPosition diffuse_position = vsgl_position(rc.position, vsgl.diffuse_mean, vsgl.diffuse_variance);
#if VSGL_SHARED_POSITIONS
    VSGLPosition specular_position = diffuse_position;
#else
    VSGLPosition specular_position = vsgl_position(rc.position, vsgl.specular_mean, vsgl.specular_variance);
#endif
    vec3 diffuse_amplitude = vsgl.diffuse_amplitude;
    vec3 specular_amplitude = vsgl.specular_amplitude;
#if VSGL_VISIBILITY
#if VSGL_ISM_MAPS == 1
    float visibility = vsgl_visibility(ism, tile_corner, vsgl.diffuse_mean, vsgl.diffuse_variance, vsgl.diffuse_axis, rc);
    tile_corner = vsgl_next_tile(tile_corner, tile_side, row_end);
    diffuse_amplitude *= visibility;
    specular_amplitude *= visibility;
#else
    diffuse_amplitude *= vsgl_visibility(ism, tile_corner, vsgl.diffuse_mean, vsgl.diffuse_variance, vsgl.diffuse_axis, rc);
    tile_corner = vsgl_next_tile(tile_corner, tile_side, row_end);
    specular_amplitude *= vsgl_visibility(ism, tile_corner, vsgl.specular_mean, vsgl.specular_variance,
                                          vsgl.specular_axis, rc);
    tile_corner = vsgl_next_tile(tile_corner, tile_side, row_end);
#endif
#endif
    vsgl_accumulate(rc, diffuse_position, diffuse_amplitude, vsgl.diffuse_axis, vsgl.diffuse_sharpness,
                    specular_position, specular_amplitude, vsgl.specular_axis, vsgl.specular_sharpness,
                    VSGL_DIFFUSE_MODE, diffuse, specular, fresnel);
  }
  ShadingInputs inputs = shading_inputs_load(pixel);
  indirect_diffuse = vec4(inputs.diffuse_reflectance * diffuse, coverage);
  indirect_specular = vec4(inputs.specular_f0 * specular + fresnel, coverage);
}
