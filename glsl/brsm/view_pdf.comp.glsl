// @require lib/brsm.glsl
//
// The defensive mixture p(y) per RSM texel (lib/brsm.glsl view_pdf) from the texel's terms and their
// sums, into the R channel of the PDF image VSGL generation reads (passes/vsgl_generation.py
// upload_pdf's layout).

void main()
{
  ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(texel, ivec2(rsm_size)))) {
    return;
  }
  vec2 terms = imageLoad(view_pdf_terms, texel).xy;
  vec2 sums = imageLoad(view_pdf_sums, ivec2(0)).xy;
  imageStore(view_pdf_image, texel, vec4(view_pdf(terms.x, terms.y, sums.x, sums.y, view_pdf_params.y), 0.0, 0.0, 0.0));
}
