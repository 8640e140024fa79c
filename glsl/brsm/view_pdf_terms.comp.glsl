// @require lib/brsm.glsl
//
// Per RSM texel y (one invocation each): the light PDF's weight w(y) = lum Phi (Rd + Rs) where the
// texel sees geometry, 0 elsewhere and where it is not finite or negative (reference view_pdf's
// guards), and w(y) I(y) (lib/brsm.glsl view_importance; only where w > 0, so that a texel without
// geometry, whose position may be anything, costs nothing). Writes (w I, w, 0, 0).

void main()
{
  ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(texel, ivec2(rsm_size)))) {
    return;
  }
  RSMTexel rsm = rsm_load(texel);
  float weight = rsm.coverage > 0.5 ? luminance(rsm.flux_diffuse + rsm.flux_specular) : 0.0;
  weight = (isnan(weight) || isinf(weight)) ? 0.0 : max(weight, 0.0);
  float product = weight > 0.0 ? weight * view_importance(rsm.position, rsm.normal) : 0.0;
  imageStore(view_pdf_terms, texel, vec4(isinf(product) ? 0.0 : product, weight, 0.0, 0.0));
}
