// @require lib/math.glsl
//
// GGX microfacet BRDF (formulas.md section 3). Papers: 004 = Tokuyoshi and Harada, "Stochastic light
// culling for VPLs on GGX microsurfaces" (EGSR 2017), Eqs. 6-8; 001 = rectangle-based MRP-ASG, Eq. 16.
// Roughness alpha in (0, 1] (D(1) = 1 / (pi alpha^2)); `incoming` and `outgoing` point away from the
// surface. Twins of vsgl_addon/reference/ggx.py (same names, same semantics, float32).

// D(c) = alpha^2 chi+(c) / (pi (alpha^2 c^2 + (1 - c)(1 + c))^2) (004 Eq. 6; 001 Eq. 16). The textbook
// denominator 1 - (1 - alpha^2) c^2 cancels near c = 1: at alpha = 1e-3 it is ~1e-6 made of numbers
// ~1 rounded to 6e-8, so D is off by percents near its peak (2.6% measured on the test grid); here
// only positive terms are added, and (1 - c)(1 + c) is exact to rounding (1 - c is exact near 1,
// Sterbenz).
float ggx_ndf(float cos_theta_m, float roughness)
{
  float c = cos_theta_m;
  float a2 = roughness * roughness;
  float sin2 = max((1.0 - c) * (1.0 + c), 0.0);
  float denominator = a2 * c * c + sin2;
  return c > 0.0 ? a2 / (PI * denominator * denominator) : 0.0;
}

// |c| + sqrt((1 - alpha^2) c^2 + alpha^2) = 2 |c| / G1dist (004 Eq. 8).
float ggx_g1_denominator(float abs_cos, float a2)
{
  return abs_cos + sqrt((1.0 - a2) * abs_cos * abs_cos + a2);
}

// Smith masking of GGX, G1dist(c) = 2 |c| / (|c| + sqrt((1 - alpha^2) c^2 + alpha^2)) (004 Eq. 8).
float g1_distant(float cos_theta, float roughness)
{
  float abs_cos = abs(cos_theta);
  float denominator = ggx_g1_denominator(abs_cos, roughness * roughness);
  return denominator > 0.0 ? 2.0 * abs_cos / denominator : 0.0;
}

// Schlick's Fresnel F = f0 + (1 - f0)(1 - c)^5, c clamped to [0, 1] (rounding, back faces).
float fresnel_schlick(float cos_theta, float f0)
{
  float m = 1.0 - clamp(cos_theta, 0.0, 1.0);
  float m2 = m * m;
  return f0 + (1.0 - f0) * (m2 * m2 * m);
}

// Below this |w.n| the cosines of the BRDF are recomputed in twice the precision: a plain dot product
// of unit vectors is off by up to ~1.8e-7, which moves f by ~2 * 1.8e-7 / (|c| + alpha) (3.6e-5 at
// the threshold) and decides chi+ wrongly for cosines of ~1e-7 (measured: f = 0 instead of 65).
const float GGX_ACCURATE_COSINE = 0.01;
// Below this alpha^2 c_h^2 + sin^2 (near the peak of a sharp NDF), sin^2 of the half vector is
// recomputed in twice the precision: (1 - c)(1 + c) from a rounded c_h is off by ~1.2e-7 absolute,
// 2 * 1.2e-7 / 0.03 = 8e-6 of D at the threshold, but 40% near the peak of alpha = 1e-3 (measured).
const float GGX_ACCURATE_DENOMINATOR = 0.03;

float ggx_cosine(vec3 direction, vec3 normal)
{
  float c = dot(direction, normal);
  if (abs(c) < GGX_ACCURATE_COSINE) {  // an if, so that a GPU can skip it (?: evaluates both sides)
    c = dot_accurate(direction, normal);
  }
  return c;
}

// 1 - (h.n)^2 for h = (wi + wo) / |wi + wo|, in twice the precision: by Lagrange's identity it is
// |H x n|^2 / |H|^2 + (1 - |n|^2) with H = wi + wo. The cross product, from H in twice the precision
// (two_sum) and exact products, keeps its digits when H is nearly parallel to n; 1 - |n|^2 (~1e-7 for
// a float32 normal, comparable to sin^2 = 1e-6 at the peak of alpha = 1e-3) is kept as the reference
// keeps it.
float ggx_half_sine_squared(vec3 incoming, vec3 outgoing, vec3 normal, float half_length)
{
  vec2 hx = two_sum(incoming.x, outgoing.x);
  vec2 hy = two_sum(incoming.y, outgoing.y);
  vec2 hz = two_sum(incoming.z, outgoing.z);
  vec3 high = vec3(hx.x, hy.x, hz.x);
  vec3 low = vec3(hx.y, hy.y, hz.y);
  vec3 c;
  for (int i = 0; i < 3; i++) {
    int j = (i + 1) % 3;
    int k = (i + 2) % 3;
    vec2 p = two_product(high[j], normal[k]);
    vec2 q = two_product(high[k], normal[j]);
    vec2 s = two_sum(p.x, -q.x);
    precise float rest = ((p.y - q.y) + s.y) + (low[j] * normal[k] - low[k] * normal[j]);
    precise float component = s.x + rest;
    c[i] = component;
  }
  vec2 n2 = dot_accurate2(normal, normal);
  precise float one_minus_n2 = (1.0 - n2.x) - n2.y;
  vec3 scaled = c / half_length;
  return max(dot(scaled, scaled) + one_minus_n2, 0.0);
}

// D(wh.n) (004 Eq. 6) for the half vector of unit `incoming` and `outgoing` above the surface, 0
// for wi = -wo (no half vector). wh.n is taken as H.n / |H| with H = wi + wo: at grazing incidence
// |H| is small and exact (its components cancel, Sterbenz), whereas (c_i + c_o) / |H| would divide
// the cosines' rounding by |H|; it is > 0 whenever both cosines are (up to rounding, so D's chi+ is
// not applied). Near the peak of a sharp lobe (denominator below GGX_ACCURATE_DENOMINATOR),
// sin^2 of the half vector is taken in twice the precision (ggx_half_sine_squared). Shared by
// microfacet_brdf and lib/principled.glsl's principled_brdf.
float ggx_half_vector_ndf(vec3 incoming, vec3 outgoing, vec3 normal, float roughness)
{
  vec3 half_sum = incoming + outgoing;
  float half_length = safe_length(half_sum);
  if (!(half_length > 0.0)) {
    return 0.0;
  }
  float a2 = roughness * roughness;
  float cos_h = dot(half_sum, normal) / half_length;
  float sin2_h = max((1.0 - cos_h) * (1.0 + cos_h), 0.0);
  float denominator = a2 * cos_h * cos_h + sin2_h;
  if (denominator < GGX_ACCURATE_DENOMINATOR) {
    sin2_h = ggx_half_sine_squared(incoming, outgoing, normal, half_length);
    denominator = a2 * cos_h * cos_h + sin2_h;
  }
  return a2 / (PI * denominator * denominator);
}

// f = F(wi.wh) G1dist(wi) G1dist(wo) D(wh.n) / (4 |wi.n| |wo.n|) (004 Eqs. 7-8), evaluated as
// F D / ((c_i + s_i)(c_o + s_o)) with s = sqrt((1 - alpha^2) c^2 + alpha^2): the masking numerators
// 2 c_i 2 c_o cancel the denominator analytically, so the grazing limit stays finite. 0 below the
// horizon (chi+) and for wi = -wo (no half vector); D of the half vector: ggx_half_vector_ndf.
float microfacet_brdf(vec3 incoming, vec3 outgoing, vec3 normal, float roughness, float f0)
{
  float a2 = roughness * roughness;
  float cos_i = ggx_cosine(incoming, normal);
  float cos_o = ggx_cosine(outgoing, normal);
  vec3 half_sum = incoming + outgoing;
  float half_length = safe_length(half_sum);
  if (!(cos_i > 0.0 && cos_o > 0.0 && half_length > 0.0)) {
    return 0.0;
  }
  float d = ggx_half_vector_ndf(incoming, outgoing, normal, roughness);
  float f = fresnel_schlick(dot(incoming, half_sum) / half_length, f0);
  return f * d / (ggx_g1_denominator(cos_i, a2) * ggx_g1_denominator(cos_o, a2));
}
