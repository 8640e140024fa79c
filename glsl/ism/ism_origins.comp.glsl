// @require lib/ism.glsl
//
// Imperfect shadow maps, the splat's table from a VSGL table (vsgl_addon/passes/ism.py
// vsgl_map_origins; twin: reference/ism.py vsgl_map_origins), so that the maps of VSGLs made on the
// GPU need no read-back. One invocation per map: ism_origin_params = (VSGL count, maps per VSGL,
// first map, point sets). Map m is lobe m mod maps-per-VSGL (0 diffuse, 1 specular) of VSGL
// m / maps-per-VSGL, centred on the lobe's ism_shadow_origin (the shading's lookups centre it the
// same way); row 0 of ism_origins: origin xyz, point set (first map + m) mod point sets; row 1: the
// map's minimum distance, ism_own_reflector_sigmas sigma_v (the lobe's own reflector, 000 sec. 5);
// row 2: no half-space (every point kept; the VPL clusters' maps have one, ism_splat.comp.glsl).
void main()
{
  int map_index = int(gl_GlobalInvocationID.x);
  int maps_per_vsgl = ism_origin_params.y;
  if (map_index >= ism_origin_params.x * maps_per_vsgl) {
    return;
  }
  VSGLRecord vsgl = vsgl_table_load(map_index / maps_per_vsgl);
  bool specular = maps_per_vsgl == 2 && map_index % 2 == 1;
  vec3 mean = specular ? vsgl.specular_mean : vsgl.diffuse_mean;
  float variance = specular ? vsgl.specular_variance : vsgl.diffuse_variance;
  vec3 axis = specular ? vsgl.specular_axis : vsgl.diffuse_axis;
  int point_set = (ism_origin_params.z + map_index) % ism_origin_params.w;
  imageStore(ism_origins, ivec2(map_index, 0), vec4(ism_shadow_origin(mean, variance, axis), float(point_set)));
  float min_distance = ism_own_reflector_sigmas * sqrt(max(variance, 0.0));
  imageStore(ism_origins, ivec2(map_index, 1), vec4(min_distance, 0.0, 0.0, 0.0));
  imageStore(ism_origins, ivec2(map_index, 2), vec4(0.0));
}
