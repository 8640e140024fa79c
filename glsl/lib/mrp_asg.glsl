// @require lib/math.glsl
// @require lib/sg.glsl
// @require lib/asg.glsl
// @require lib/ggx.glsl
// @require lib/light_emission.glsl
//
// Glossy interreflection from one rectangle proxy with MRP-ASG (001 Eqs. 6-37; formulas.md sec. 8).
// Twins of vsgl_addon/reference/mrp_asg.py (same names, float32), whose module documentation
// derives each step: the specular peak (Eq. 12, exact for local lights), the radiance at the peak
// in Blender's units (not Eq. 17's distant-light form), the disk integral with the energy-matched
// k and the local-light spread, the area ratio from the bounding rectangle of disk and rectangle
// (normalised by the disk's square), the ASG light (Eqs. 18, 28-35), the receiver's NDF as an SG
// (Eqs. 6, 8) and its convolution with the ASG (Eq. 11, nu = lam / 2) or, in SG mode, Eq. 37.

const float MRP_ALPHA_MIN = 1e-3;
const float MRP_EXTENT_FLOOR = 1e-4;
const float MRP_EXTENT_MAX = 1e6;
const float MRP_BANDWIDTH_FLOOR = 1e-3;
const float MRP_K_OFFSET = 0.673;
// The sampling disk's radius in lobe footprints (reference DISK_LOBE_SCALE): at least this many.
const float MRP_DISK_LOBE_SCALE = 1.5;
const float MRP_LOG_INV_EPSILON = 2.996;
const int MRP_MODE_ASG = 0;
const int MRP_MODE_SG = 1;

// Eq. 12 for a distant light towards `incoming`: false (peak = position) when i.n_r <= 0 or the
// receiver is not in front of the plane.
bool mrp_peak_distant(vec3 position, vec3 center, vec3 normal, vec3 incoming, out vec3 peak)
{
  float cos_i = dot(incoming, normal);
  float height = dot(position - center, normal);
  peak = position;
  if (!(cos_i > 0.0 && height > 0.0)) {
    return false;
  }
  vec3 r = 2.0 * cos_i * normal - incoming;
  peak = position - r * (height / cos_i);
  return true;
}

// The exact peak of a point-like light: where the segment from the receiver to the light's mirror
// image crosses the plane. False when the receiver or the light is not in front of the plane.
bool mrp_peak_local(vec3 position, vec3 center, vec3 normal, vec3 light_position, out vec3 peak)
{
  float h_x = dot(position - center, normal);
  float h_l = dot(light_position - center, normal);
  peak = position;
  if (!(h_x > 0.0 && h_l > 0.0)) {
    return false;
  }
  vec3 mirror = light_position - 2.0 * h_l * normal;
  peak = position + (mirror - position) * (h_x / (h_x + h_l));
  return true;
}

// R's GGX BRDF at its own peak without the Fresnel factor: D(1) / (c + s)^2 (c_i = c_o = cos sigma).
float mrp_peak_brdf_geometry(float cos_sigma, float roughness)
{
  float c = max(cos_sigma, 0.0);
  float alpha = max(roughness, MRP_ALPHA_MIN);
  float a2 = alpha * alpha;
  float g = ggx_g1_denominator(c, a2);
  return 1.0 / (PI * a2 * g * g);
}

float mrp_peak_brdf(float cos_sigma, float roughness, float f0)
{
  return fresnel_schlick(max(cos_sigma, 0.0), f0) * mrp_peak_brdf_geometry(cos_sigma, roughness);
}

// L_y = f_r (i.n_r) E_perp (Blender's units: E_perp = I / d_l^2, or S for a sun).
float mrp_peak_radiance(float cos_sigma, float roughness, float f0, float irradiance_normal)
{
  float c = max(cos_sigma, 0.0);
  return mrp_peak_brdf(c, roughness, f0) * c * irradiance_normal;
}

// (1 - e^-x) / x for any real x, 1 at 0.
float mrp_exp_ratio(float x)
{
  return x != 0.0 ? -expm1(-x) / x : 1.0;
}

// E / L_y = pi t (1 - e^-kt) / (kt) (Eqs. 25-27) with k = 1 / (4 m_r^2 cos sigma) - 0.673 (the
// energy-matched fit), k > 0 scaled by spread^2 (spread = 1 + d_x / d_l), t = q / (1 + q),
// q = extent^2 cos^2 sigma.
float mrp_disk_integral(float cos_sigma, float roughness, float extent, float spread)
{
  float c = clamp(cos_sigma, 0.0, 1.0);
  float alpha = max(roughness, MRP_ALPHA_MIN);
  float k = 1.0 / (4.0 * alpha * alpha * max(c, COSINE_FLOOR)) - MRP_K_OFFSET;
  if (k > 0.0) {
    k *= spread * spread;
  }
  float e = min(extent, MRP_EXTENT_MAX);
  float q = e * e * c * c;
  float t = q / (1.0 + q);
  return PI * t * mrp_exp_ratio(k * t);
}

// rho_lobe, the unit-distance radius of the reflector lobe's footprint (reference mrp_lobe_extent):
// k t = 1 with mrp_disk_integral's k, rho = 1 / (cos sigma sqrt(k - 1)); MRP_EXTENT_MAX for k <= 1.
float mrp_lobe_extent(float cos_sigma, float roughness, float spread)
{
  float c = clamp(cos_sigma, COSINE_FLOOR, 1.0);
  float alpha = max(roughness, MRP_ALPHA_MIN);
  float k = 1.0 / (4.0 * alpha * alpha * c) - MRP_K_OFFSET;
  if (k > 0.0) {
    k *= spread * spread;
  }
  return k > 1.0 ? min(1.0 / (c * sqrt(k - 1.0)), MRP_EXTENT_MAX) : MRP_EXTENT_MAX;
}

// A of Eq. 36: the bounding rectangle of disk and R in R's frame, over the disk's square 4 r^2.
float mrp_area_ratio(vec3 peak, vec3 center, vec3 axis_u, vec3 axis_v, float half_u, float half_v,
                     float disk_radius)
{
  vec3 d = peak - center;
  float x0 = dot(d, axis_u);
  float y0 = dot(d, axis_v);
  float r = disk_radius;
  float dy = clamp(y0, -half_v, half_v) - y0;
  float dx = clamp(x0, -half_u, half_u) - x0;
  float wx = sqrt(max(r * r - dy * dy, 0.0));
  float wy = sqrt(max(r * r - dx * dx, 0.0));
  // min(x0 + w, a) - max(x0 - w, -a), written without subtracting the two ends (a small disk far
  // from R's centre would cancel them).
  float lx = max(min(wx, half_u - x0) + min(wx, half_u + x0), 0.0);
  float ly = max(min(wy, half_v - y0) + min(wy, half_v + y0), 0.0);
  float denominator = 4.0 * r * r;
  return denominator > 0.0 ? lx * ly / denominator : 0.0;
}

// Eq. 32 (epsilon = 0.05): (1 + 1/l^2)(2.996 - ln(1 + l^2) / 2), floored.
float mrp_bandwidth(float extent)
{
  float l = clamp(extent, MRP_EXTENT_FLOOR, MRP_EXTENT_MAX);
  float l2 = l * l;
  return max((1.0 + 1.0 / l2) * (MRP_LOG_INV_EPSILON - 0.5 * log(1.0 + l2)), MRP_BANDWIDTH_FLOOR);
}

// Eqs. 18, 28: m = normalize(yx x n_r), n = yx x m, z = -yx, yx = (p_x - p_y) / d; cos_n = n_r.yx.
void mrp_asg_frame(vec3 position, vec3 peak, vec3 normal, out vec3 m, out vec3 n, out vec3 z,
                   out float distance, out float cos_n)
{
  vec3 d_vec = position - peak;
  distance = safe_length(d_vec);
  vec3 yx = safe_normalize(d_vec, normal);
  vec3 v = cross(yx, normal);
  m = length(v) > 1e-6 ? normalize(v) : asg_any_tangent(yx);
  m = normalize(m - dot(m, yx) * yx);
  n = cross(yx, m);
  z = -yx;
  cos_n = dot(normal, yx);
}

// The receiver's NDF as an SG in the light domain (Eqs. 6, 8).
void mrp_receiver_sg(vec3 view, vec3 normal, float roughness, out vec3 axis, out float sharpness,
                     out float amplitude)
{
  float alpha = max(roughness, MRP_ALPHA_MIN);
  float cos_o = dot(view, normal);
  axis = 2.0 * cos_o * normal - view;
  sharpness = ndf_sharpness(alpha) / (4.0 * max(abs(cos_o), COSINE_FLOOR));
  amplitude = 1.0 / (PI * alpha * alpha);
}

// M(-r_y, o)(-r_y.n_x) of Eq. 10 without the Fresnel factor: c_i / ((c_i + s_i)(c_o + s_o)).
float mrp_receiver_geometry(vec3 incoming, vec3 view, vec3 normal, float roughness)
{
  float alpha = max(roughness, MRP_ALPHA_MIN);
  float a2 = alpha * alpha;
  float ci = dot(incoming, normal);
  float co = dot(view, normal);
  if (!(ci > 0.0 && co > 0.0)) {
    return 0.0;
  }
  return ci / (ggx_g1_denominator(ci, a2) * ggx_g1_denominator(co, a2));
}

float mrp_receiver_factor(vec3 incoming, vec3 view, vec3 normal, float roughness, float f0)
{
  vec3 h = safe_normalize(incoming + view, normal);
  return fresnel_schlick(dot(incoming, h), f0) * mrp_receiver_geometry(incoming, view, normal, roughness);
}

// The integral of the ASG light (amplitude t) times the receiver SG: Eq. 11 or Eq. 37's SG.
float mrp_convolve(vec3 view, vec3 normal, float roughness, vec3 m, vec3 n, vec3 z, float bandwidth_m,
                   float bandwidth_n, float amplitude, int mode)
{
  vec3 axis;
  float sharpness, sg_amplitude;
  mrp_receiver_sg(view, normal, roughness, axis, sharpness, sg_amplitude);
  // The receiver's GGX NDF as two SGs of the same peak and integral (reference RECEIVER_NDF_LOBES):
  // Eq. 8's single SG has a wider core than GGX and over-lights sharp receivers.
  const float weights[2] = float[2](0.83, 0.17);
  const float scales[2] = float[2](1.96, 0.17 / (1.0 - 0.83 / 1.96));
  float value = 0.0;
  for (int i = 0; i < 2; i++) {
    float lobe = scales[i] * sharpness;
    value += weights[i] * (mode == MRP_MODE_SG ?
                               sg_product_integral(z, 2.0 * max(bandwidth_m, bandwidth_n), axis, lobe) :
                               sg_asg_convolution(axis, lobe, m, n, z, bandwidth_m, bandwidth_n));
  }
  return amplitude * sg_amplitude * value;
}

// Schlick's Fresnel for an RGB F0 (linear in F0).
vec3 mrp_fresnel(float cos_theta, vec3 f0)
{
  float w = fresnel_schlick(cos_theta, 0.0);
  return vec3(w) + f0 * (1.0 - w);
}

// One rectangle, one light: L_x per unit light colour (RGB from both F0s), and the peak (for the
// caller's shadow lookup) with its direction to the light. Returns false when there is no peak
// or no contribution. `light_position`, `light_axis`, `params`, `light_to_local`: the light as
// lib/light_emission.glsl takes it. `visibility` multiplies afterwards (the caller's shadow).
bool mrp_shade(vec3 position, vec3 normal, vec3 view, float roughness, vec3 f0, vec3 center,
               vec3 rect_normal, vec3 axis_u, vec3 axis_v, float half_u, float half_v,
               float rect_roughness, vec3 rect_f0, vec3 light_position, vec3 light_axis, vec4 params,
               mat3 light_to_local, float disk_radius, int mode, out vec3 radiance, out vec3 peak)
{
  radiance = vec3(0.0);
  bool sun = int(params.x + 0.5) == LIGHT_SUN;
  bool valid = sun ? mrp_peak_distant(position, center, rect_normal, -light_axis, peak) :
                     mrp_peak_local(position, center, rect_normal, light_position, peak);
  if (!valid) {
    return false;
  }
  vec3 incoming;
  float irradiance;
  float light_distance;
  if (sun) {
    incoming = -light_axis;
    irradiance = params.w;
    light_distance = -1.0;
  }
  else {
    vec3 to_light = light_position - peak;
    light_distance = safe_length(to_light);
    incoming = safe_normalize(to_light, light_axis);
    irradiance = light_intensity(params, -incoming, light_axis, light_to_local) /
                 max(light_distance * light_distance, 1e-30);
  }
  float cos_sigma = clamp(dot(incoming, rect_normal), 0.0, 1.0);
  vec3 m, n, z;
  float distance, cos_n;
  mrp_asg_frame(position, peak, rect_normal, m, n, z, distance, cos_n);
  if (!(distance > 0.0 && irradiance > 0.0 && cos_sigma > 0.0)) {
    return false;
  }
  float spread = light_distance > 0.0 ? 1.0 + distance / light_distance : 1.0;
  // A disk of at least MRP_DISK_LOBE_SCALE lobe footprints: it holds the highlight for far
  // receivers, grazing light and rougher reflectors, which a fixed r_d loses (docs/accuracy.md).
  float extent = min(max(disk_radius / distance,
                         MRP_DISK_LOBE_SCALE * mrp_lobe_extent(cos_sigma, rect_roughness, spread)),
                     MRP_EXTENT_MAX);
  float total = mrp_area_ratio(peak, center, axis_u, axis_v, half_u, half_v, extent * distance) *
                mrp_disk_integral(cos_sigma, rect_roughness, extent, spread) *
                mrp_peak_brdf_geometry(cos_sigma, rect_roughness) * cos_sigma * irradiance;
  float bandwidth_m = mrp_bandwidth(extent);
  float bandwidth_n = mrp_bandwidth(extent * abs(cos_n));
  float amplitude = sqrt(bandwidth_m) * sqrt(bandwidth_n) / PI * total;
  float conv = mrp_convolve(view, normal, roughness, m, n, z, bandwidth_m, bandwidth_n, amplitude, mode);
  float geometry = mrp_receiver_geometry(z, view, normal, roughness);
  vec3 h = safe_normalize(z + view, normal);
  radiance = mrp_fresnel(cos_sigma, rect_f0) * mrp_fresnel(dot(z, h), f0) * (geometry * conv);
  return true;
}
