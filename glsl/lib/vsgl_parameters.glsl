// @require lib/sg.glsl
//
// VSGL parameters from cluster totals of the RSM's VPL moments (000 app. B.1-B.3; formulas.md
// section 5). Twin of vsgl_addon/reference/vsgl.py (`_lobe`, `_position`, `texel_moments`),
// float32, with the same clamps. 000 = Tokuyoshi, "Modified filtered importance sampling for
// virtual spherical Gaussian lights" (CVM 2016).

// Rec. 709 luminance (Blender's scene-linear RGB): the scalar weight of an RGB power.
const vec3 LUMINANCE_WEIGHTS = vec3(0.2126, 0.7152, 0.0722);

// |xi_v| <= 1 - 2^-20, so lam_v <= 2^20 - 1 (reference MAX_AXIS_LENGTH; exact in float32).
const float MAX_AXIS_LENGTH = 0.99999904632568359375;
// sigma_v^2 >= max(2^-20 E|y|^2, 1e-12) (reference VARIANCE_FLOOR_RELATIVE / _ABSOLUTE).
const float VARIANCE_FLOOR_RELATIVE = 9.5367431640625e-07;
const float VARIANCE_FLOOR_ABSOLUTE = 1e-12;

const vec3 FALLBACK_AXIS = vec3(0.0, 0.0, 1.0);

float luminance(vec3 rgb)
{
  return dot(rgb, LUMINANCE_WEIGHTS);
}

// Toksvig's mean direction lam / (lam + 1) xi (000 app. B.1): 0 at lam = 0, xi at lam = +inf.
vec3 toksvig_mean_direction(vec3 axis, float sharpness)
{
  float factor = sharpness > 0.0 ? (isinf(sharpness) ? 1.0 : 1.0 / (1.0 + 1.0 / sharpness)) : 0.0;
  return factor * axis;
}

// v / |v| when `lit` and |v| is positive and finite, else 0 (reference `_unit_or_zero`).
vec3 unit_or_zero(vec3 v, bool lit)
{
  if (!lit || any(isnan(v)) || any(isinf(v))) {
    return vec3(0.0);
  }
  return safe_normalize(v, vec3(0.0));
}

// One SG lobe from sum(Phi R) (RGB) and sum(w xi_bar) (000 app. B.1): xi_bar_v = sum(w xi_bar) /
// sum(w), xi_v = xi_bar_v / |xi_bar_v|, lam_v = |xi_bar_v| / (1 - |xi_bar_v|), c_v = sum(Phi R) / A(lam_v).
void vsgl_lobe(vec3 power, vec3 direction_sum, out vec3 amplitude, out vec3 axis, out float sharpness)
{
  float weight = luminance(power);
  vec3 mean_direction = weight > 0.0 ? direction_sum / weight : vec3(0.0);
  float axis_length = safe_length(mean_direction);
  axis = axis_length > 0.0 ? safe_normalize(mean_direction, FALLBACK_AXIS) : FALLBACK_AXIS;
  axis_length = min(axis_length, MAX_AXIS_LENGTH);
  sharpness = axis_length / (1.0 - axis_length);
  amplitude = power / sg_integral(sharpness);
}

// mu_v = sum(w y) / sum(w), sigma_v^2 = sum(w |y|^2) / sum(w) - |mu_v|^2, floored (000 app. B.2).
void vsgl_position(float weight, vec3 position_sum, float position_squared_sum, vec3 fallback_mean,
                   float fallback_variance, out vec3 mean, out float variance)
{
  bool has = weight > 0.0;
  mean = has ? position_sum / weight : fallback_mean;
  float second = has ? position_squared_sum / weight : 0.0;
  variance = has ? second - dot(mean, mean) : fallback_variance;
  float floor_value = has ? max(VARIANCE_FLOOR_RELATIVE * second, VARIANCE_FLOOR_ABSOLUTE)
                          : VARIANCE_FLOOR_ABSOLUTE;
  variance = max(variance, floor_value);
}
