// @require lib/vsgl_parameters.glsl
//
// The view-dependent PDF of VSGL generation (000 §5, bidirectional reflective shadow maps). Twin of
// vsgl_addon/reference/brsm.py (view_importance, view_pdf), float32, with its guards:
//
//   I(y) = sum_x rho_d(x) max(0, n_y.w) max(0, -n_x.w) / (|x - y|^2 + r^2),   w = (x - y) / |x - y|
//   p(y) = (1 - beta) w(y) I(y) / sum w I + beta w(y) / sum w
//
// view_receivers (FLOAT_2D sampler, receivers along x): row 0 = (x, rho_d), row 1 = (n_x, 0);
// view_pdf_sizes.x = the receiver count, view_pdf_params.x = r.

// The distance below which a receiver counts as lying on the texel (reference: max(d^2, 1e-30)):
// its cosines are then 0, not 0/0.
const float VIEW_PDF_MIN_DISTANCE_SQUARED = 1e-30;

// I(y) of texel y with normal n_y (any length; zero where the texel has no geometry); 0 where the
// sum is not finite (reference: np.where(isfinite(out), out, 0)).
float view_importance(vec3 y, vec3 n_y)
{
  float radius = view_pdf_params.x;
  float radius_squared = radius * radius;
  float total = 0.0;
  for (int j = 0; j < view_pdf_sizes.x; j++) {
    vec4 receiver = texelFetch(view_receivers, ivec2(j, 0), 0);
    vec3 n_x = texelFetch(view_receivers, ivec2(j, 1), 0).xyz;
    vec3 d = receiver.xyz - y;
    float distance_squared = dot(d, d);
    float inverse_distance = inversesqrt(max(distance_squared, VIEW_PDF_MIN_DISTANCE_SQUARED));
    float cos_y = max(dot(d, n_y) * inverse_distance, 0.0);
    float cos_x = max(-dot(d, n_x) * inverse_distance, 0.0);
    total += max(receiver.w, 0.0) * (cos_y * cos_x / (distance_squared + radius_squared));
  }
  return (isnan(total) || isinf(total)) ? 0.0 : total;
}

// The defensive mixture p(y) from the texel's w I and w and their sums over the RSM: 0 where no
// texel has weight, the light PDF w / sum w where nothing in view is lit (sum w I = 0).
float view_pdf(float product, float weight, float product_total, float weight_total, float defensive)
{
  if (!(weight_total > 0.0) || isinf(weight_total)) {
    return 0.0;
  }
  float light = weight / weight_total;
  if (!(product_total > 0.0) || isinf(product_total)) {
    return light;
  }
  float p = (1.0 - defensive) * (product / product_total) + defensive * light;
  return (isnan(p) || isinf(p)) ? light : max(p, 0.0);
}
