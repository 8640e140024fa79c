// The sums over the RSM of w I and w (view_pdf_terms.comp.glsl's x and y), one work group of
// VIEW_PDF_SUM_GROUP invocations: each adds a strided share of the texels, then a tree in shared
// memory (the mixture's two normalizers, reference brsm.view_pdf's product.sum() and total).

void main()
{
  uint local = gl_LocalInvocationIndex;
  int side = rsm_size;
  int count = side * side;
  vec2 total = vec2(0.0);
  for (int i = int(local); i < count; i += VIEW_PDF_SUM_GROUP) {
    total += imageLoad(view_pdf_terms, ivec2(i % side, i / side)).xy;
  }
  view_pdf_partial[local] = total;
  barrier();
  for (uint stride = uint(VIEW_PDF_SUM_GROUP) / 2u; stride > 0u; stride /= 2u) {
    if (local < stride) {
      view_pdf_partial[local] += view_pdf_partial[local + stride];
    }
    barrier();
  }
  if (local == 0u) {
    imageStore(view_pdf_sums, ivec2(0), vec4(view_pdf_partial[0], 0.0, 0.0));
  }
}
