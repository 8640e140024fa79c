// @require lib/math.glsl
//
// Spherical Gaussians G(w; xi, lam) = exp(lam (w.xi - 1)) and the SG reflection lobes
// (formulas.md section 1). Papers: 000 = Tokuyoshi, "Modified filtered importance sampling for
// virtual spherical Gaussian lights" (CVM 2016), app. A and Eqs. 6-7; 003 = the Square Enix SG talk.
// Twins of vsgl_addon/reference/sg.py (same names, same semantics, float32); unit vectors in,
// nothing is renormalized.

// Sharpness of the diffuse SG lobe, lam_d ~= 2 (000 Eq. 6). Same value as reference/sg.py.
const float DIFFUSE_SHARPNESS = 2.0;
// 1 + e^(-lam_d): 000 Eq. 6's lobe normalized over the hemisphere, where a Lambertian reflector
// emits, instead of the sphere (reference/sg.py DIFFUSE_HEMISPHERE_SCALE).
const float DIFFUSE_HEMISPHERE_SCALE = 1.1353352832366128;

// Floor on |w'.n| in the spherical warp (000 Eq. 7) and on (w_o.n) in the ASG bandwidths (003): the
// sharpness would be infinite at grazing incidence. Same value as reference/sg.py, whose comment
// shows the largest sharpnesses it allows stay finite in float32.
const float COSINE_FLOOR = 1e-4;

// G(w; xi, lam) (000 app. A) as exp(-lam/2 |w - xi|^2), equal for unit vectors. w.xi - 1 rounds to 0
// in float32 below ~3e-4 rad, which is most of a lobe of sharpness 1e6; w - xi is exact there
// (Sterbenz: the components are close), so the difference form keeps every digit of small angles
// (the dot form is 8% off on the test grid).
float sg_evaluate(vec3 omega, vec3 axis, float sharpness)
{
  vec3 d = omega - axis;
  return exp(-0.5 * sharpness * dot(d, d));
}

// A(lam) = integral of G over the sphere = 2 pi (1 - e^(-2 lam)) / lam (000 app. A), written as
// 4 pi (1 - e^(-2 lam)) / (2 lam) with an accurate 1 - e^(-x): exact to rounding at lam = 1e-6,
// 4 pi at lam = 0.
float sg_integral(float sharpness)
{
  return FOUR_PI * one_minus_exp_ratio(2.0 * sharpness);
}

// xi_m = lam1 xi1 + lam2 xi2 (000 app. A), summed as (lam_big - lam_small) xi_big +
// lam_small (xi1 + xi2). The direct sum cancels for nearly opposite lobes of similar sharpness
// (two vectors of length ~1e6 whose sum is ~1e3 keep ~4 correct digits in float32); here
// lam_big - lam_small and xi1 + xi2 are exact or accurate where they cancel, and the two terms
// never point into opposite half-spaces (xi_big . (xi1 + xi2) = 1 + xi1.xi2 >= 0), so their sum
// cannot cancel.
vec3 sg_product_vector(vec3 axis1, float sharpness1, vec3 axis2, float sharpness2)
{
  bool first_is_sharper = sharpness1 >= sharpness2;
  vec3 sharper_axis = first_is_sharper ? axis1 : axis2;
  float larger = max(sharpness1, sharpness2);
  float smaller = min(sharpness1, sharpness2);
  return (larger - smaller) * sharper_axis + smaller * (axis1 + axis2);
}

// d = |xi_m| - lam1 - lam2 as -lam1 lam2 |xi1 - xi2|^2 / (|xi_m| + lam1 + lam2) (formulas.md
// section 1): equal for unit axes, but the difference of two numbers ~2e6 would leave ~0.1 of
// absolute error for close sharp lobes. lam2 / (...) <= 1 keeps the product from overflowing.
float sg_product_exponent(vec3 axis1, float sharpness1, vec3 axis2, float sharpness2, float xi_m_length)
{
  vec3 difference = axis1 - axis2;
  float denominator = xi_m_length + sharpness1 + sharpness2;
  return denominator > 0.0 ? -(sharpness1 * (sharpness2 / denominator)) * dot(difference, difference) : 0.0;
}

// G(w; xi1, lam1) G(w; xi2, lam2) = scale * G(w; axis, sharpness) (000 app. A; 003):
// axis = xi_m / |xi_m|, sharpness = |xi_m|, scale = e^(|xi_m| - lam1 - lam2). When |xi_m| = 0 the
// product is the constant `scale` and axis1 is returned (any axis is right for sharpness 0).
void sg_product(vec3 axis1, float sharpness1, vec3 axis2, float sharpness2,
                out vec3 axis, out float sharpness, out float scale)
{
  vec3 xi_m = sg_product_vector(axis1, sharpness1, axis2, sharpness2);
  sharpness = safe_length(xi_m);
  axis = safe_normalize(xi_m, axis1);
  scale = exp(sg_product_exponent(axis1, sharpness1, axis2, sharpness2, sharpness));
}

// Integral of G(w; xi1, lam1) G(w; xi2, lam2) over the sphere (000 app. A; 003):
// 4 pi sinh(|xi_m|) / (e^(lam1 + lam2) |xi_m|) = 2 pi e^d (1 - e^(-2 |xi_m|)) / |xi_m|, which has
// neither the overflow of sinh and e^(lam1 + lam2) nor the cancellation of d; 4 pi e^(-lam1 - lam2)
// at |xi_m| = 0.
float sg_product_integral(vec3 axis1, float sharpness1, vec3 axis2, float sharpness2)
{
  float xi_m_length = safe_length(sg_product_vector(axis1, sharpness1, axis2, sharpness2));
  float d = sg_product_exponent(axis1, sharpness1, axis2, sharpness2, xi_m_length);
  return FOUR_PI * exp(d) * one_minus_exp_ratio(2.0 * xi_m_length);
}

// G(w; xi, lam) / A(lam), the von Mises-Fisher density (000 app. A, Eqs. 6-7): peaks at
// lam / (2 pi) for sharp lobes (1.6e5 at lam = 1e6), finite for lam in [0, ~1e38).
float sg_lobe_normalized(vec3 omega, vec3 axis, float sharpness)
{
  return sg_evaluate(omega, axis, sharpness) / sg_integral(sharpness);
}

// Lambert <w, n> / pi as a normalized SG of sharpness lam_d (000 Eq. 6). Times R_d outside.
float diffuse_lobe(vec3 omega, vec3 normal)
{
  return sg_lobe_normalized(omega, normal, DIFFUSE_SHARPNESS);
}

// lam_h = 2 / alpha^2: the SG fit of a Beckmann/GGX NDF normalized to max 1 (000 app. A.1; 003).
// alpha = 0 gives +inf (a mirror); callers clamp the roughness.
float ndf_sharpness(float roughness)
{
  return 2.0 / (roughness * roughness);
}

// lam_s = lam_h / (4 max(|w'.n|, COSINE_FLOOR)) (000 Eq. 7; see specular_lobe_warp).
float specular_lobe_sharpness(float cos_n, float roughness)
{
  return ndf_sharpness(roughness) / (4.0 * max(abs(cos_n), COSINE_FLOOR));
}

// Spherical warp of the NDF's SG to the outgoing domain (000 Eq. 7, after Wang et al.):
// xi_s = 2 (w'.n) n - w' (mirror direction of w', which points away from the surface),
// lam_s = lam_h / (4 |w'.n|) (000 writes |xi_s.n|, the same for unit vectors), with |w'.n| floored
// at COSINE_FLOOR so that lam_s stays finite at grazing incidence. Near grazing w'.n is a
// cancelling sum of O(1) products: its plain float32 rounding (~6e-8) is 6e-4 of a cosine of 1e-4
// and so of lam_s; dot_accurate keeps lam_s to float32 precision.
void specular_lobe_warp(vec3 incoming, vec3 normal, float roughness, out vec3 axis, out float sharpness)
{
  float cos_n = dot_accurate(incoming, normal);
  axis = 2.0 * cos_n * normal - incoming;
  sharpness = specular_lobe_sharpness(cos_n, roughness);
}

// rho_s <w, n> ~= R_s G(w; xi_s, lam_s) / A(lam_s), the energy-preserving form (000 Eq. 7).
// Times R_s outside. Not sg_lobe_normalized(w, xi_s, lam_s): xi_s rounded to float32 is off by
// ~6e-8, which inside a lobe of sharpness lam_s = 5e9 (roughness 1e-3, grazing) changes
// lam_s / 2 |w - xi_s|^2 by several percent. w - xi_s = (w + w') - 2 (w'.n) n is formed in twice the
// precision instead (the two parts are close where it matters, so their difference is exact).
float specular_lobe(vec3 omega, vec3 incoming, vec3 normal, float roughness)
{
  vec2 cos_n = dot_accurate2(incoming, normal);
  float sharpness = specular_lobe_sharpness(cos_n.x, roughness);
  vec3 d;
  for (int i = 0; i < 3; i++) {
    vec2 sum = two_sum(omega[i], incoming[i]);
    vec2 mirror = two_product(2.0 * cos_n.x, normal[i]);
    precise float low = (sum.y - mirror.y) - 2.0 * cos_n.y * normal[i];
    precise float difference = (sum.x - mirror.x) + low;
    d[i] = difference;
  }
  return exp(-0.5 * sharpness * dot(d, d)) / sg_integral(sharpness);
}

// S(mu, lam) = 1/pi int G(w; xi, lam) max(w.n, 0) dw, mu = xi.n: the diffuse light of a unit SG on a
// unit-albedo Lambert receiver (reference/sg.py, section "SG times the clamped cosine", which gives
// the formula, its sources and its measured error): Tokuyoshi, Ikeda, Kulkarni and Harada,
// "Hierarchical light sampling with accurate spherical Gaussian lighting" (SIGGRAPH Asia 2024,
// supplementary document, Listings 6-7), after Tokuyoshi, "Accurate diffuse lighting from spherical
// Gaussian lights" (HPG 2022 posters):
//   S = 2 (Sl + s (Su - Sl)), Su, Sl its exact values at mu = 1 and -1 over 2, s the clamped cosine
//   smoothed by a Gaussian of width 1/t(lam).
const float CLAMPED_COSINE_SERIES_LIMIT = 0.5;
const float CLAMPED_COSINE_T_A = 2.7360831611272558;
const float CLAMPED_COSINE_T_B = 17.021297781741875;
const float CLAMPED_COSINE_T_C = 4.0100826728510421;
const float CLAMPED_COSINE_T_D = 15.219156263147211;
const float CLAMPED_COSINE_T_E = 76.087896272360737;

// Sum over k = 0..8 of (x^k / (k + 2)!): the series of both hemisphere integrals below
// CLAMPED_COSINE_SERIES_LIMIT (truncation < 0.5^9 / 11! = 5e-11 relative), where their closed forms
// cancel.
float sg_clamped_cosine_series(float x)
{
  return 1.0 / 2.0 + x * (1.0 / 6.0 + x * (1.0 / 24.0 + x * (1.0 / 120.0 + x * (1.0 / 720.0 +
         x * (1.0 / 5040.0 + x * (1.0 / 40320.0 + x * (1.0 / 362880.0 + x * (1.0 / 3628800.0))))))));
}

// Su(lam) = 1/(2 pi) int G(w; n, lam) max(w.n, 0) dw = (lam - 1 + e^-lam) / lam^2.
float sg_upper_clamped_cosine(float sharpness)
{
  if (sharpness > CLAMPED_COSINE_SERIES_LIMIT) {
    return (1.0 - one_minus_exp_ratio(sharpness)) / sharpness;
  }
  return sg_clamped_cosine_series(-sharpness);
}

// Sl(lam) = 1/(2 pi) int G(w; -n, lam) max(w.n, 0) dw = e^-lam (1 - e^-lam (1 + lam)) / lam^2.
float sg_lower_clamped_cosine(float sharpness)
{
  float e = exp(-sharpness);
  if (sharpness > CLAMPED_COSINE_SERIES_LIMIT) {
    return e * (one_minus_exp_ratio(sharpness) - e) / sharpness;
  }
  return e * e * sg_clamped_cosine_series(sharpness);
}

// t(lam) = lam sqrt(1/2 (lam^2 + A lam + B) / (lam^3 + C lam^2 + D lam + E)), in 1/lam above lam = 1 so
// that lam^3 never forms (lam reaches 1e20).
float sg_clamped_cosine_steepness(float sharpness)
{
  float ratio;
  if (sharpness < 1.0) {
    ratio = ((sharpness + CLAMPED_COSINE_T_A) * sharpness + CLAMPED_COSINE_T_B) /
            (((sharpness + CLAMPED_COSINE_T_C) * sharpness + CLAMPED_COSINE_T_D) * sharpness + CLAMPED_COSINE_T_E);
  }
  else {
    float inv = 1.0 / sharpness;
    ratio = inv * ((CLAMPED_COSINE_T_B * inv + CLAMPED_COSINE_T_A) * inv + 1.0) /
            (((CLAMPED_COSINE_T_E * inv + CLAMPED_COSINE_T_D) * inv + CLAMPED_COSINE_T_C) * inv + 1.0);
  }
  return sharpness * sqrt(0.5 * ratio);
}

// s(mu, t) = 1/2 (mu erfc(-t mu) + erfc(t)) - e^(-t^2 mu^2) expm1(t^2 (mu^2 - 1)) / (2 sqrt(pi) t), in [0, 1].
float sg_clamped_cosine_lerp(float cosine, float steepness)
{
  float mu = clamp(cosine, -1.0, 1.0);
  float t = steepness;
  float tz = t * mu;
  float s = 0.5 * (mu * erfc(-tz) + erfc(t));
  if (t > 0.0) {
    s -= exp(-tz * tz) * expm1(t * t * (mu * mu - 1.0)) * (0.28209479177387814 / t);
  }
  return clamp(s, 0.0, 1.0);
}

float sg_clamped_cosine_integral(float cosine, float sharpness)
{
  float upper = sg_upper_clamped_cosine(sharpness);
  float lower = sg_lower_clamped_cosine(sharpness);
  float s = sg_clamped_cosine_lerp(cosine, sg_clamped_cosine_steepness(sharpness));
  return 2.0 * (lower + s * (upper - lower));
}
