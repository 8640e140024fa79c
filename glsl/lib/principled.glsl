// @require lib/ggx.glsl
//
// Blender's Principled BSDF base layer as Cycles renders it: Lambert diffuse under a dielectric GGX
// layer (real Fresnel of the IOR adjusted to Specular IOR Level), a metallic GGX layer (Schlick with
// F0 = base colour, = Cycles' F82-tint for the default white tint), Smith height-correlated masking,
// Cycles' multiple-scattering energy preservation. The model, its sources and its measurement
// against Cycles: vsgl_addon/reference/principled.py (the float64 twin: same names, same semantics).
// Directions point away from the surface, unit; `incoming` towards the light, `outgoing` towards
// the viewer. BRDFs exclude the cosine.

const float PRINCIPLED_ALPHA_MIN = 1e-6;
const float PRINCIPLED_F0_MAX = 0.9999;
const float PRINCIPLED_MU_MIN = 1e-4;
const int PRINCIPLED_ALBEDO_GRID = 8;
const int PRINCIPLED_AVERAGE_GRID = 4;

// GGX alpha = roughness^2 (roughness clamped to [0, 1]), at least PRINCIPLED_ALPHA_MIN.
float principled_alpha(float roughness)
{
  float r = clamp(roughness, 0.0, 1.0);
  return max(r * r, PRINCIPLED_ALPHA_MIN);
}

// F0 = ((ior - 1) / (ior + 1))^2 * 2 * level, clamped to [0, PRINCIPLED_F0_MAX].
float principled_dielectric_f0(float ior, float specular_ior_level)
{
  float ratio = (ior - 1.0) / (ior + 1.0);
  return clamp(ratio * ratio * 2.0 * max(specular_ior_level, 0.0), 0.0, PRINCIPLED_F0_MAX);
}

// Unpolarised Fresnel reflectance of a dielectric with normal-incidence reflectance f0
// (eta = (1 + sqrt f0) / (1 - sqrt f0), seen from outside).
float fresnel_dielectric_f0(float cos_theta, float f0)
{
  float c = clamp(abs(cos_theta), 0.0, 1.0);
  float root = sqrt(clamp(f0, 0.0, PRINCIPLED_F0_MAX));
  float eta = (1.0 + root) / (1.0 - root);
  float g = sqrt(max(eta * eta - 1.0 + c * c, 0.0));
  float a = (g - c) / max(g + c, 1e-30);
  float b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
  return clamp(0.5 * a * a * (1.0 + b * b), 0.0, 1.0);
}

vec3 fresnel_schlick_rgb(float cos_theta, vec3 f0)
{
  float m = 1.0 - clamp(cos_theta, 0.0, 1.0);
  float m2 = m * m;
  return f0 + (1.0 - f0) * (m2 * m2 * m);
}

// 2 mu_i / (mu_o s_i + mu_i s_o), s = sqrt(mu^2 + alpha^2 (1 - mu^2)): height-correlated G2 / mu_o.
float principled_g2_ratio(float ci, float co, float a2)
{
  float si = sqrt(ci * ci + a2 * (1.0 - ci * ci));
  float so = sqrt(co * co + a2 * (1.0 - co * co));
  return 2.0 * ci / (co * si + ci * so);
}

// Single-scattering directional albedos of GGX at mu_o: with Fresnel 1 (e_white), the dielectric
// Fresnel of f0_dielectric (e_dielectric), Schlick of f0_metal (e_metal). grid^2 stratified half
// vectors from the NDF (reference: albedo_quadrature).
void principled_directional_albedos(float mu_o, float roughness, float f0_dielectric, vec3 f0_metal,
                                    int grid, out float e_white, out float e_dielectric,
                                    out vec3 e_metal)
{
  float mu = clamp(mu_o, PRINCIPLED_MU_MIN, 1.0);
  float alpha = principled_alpha(roughness);
  float a2 = alpha * alpha;
  float sin_o = sqrt(max(1.0 - mu * mu, 0.0));
  float inv_count = 1.0 / float(grid * grid);
  float white = 0.0;
  float dielectric = 0.0;
  float schlick = 0.0;
  for (int i = 0; i < grid; i++) {
    float u1 = (float(i) + 0.5) / float(grid);
    float cos2 = (1.0 - u1) / (1.0 + (a2 - 1.0) * u1);
    float ch = sqrt(cos2);
    float sh = sqrt(max(1.0 - cos2, 0.0));
    for (int j = 0; j < grid; j++) {
      float phi = TWO_PI * (float(j) + 0.5) / float(grid);
      float oh = sin_o * sh * cos(phi) + mu * ch;
      float ci = 2.0 * oh * ch - mu;
      if (ci > 0.0 && oh > 0.0) {
        float w = principled_g2_ratio(ci, mu, a2) * oh / ch * inv_count;
        float m = 1.0 - clamp(oh, 0.0, 1.0);
        float m2 = m * m;
        white += w;
        dielectric += w * fresnel_dielectric_f0(oh, f0_dielectric);
        schlick += w * (m2 * m2 * m);
      }
    }
  }
  e_white = white;
  e_dielectric = dielectric;
  e_metal = f0_metal * (white - schlick) + schlick;
}

// E_avg = 2 int E_white(mu) mu dmu: 4-point Gauss-Legendre in mu, PRINCIPLED_AVERAGE_GRID^2 half
// vectors each.
float principled_average_albedo(float roughness)
{
  const float nodes[4] = float[4](0.0694318442029737, 0.3300094782075719, 0.6699905217924281,
                                  0.9305681557970263);
  const float weights[4] = float[4](0.1739274225687269, 0.3260725774312731, 0.3260725774312731,
                                    0.1739274225687269);
  float total = 0.0;
  for (int k = 0; k < 4; k++) {
    float e_white, e_dielectric;
    vec3 e_metal;
    principled_directional_albedos(nodes[k], roughness, 0.0, vec3(0.0), PRINCIPLED_AVERAGE_GRID,
                                   e_white, e_dielectric, e_metal);
    total += weights[k] * 2.0 * nodes[k] * e_white;
  }
  return total;
}

float principled_mean_schlick(float f0)
{
  return f0 + (1.0 - f0) / 21.0;
}

// 1 + F_ms (1 - E) / E, F_ms = F_ss E_avg / (1 - F_ss (1 - E_avg)).
vec3 principled_multiscatter(float e_white, float e_avg, vec3 fss)
{
  float e = clamp(e_white, 1e-3, 1.0);
  float avg = clamp(e_avg, 0.0, 1.0);
  vec3 fms = fss * avg / (1.0 - fss * (1.0 - avg));
  return 1.0 + fms * (1.0 - e) / e;
}

// Per-pixel terms (view-dependent through mu_o = n.wo), computed once before a loop over lights.
struct PrincipledTerms {
  vec3 diffuse;          // Rd = base (1 - metallic)(1 - E_spec(mu_o))
  float f0_dielectric;
  vec3 f0_metal;         // base colour
  float ms_dielectric;   // multiple-scattering factors
  vec3 ms_metal;
  vec3 specular_albedo;  // albedo of both specular lobes (Cycles' Glossy Color)
  float alpha;
  float metallic;
};

PrincipledTerms principled_terms(vec3 base_color, float metallic, float specular_ior_level,
                                 float ior, float roughness, float mu_o)
{
  PrincipledTerms t;
  vec3 base = max(base_color, vec3(0.0));
  float m = clamp(metallic, 0.0, 1.0);
  float f0 = principled_dielectric_f0(ior, specular_ior_level);
  float e_white, e_d;
  vec3 e_m;
  principled_directional_albedos(mu_o, roughness, f0, base, PRINCIPLED_ALBEDO_GRID, e_white, e_d,
                                 e_m);
  float e_avg = principled_average_albedo(roughness);
  t.ms_dielectric = principled_multiscatter(e_white, e_avg, vec3(principled_mean_schlick(f0))).x;
  t.ms_metal = principled_multiscatter(e_white, e_avg, base + (1.0 - base) / 21.0);
  float e_dielectric = clamp(e_d * t.ms_dielectric, 0.0, 1.0);
  vec3 e_metal = clamp(e_m * t.ms_metal, 0.0, 1.0);
  t.diffuse = base * (1.0 - m) * (1.0 - e_dielectric);
  t.f0_dielectric = f0;
  t.f0_metal = base;
  t.specular_albedo = (1.0 - m) * e_dielectric + m * e_metal;
  t.alpha = principled_alpha(roughness);
  t.metallic = m;
  return t;
}

// D G2 / (4 mu_i mu_o) with Smith height-correlated G2 = D / (2 (mu_o s_i + mu_i s_o)).
float principled_ggx_correlated(float ci, float co, float d, float a2)
{
  if (!(ci > 0.0 && co > 0.0)) {
    return 0.0;
  }
  float si = sqrt(ci * ci + a2 * (1.0 - ci * ci));
  float so = sqrt(co * co + a2 * (1.0 - co * co));
  return d / (2.0 * (co * si + ci * so));
}

// Diffuse and specular BRDFs (RGB, no cosine) for the terms of a pixel; 0 below either horizon.
// D of the half vector as microfacet_brdf (lib/ggx.glsl) takes it, ggx_half_vector_ndf: accurate
// cosines near grazing and sin^2 of the half vector in twice the precision near the peak of a
// sharp lobe.
void principled_brdf(PrincipledTerms t, vec3 incoming, vec3 outgoing, vec3 normal,
                     out vec3 diffuse, out vec3 specular)
{
  diffuse = vec3(0.0);
  specular = vec3(0.0);
  float a2 = t.alpha * t.alpha;
  float cos_i = ggx_cosine(incoming, normal);
  float cos_o = ggx_cosine(outgoing, normal);
  if (!(cos_i > 0.0 && cos_o > 0.0)) {
    return;
  }
  diffuse = t.diffuse / PI;
  vec3 half_sum = incoming + outgoing;
  float half_length = safe_length(half_sum);
  if (!(half_length > 0.0)) {
    return;
  }
  float d = ggx_half_vector_ndf(incoming, outgoing, normal, t.alpha);
  float lobe = principled_ggx_correlated(cos_i, cos_o, d, a2);
  float cos_ih = clamp(dot(incoming, half_sum) / half_length, 0.0, 1.0);
  vec3 f_metal = fresnel_schlick_rgb(cos_ih, t.f0_metal) * t.ms_metal;
  float f_dielectric = fresnel_dielectric_f0(cos_ih, t.f0_dielectric) * t.ms_dielectric;
  specular = ((1.0 - t.metallic) * f_dielectric + t.metallic * f_metal) * lobe;
}
