// @require lib/math.glsl
// @require lib/sg.glsl
// @require lib/asg.glsl
// @require lib/ggx.glsl
//
// Shading with virtual spherical Gaussian lights (000 = Tokuyoshi, "Modified filtered importance
// sampling for virtual spherical Gaussian lights", CVM 2016, app. C; 003 = the Square Enix SG talk;
// formulas.md section 6). Twin of vsgl_addon/reference/vsgl_shading.py (same names, same
// semantics, float32); its module documentation defines C(xi_in) exactly.
//
// Per shading point: vsgl_receiver() once (the ASG specular lobe of 003 and the view terms of C);
// per VSGL vsgl_accumulate() (both its lobes: the diffuse and the specular SG of every VSGL
// illuminate; vsgl_accumulate_lobe() is one lobe), which adds per lobe
//   diffuse   += c_sep * A(lam_sigma)/pi * <xi_mu, n>                (separable, 000 Eqs. 10-11, app. C)
//             or c_in * A(lam_in)/pi * <xi_in, n>                    (cosine pulled out, 000 app. C)
//             or c_in * int G(xi_in, lam_in) G(n, lam_d) / A(lam_d)   (003's 2-VSGL mode)
//             or c_in * 1/pi int G(xi_in, lam_in) max(<w, n>, 0) dw   (clamped cosine)
//   specular  += c_in * k * (1 - m^5)   and   fresnel += c_in * k * m^5,
// c_sep = I_v(-xi_mu) / (2 pi sigma_v^2): the radiant intensity at the direction of the mean
// (vsgl_accumulate: a flat diffuse lobe's texels' Lambertian lobe, vsgl_diffuse_emission; the specular
// lobe's, and vsgl_accumulate_lobe's, the SG c_v G(-xi_mu; xi_v, lam_v)) times the positional lobe,
// not multiplied into Eq. 12's SG, whose axis a broad positional lobe tilts towards -xi_v (behind the walls of a cluster spanning a corner; the reference's module
// documentation). The specular always takes Eq. 12's product c_in G(xi_in, lam_in); in the separable
// mode a flat diffuse lobe's c_in is scaled to its Lambertian emission where the receiver's specular
// gathers the lobe's light (vsgl_diffuse_emission_ratio at vsgl_specular_emission_direction).
// k = D(1) <xi_in, n> / ((c_i + s_i)(c_o + s_o)) * pi / sqrt((eta_x + nu)(eta_y + nu))
//     * exp(-eta_x' (xi_in.x)^2 - eta_y' (xi_in.y)^2), m = 1 - xi_in.h (Schlick), so that the
// specular radiance is F0 * specular + fresnel (Schlick is linear in F0) and the diffuse radiance
// Rd * diffuse: the material enters once per pixel, not once per VSGL.
//
// Plain float32 except two places that measurably needed more (tests/test_vsgl_shading_gpu.py): the
// view cosine c_o (dot_accurate, once per pixel: it decides the jump of the GGX lobe at the horizon)
// and xi_in.h = |xi_in + w_o| / 2 (no normalized half vector at grazing reflection). Reached on the
// lobe grid: relative error <= 3.2e-5 where the result is well-conditioned in float32 inputs.

// Floor on sigma_v^2 (the generator's absolute floor, reference VARIANCE_FLOOR).
const float VSGL_VARIANCE_FLOOR = 1e-12;
// Smallest receiver GGX alpha (reference ALPHA_MIN): lam_h = 2 / alpha^2 <= 2e6.
const float VSGL_ALPHA_MIN = 1e-3;

const int VSGL_DIFFUSE_COSINE = 0;          // 000 app. C
const int VSGL_DIFFUSE_SG_CONVOLUTION = 1;  // 003's 2-VSGL mode
const int VSGL_DIFFUSE_CLAMPED_COSINE = 2;  // Tokuyoshi et al. 2024 (sg.glsl sg_clamped_cosine_integral)
const int VSGL_DIFFUSE_SEPARABLE = 3;       // 000 Eqs. 10-11, intensity at the mean's direction
// The mean normal length over which a diffuse lobe goes from the SG to Lambert's lobe (reference
// FLAT_CLUSTER).
const vec2 VSGL_FLAT_CLUSTER = vec2(0.95, 0.99);

// The mean length of a VSGL diffuse lobe's texel normals from its lam_v (reference
// mean_normal_length): |xi_v| (lam_d + 1) / lam_d with |xi_v| = lam_v / (lam_v + 1).
float vsgl_mean_normal_length(float lobe_sharpness)
{
  float lam = max(lobe_sharpness, 0.0);
  return clamp(lam / (lam + 1.0) * ((DIFFUSE_SHARPNESS + 1.0) / DIFFUSE_SHARPNESS), 0.0, 1.0);
}

// The separable diffuse's emission of a VSGL diffuse lobe per unit c_v towards `direction`, `axis`
// its axis (reference vsgl_diffuse_emission): 000 Eq. 6's SG blended by smoothstep over
// VSGL_FLAT_CLUSTER of the mean normal length into its texels' Lambertian lobe
// c_v A(lam_v) / (1 + e^-lam_d) max(mu, 0) / pi. The SG keeps e^-2 of its peak at the horizon, where
// a Lambertian texel sends nothing: a flat reflector lit what it sees edge-on too much (the
// occluder scene 0.83 -> 0.20 relative RMSE). (1 - w) a + w b, not mix's a + w (b - a): at w = 1 the
// SG's rounding would stay where it is much the larger.
float vsgl_diffuse_emission(vec3 direction, vec3 axis, float lobe_sharpness)
{
  float weight = smoothstep(VSGL_FLAT_CLUSTER.x, VSGL_FLAT_CLUSTER.y, vsgl_mean_normal_length(lobe_sharpness));
  float mu = dot(direction, axis);
  float lambert = sg_integral(lobe_sharpness) / DIFFUSE_HEMISPHERE_SCALE * max(mu, 0.0) * (1.0 / PI);
  return (1.0 - weight) * sg_evaluate(direction, axis, lobe_sharpness) + weight * lambert;
}

// Cap on the exponent of vsgl_diffuse_emission_ratio (reference EMISSION_RATIO_EXPONENT_MAX): a
// diffuse lobe's lam_v (<= lam_d = 2) keeps the exponent <= 2 where Lambert's lobe is non-zero; the
// cap only bounds out-of-range sharpnesses.
const float VSGL_EMISSION_RATIO_EXPONENT_MAX = 2.0 * DIFFUSE_SHARPNESS;

// vsgl_diffuse_emission over 000 Eq. 6's SG at the same direction, without the division (reference
// vsgl_diffuse_emission_ratio): (1 - w) + w P max(mu, 0) / pi e^min(lam_v (1 - mu), cap). 1 for a
// cluster that keeps the SG; Lambert's lobe over the SG for a flat one, 0 at and below its horizon.
float vsgl_diffuse_emission_ratio(vec3 direction, vec3 axis, float lobe_sharpness)
{
  float weight = smoothstep(VSGL_FLAT_CLUSTER.x, VSGL_FLAT_CLUSTER.y, vsgl_mean_normal_length(lobe_sharpness));
  float mu = min(dot(direction, axis), 1.0);
  float exponent = min(lobe_sharpness * (1.0 - mu), VSGL_EMISSION_RATIO_EXPONENT_MAX);
  float lambert = sg_integral(lobe_sharpness) / DIFFUSE_HEMISPHERE_SCALE * max(mu, 0.0) * (1.0 / PI) * exp(exponent);
  return (1.0 - weight) + weight * lambert;
}

// Incoming radiance SG of one VSGL lobe at `position` (000 Eq. 12), without c_v:
// xi_mu = (mu_v - y_p)/|mu_v - y_p|, lam_sigma = |mu_v - y_p|^2 / sigma_v^2,
// G(w; -xi_v, lam_v) G(w; xi_mu, lam_sigma) / (2 pi sigma_v^2) = scale * G(w; axis_in, sharpness_in).
// At y_p = mu_v lam_sigma = 0 and -xi_v stands in for xi_mu. lam_sigma is dist * (dist / var): no
// overflow of dist^2 before the division.
void vsgl_incoming_sg(vec3 position, vec3 mean, float variance, vec3 lobe_axis, float lobe_sharpness,
                      out vec3 axis_in, out float sharpness_in, out float scale)
{
  vec3 r = mean - position;
  float dist = safe_length(r);
  vec3 xi_mu = safe_normalize(r, -lobe_axis);
  float var = max(variance, VSGL_VARIANCE_FLOOR);
  float lam_sigma = dist * (dist / var);
  float product_scale;
  sg_product(-lobe_axis, lobe_sharpness, xi_mu, lam_sigma, axis_in, sharpness_in, product_scale);
  scale = product_scale / (TWO_PI * var);
}

// The separable incoming radiance of one VSGL lobe without c_v (reference vsgl_separable_lobe):
// G(-xi_mu; xi_v, lam_v) G(w; xi_mu, lam_sigma) / (2 pi sigma_v^2) = scale * G(w; xi_mu, lam_sigma).
// At y_p = mu_v (lam_sigma = 0) -xi_v stands in for xi_mu, as in vsgl_incoming_sg.
void vsgl_separable_lobe(vec3 position, vec3 mean, float variance, vec3 lobe_axis, float lobe_sharpness,
                         out vec3 xi_mu, out float lam_sigma, out float scale)
{
  vec3 r = mean - position;
  float dist = safe_length(r);
  xi_mu = safe_normalize(r, -lobe_axis);
  float var = max(variance, VSGL_VARIANCE_FLOOR);
  lam_sigma = dist * (dist / var);
  scale = sg_evaluate(-xi_mu, lobe_axis, lobe_sharpness) / (TWO_PI * var);
}

// Ld / (c_in Rd) (reference diffuse_factor); VSGL_DIFFUSE_SEPARABLE takes the positional lobe
// (xi_mu, lam_sigma) and is the cosine form of it.
float vsgl_diffuse_factor(vec3 axis_in, float sharpness_in, vec3 normal, int mode)
{
  if (mode == VSGL_DIFFUSE_CLAMPED_COSINE) {
    return sg_clamped_cosine_integral(dot(axis_in, normal), sharpness_in);
  }
  if (mode == VSGL_DIFFUSE_SG_CONVOLUTION) {
    return sg_product_integral(axis_in, sharpness_in, normal, DIFFUSE_SHARPNESS) /
           sg_integral(DIFFUSE_SHARPNESS);
  }
  return sg_integral(sharpness_in) * (1.0 / PI) * max(dot(axis_in, normal), 0.0);
}

// What the specular of a shading point needs, computed once per pixel.
struct VSGLReceiver {
  vec3 position;
  vec3 normal;
  vec3 view;       // unit, towards the eye
  float a2;        // alpha^2
  float d1_view;   // D(1) / (c_o + s_o); 0 when the view is below the normal (no specular)
  vec3 x_axis;     // the ASG of 003 (asg_specular_lobe)
  vec3 y_axis;
  float eta_x;
  float eta_y;
  vec3 reflection;             // the specular lobe warped to the reflection direction (000 Eq. 7)
  float reflection_sharpness;
};

VSGLReceiver vsgl_receiver(vec3 position, vec3 normal, vec3 view, float roughness)
{
  VSGLReceiver rc;
  rc.position = position;
  rc.normal = normal;
  rc.view = view;
  float alpha = max(roughness, VSGL_ALPHA_MIN);
  rc.a2 = alpha * alpha;
  vec3 z_axis;
  asg_specular_lobe(view, normal, alpha, rc.x_axis, rc.y_axis, z_axis, rc.eta_x, rc.eta_y);
  // Twice the precision (once per pixel): the view's chi+ decides between 0 and a finite grazing
  // limit D(1) / (alpha (c_o + s_o)); a plain dot product gets the sign of c_o ~ 1e-7 wrong.
  float co = dot_accurate(view, normal);
  rc.d1_view = co > 0.0 ? 1.0 / (PI * rc.a2 * ggx_g1_denominator(co, rc.a2)) : 0.0;
  specular_lobe_warp(view, normal, alpha, rc.reflection, rc.reflection_sharpness);
  return rc;
}

// Where the receiver's specular gathers a lobe's light from (reference specular_emission_direction):
// the axis of the product of the incoming SG (axis_in, sharpness_in) and the receiver's warped
// specular lobe, the incoming lobe's peak for a broad receiver, its mirror direction for a sharp one.
vec3 vsgl_specular_emission_direction(VSGLReceiver rc, vec3 axis_in, float sharpness_in)
{
  // The sharpnesses as weights in [0, 1] (lam_in reaches ~1e20: its square would overflow); the
  // reflection's is > 0. A sum that cancels (the lobes opposite and equally sharp) gives a short
  // vector, whose emission ratio is the SG's share, finite.
  float total = sharpness_in + rc.reflection_sharpness;
  vec3 summed = (sharpness_in / total) * axis_in + (rc.reflection_sharpness / total) * rc.reflection;
  return summed * inversesqrt(max(dot(summed, summed), 1e-24));
}

// k of the module comment without c_in and Fresnel; `m5` = (1 - xi_in.h)^5.
float vsgl_specular_factor(VSGLReceiver rc, vec3 axis_in, float sharpness_in, out float m5)
{
  // xi_in.h = |xi_in + w_o| / 2 for unit vectors: at grazing reflection xi_in + w_o cancels and its
  // normalized direction is poor (3e-4 rad at |xi_in + w_o| = 2e-4), its length is not.
  float m = 1.0 - clamp(0.5 * safe_length(axis_in + rc.view), 0.0, 1.0);
  float m2 = m * m;
  m5 = m2 * m2 * m;
  if (!(rc.d1_view > 0.0)) {
    return 0.0;
  }
  float ci = max(dot(axis_in, rc.normal), 0.0);
  // sg_asg_convolution with the rendering equation's cosine <w, n> in place of the ASG's <w, z>.
#ifdef VSGL_ACCURATE_ASG
  float conv = sg_asg_convolution(axis_in, sharpness_in, rc.x_axis, rc.y_axis, rc.normal, rc.eta_x,
                                  rc.eta_y);
#else
  // asg.glsl's sg_asg_convolution with plain float32 tangent cosines: its dot_accurate branch for
  // sharp lobes buys nothing here, because xi_in is itself computed and rounded to float32 (~6e-8
  // per component) before the dot product. Measured on the lobe grid of tests/test_vsgl_shading_gpu.py
  // (well-conditioned points): worst relative error 2.6e-5 plain vs 2.5e-5 compensated; the pass is
  // 15 % faster on llvmpipe (64x64 pixels x 1024 VSGLs: 165 ms vs 189 ms), which runs both sides of
  // the branch. Define VSGL_ACCURATE_ASG to get the library's version.
  float nu = 0.5 * sharpness_in;
  float sum_x = rc.eta_x + nu;
  float sum_y = rc.eta_y + nu;
  float reduced_x = sum_x > 0.0 ? rc.eta_x * (nu / sum_x) : 0.0;
  float reduced_y = sum_y > 0.0 ? rc.eta_y * (nu / sum_y) : 0.0;
  float cx = dot(axis_in, rc.x_axis);
  float cy = dot(axis_in, rc.y_axis);
  float conv = PI / (sqrt(sum_x) * sqrt(sum_y)) * ci * exp(-reduced_x * cx * cx - reduced_y * cy * cy);
#endif
  return conv * rc.d1_view / ggx_g1_denominator(ci, rc.a2);
}

// Adds one VSGL lobe (amplitude c_v RGB, axis xi_v, sharpness lam_v; position mu_v, sigma_v^2).
void vsgl_accumulate_lobe(VSGLReceiver rc, vec3 mean, float variance, vec3 amplitude, vec3 lobe_axis,
                          float lobe_sharpness, int diffuse_mode, inout vec3 diffuse,
                          inout vec3 specular, inout vec3 fresnel)
{
  vec3 axis_in;
  float sharpness_in;
  float scale;
  vsgl_incoming_sg(rc.position, mean, variance, lobe_axis, lobe_sharpness, axis_in, sharpness_in,
                   scale);
  vec3 c_in = amplitude * scale;
  if (diffuse_mode == VSGL_DIFFUSE_SEPARABLE) {
    vec3 xi_mu;
    float lam_sigma;
    float separable_scale;
    vsgl_separable_lobe(rc.position, mean, variance, lobe_axis, lobe_sharpness, xi_mu, lam_sigma,
                        separable_scale);
    diffuse += amplitude * (separable_scale * vsgl_diffuse_factor(xi_mu, lam_sigma, rc.normal, diffuse_mode));
  }
  else {
    diffuse += c_in * vsgl_diffuse_factor(axis_in, sharpness_in, rc.normal, diffuse_mode);
  }
  float m5;
  float k = vsgl_specular_factor(rc, axis_in, sharpness_in, m5);
  specular += c_in * (k * (1.0 - m5));
  fresnel += c_in * (k * m5);
}

// What shading needs of one lobe's positional Gaussian seen from the shading point (000 Eqs. 11-12):
// xi_mu = (mu_v - y_p)/|mu_v - y_p|, lam_sigma = |mu_v - y_p|^2 / sigma_v^2 (dist * (dist / var): no
// overflow of dist^2 before the division) and 1 / (2 pi sigma_v^2). At y_p = mu_v lam_sigma = 0 and
// xi_mu drops out of the product (any unit vector would do).
struct VSGLPosition {
  vec3 xi_mu;
  float lam_sigma;
  float inv_area;
};

VSGLPosition vsgl_position(vec3 shading_position, vec3 mean, float variance)
{
  vec3 r = mean - shading_position;
  float dist = safe_length(r);
  float var = max(variance, VSGL_VARIANCE_FLOOR);
  VSGLPosition p;
  p.xi_mu = safe_normalize(r, vec3(0.0, 0.0, 1.0));
  p.lam_sigma = dist * (dist / var);
  p.inv_area = 1.0 / (TWO_PI * var);
  return p;
}

// Adds both lobes of one VSGL (its diffuse and its specular SG), each at its own position
// (per-lobe positional distribution; with the paper's shared one, 000 app. B.2, the caller passes
// the same VSGLPosition twice and computes it once: vsgl_addon/reference/vsgl.py
// POSITIONAL_DISTRIBUTIONS). The same sums as two vsgl_accumulate_lobe calls. A lobe without power
// (amplitude 0: the 2-VSGL mode's rows, empty clusters, an occluded one) is not skipped: for finite
// fields every factor its amplitude multiplies is finite (variance floored, product exponent <= 0,
// eta_x, eta_y > 0), so it adds +-0 to sums that start at +0 and never become -0: the same bits.
// llvmpipe's masked `continue` cost more than the lobe (demo.blend, 128² x 1024 VSGLs: 0.64-0.73x
// the shading time without it).
void vsgl_accumulate(VSGLReceiver rc, VSGLPosition diffuse_position, vec3 diffuse_amplitude,
                     vec3 diffuse_axis, float diffuse_sharpness, VSGLPosition specular_position,
                     vec3 specular_amplitude, vec3 specular_axis, float specular_sharpness,
                     int diffuse_mode, inout vec3 diffuse, inout vec3 specular, inout vec3 fresnel)
{
  for (int lobe = 0; lobe < 2; lobe++) {
    vec3 amplitude = lobe == 0 ? diffuse_amplitude : specular_amplitude;
    vec3 lobe_axis = -(lobe == 0 ? diffuse_axis : specular_axis);
    float lobe_sharpness = lobe == 0 ? diffuse_sharpness : specular_sharpness;
    VSGLPosition at = lobe == 0 ? diffuse_position : specular_position;
    vec3 xi_mu = at.xi_mu;
    float lam_sigma = at.lam_sigma;
    float inv_area = at.inv_area;
    // sg_product(lobe_axis, lobe_sharpness, xi_mu, lam_sigma, ...) with one length.
    vec3 xi_m = sg_product_vector(lobe_axis, lobe_sharpness, xi_mu, lam_sigma);
    // safe_length(xi_m) and safe_normalize(xi_m, lobe_axis) with one scaling (same arithmetic).
    float largest = max(max(abs(xi_m.x), abs(xi_m.y)), abs(xi_m.z));
    float sharpness_in = 0.0;
    vec3 axis_in = lobe_axis;
    if (largest > 0.0) {
      vec3 scaled = xi_m / largest;
      float squared = dot(scaled, scaled);
      sharpness_in = largest * sqrt(squared);
      axis_in = scaled * inversesqrt(squared);
    }
    float product_scale = exp(sg_product_exponent(lobe_axis, lobe_sharpness, xi_mu, lam_sigma,
                                                  sharpness_in));
    vec3 c_in = amplitude * (product_scale * inv_area);
    if (diffuse_mode == VSGL_DIFFUSE_SEPARABLE) {
      // vsgl_separable_lobe from the VSGLPosition (lobe_axis is -xi_v here: G(xi_mu; -xi_v, lam_v)).
      // A flat diffuse lobe emits as its texels' Lambertian lobe (vsgl_diffuse_emission), the
      // specular lobe as its SG.
      vec3 xi_sep = lam_sigma > 0.0 ? xi_mu : lobe_axis;
      float emission = lobe == 0 ? vsgl_diffuse_emission(xi_sep, lobe_axis, lobe_sharpness) :
                                   sg_evaluate(xi_sep, lobe_axis, lobe_sharpness);
      diffuse += amplitude * (emission * inv_area * vsgl_diffuse_factor(xi_sep, lam_sigma, rc.normal, diffuse_mode));
      // The specular keeps Eq. 12's lobe but sees a flat diffuse lobe's Lambertian emission too, taken
      // where it gathers the lobe's light (the reference's shade; docs/accuracy.md).
      float ratio = vsgl_diffuse_emission_ratio(vsgl_specular_emission_direction(rc, axis_in, sharpness_in),
                                                lobe_axis, lobe_sharpness);
      c_in *= lobe == 0 ? ratio : 1.0;
    }
    else {
      diffuse += c_in * vsgl_diffuse_factor(axis_in, sharpness_in, rc.normal, diffuse_mode);
    }
    float m5;
    float k = vsgl_specular_factor(rc, axis_in, sharpness_in, m5);
    specular += c_in * (k * (1.0 - m5));
    fresnel += c_in * (k * m5);
  }
}
