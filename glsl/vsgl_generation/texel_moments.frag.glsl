// @require lib/vsgl_parameters.glsl
//
// Level 0 of the mip chains: the per-texel VPL moments of 000 app. B.3 (reference
// `vsgl.texel_moments`) and the PDF weight, one fragment per RSM texel, one render target per plane
// (glsl/lib/mip_atlas.glsl; drawn with the viewport set to the RSM's size).
//
// Planes (20 moment channels in the reference's order, channel c in plane c / 4, component c % 4):
//   0: (Phi Rd).rgb, (w_d xi_bar_d).x          1: (w_d xi_bar_d).yz, (Phi Rs).rg
//   2: (Phi Rs).b, (w_s xi_bar_s).xyz          3: w_d y, w_d |y|^2          4: w_s y, w_s |y|^2
//   5: PDF weight (lum(Phi (Rd + Rs)) or the custom PDF), 0, 0, 0
// Planes 3 and 4 are the lobes' own position moments; 000 app. B.2's shared ones (w = w_d + w_s)
// are their sum (reference `combined_position_moments`).
//
// RSM textures (RGBA32F, rsm_size^2, one RSMTexel per texel fetched by the generated rsm_load;
// vsgl_addon/layouts.py RSM): y = position, lam_s = specular_sharpness, n = normal,
// xi_s = specular_axis; pdf_image = (custom PDF weight, -, -, -) when use_custom_pdf != 0.

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy);
  RSMTexel rsm = rsm_load(texel);
  vec3 flux_diffuse = rsm.flux_diffuse;
  vec3 flux_specular = rsm.flux_specular;
  float w_d = luminance(flux_diffuse);
  float w_s = luminance(flux_specular);
  bool lit_d = w_d > 0.0;
  bool lit_s = w_s > 0.0;
  bool lit = w_d + w_s > 0.0;
  vec3 normal = unit_or_zero(rsm.normal, lit_d);
  vec3 specular_axis = unit_or_zero(rsm.specular_axis, lit_s);
  float specular_sharpness = lit_s ? rsm.specular_sharpness : 0.0;
  vec3 y = lit ? rsm.position : vec3(0.0);
  float y_squared = dot(y, y);

  vec3 diffuse_direction = w_d * toksvig_mean_direction(normal, DIFFUSE_SHARPNESS);
  vec3 specular_direction = w_s * toksvig_mean_direction(specular_axis, specular_sharpness);

  level0_out0 = vec4(flux_diffuse, diffuse_direction.x);
  level0_out1 = vec4(diffuse_direction.yz, flux_specular.rg);
  level0_out2 = vec4(flux_specular.b, specular_direction);
  level0_out3 = w_d * vec4(y, y_squared);
  level0_out4 = w_s * vec4(y, y_squared);
  float pdf_weight = use_custom_pdf != 0 ? texelFetch(pdf_image, texel, 0).r : w_d + w_s;
  level0_out5 = vec4(pdf_weight, 0.0, 0.0, 0.0);
}
