// @require lib/vsgl_parameters.glsl
//
// Level 0 of the mip chains: the per-texel VPL moments of 000 app. B.3 (reference
// `vsgl.texel_moments`) and the PDF weight, one fragment per RSM texel, one render target per plane
// (glsl/lib/mip_atlas.glsl; drawn with the viewport set to the RSM's size).
//
// Planes (20 moment channels in the reference's order, channel c in plane c / 4, component c % 4):
//   0: (Phi Rd).rgb, (w_d xi_bar_d).x          1: (w_d xi_bar_d).yz, (Phi Rs).rg
//   2: (Phi Rs).b, (w_s xi_bar_s).xyz          3: w_d y, w_d |y|^2          4: w_s y, w_s |y|^2
//   5: PDF weight (lum(Phi (Rd + Rs)) or the custom PDF), lum(Phi (Rd + Rs)) [texel beside a depth
//      discontinuity] (reference `vsgl.texel_jumps`; 0 unless compute_jumps != 0), 0, 0
// Planes 3 and 4 are the lobes' own position moments; 000 app. B.2's shared ones (w = w_d + w_s)
// are their sum (reference `combined_position_moments`).
//
// RSM textures (RGBA32F, rsm_size^2, one RSMTexel per texel fetched by the generated rsm_load;
// vsgl_addon/layouts.py RSM): y = position, lam_s = specular_sharpness, n = normal,
// xi_s = specular_axis; pdf_image = (custom PDF weight, -, -, -) when use_custom_pdf != 0.

bool texel_lit(RSMTexel t)
{
  return luminance(t.flux_diffuse) + luminance(t.flux_specular) > 0.0;
}

// The shorter of the differences to the lit neighbours at texel -/+ step (reference
// `vsgl._one_sided_difference`): zero where neither is lit or inside the RSM.
vec3 one_sided_difference(ivec2 texel, ivec2 step, vec3 y, out vec3 backward, out vec3 forward,
                          out bool has_backward, out bool has_forward)
{
  ivec2 ahead = texel + step;
  ivec2 behind = texel - step;
  has_forward = all(greaterThanEqual(ahead, ivec2(0))) && all(lessThan(ahead, ivec2(rsm_size)));
  has_backward = all(greaterThanEqual(behind, ivec2(0))) && all(lessThan(behind, ivec2(rsm_size)));
  forward = vec3(0.0);
  backward = vec3(0.0);
  if (has_forward) {
    RSMTexel t = rsm_load(ahead);
    has_forward = texel_lit(t);
    forward = t.position - y;
  }
  if (has_backward) {
    RSMTexel t = rsm_load(behind);
    has_backward = texel_lit(t);
    backward = y - t.position;
  }
  vec3 best = vec3(0.0);
  float best_length = 3.0e38;
  if (has_forward && length(forward) < best_length) {
    best = forward;
    best_length = length(forward);
  }
  if (has_backward && length(backward) < best_length) {
    best = backward;
  }
  return best;
}

// 1 where a lit 4-neighbour lies farther than JUMP_TEXELS times the texel's size sqrt(a) (a from
// the one-sided differences: |du x dv|, or |d|^2 of the one axis with a lit neighbour); reference
// `vsgl.texel_areas` and `vsgl.texel_jumps`.
float texel_jump(ivec2 texel, vec3 y)
{
  vec3 u_back, u_ahead, v_back, v_ahead;
  bool has_u_back, has_u_ahead, has_v_back, has_v_ahead;
  vec3 du = one_sided_difference(texel, ivec2(1, 0), y, u_back, u_ahead, has_u_back, has_u_ahead);
  vec3 dv = one_sided_difference(texel, ivec2(0, 1), y, v_back, v_ahead, has_v_back, has_v_ahead);
  bool has_u = dot(du, du) > 0.0;
  bool has_v = dot(dv, dv) > 0.0;
  float area = has_u && has_v ? length(cross(du, dv)) : (has_u ? dot(du, du) : dot(dv, dv));
  float reach = JUMP_TEXELS * sqrt(area);
  if (!(reach > 0.0)) {
    return 0.0;
  }
  bool jump = (has_u_back && length(u_back) > reach) || (has_u_ahead && length(u_ahead) > reach)
              || (has_v_back && length(v_back) > reach) || (has_v_ahead && length(v_ahead) > reach);
  return jump ? 1.0 : 0.0;
}

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
  float jump = lit && compute_jumps != 0 ? texel_jump(texel, rsm.position) : 0.0;
  level0_out5 = vec4(pdf_weight, (w_d + w_s) * jump, 0.0, 0.0);
}
