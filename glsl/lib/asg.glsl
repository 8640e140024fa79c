// @require lib/math.glsl
// @require lib/sg.glsl
//
// Anisotropic spherical Gaussians Ga(w; x, y, z, eta_x, eta_y) = <w, z> exp(-eta_x (w.x)^2 -
// eta_y (w.y)^2) with an orthonormal frame (x, y, z) (formulas.md section 2). Papers: 000 = Tokuyoshi
// VSGL (CVM 2016) app. C; 001 = rectangle-based MRP-ASG, Eqs. 2, 11, 34; 003 = Square Enix SG talk.
// Twins of vsgl_addon/reference/asg.py (same names, same semantics, float32).

// Below this sine between view and normal the plane of incidence is undefined and the lobe is
// isotropic anyway (1/cos^2 - 1 < 1e-14): a fixed tangent is used. Same value as reference/asg.py.
const float ASG_PARALLEL_SINE = 1e-7;

// A plain dot product of unit vectors w.t is off by up to ~1.8e-7 (three rounded products, two
// rounded sums), which moves the exponent eta (w.t)^2 by up to 2 eta |w.t| 1.8e-7: 3.6e-5 at
// eta |w.t| = 100. Beyond that, and where the ASG is not negligible (exponent below 64, e^-64 =
// 1.6e-28), w.t is recomputed in twice the precision. Both hold only for bandwidths above
// (100/8)^2 = 156, so a GPU skips the branch for the usual reduced bandwidths of VSGL shading
// (<= nu). llvmpipe executes both sides of every branch under a mask: there it always costs
// (sg_asg_convolution measured ~1.7x slower than with plain dot products).
const float ASG_ACCURATE_TANGENT = 100.0;
const float ASG_NEGLIGIBLE_EXPONENT = 64.0;

// w.t for a tangent axis t of an ASG of bandwidth eta. Inside a sharp lobe w.t is a small value
// cancelled out of O(1) products: at eta = 1e7 a plain dot product changes the ASG by up to 6e-4.
float asg_tangent_cosine(vec3 omega, vec3 tangent, float eta)
{
  float c = dot(omega, tangent);
  float spread = eta * abs(c);
  // An if, not ?: (which compilers flatten into evaluating both sides).
  if (spread > ASG_ACCURATE_TANGENT && spread * abs(c) < ASG_NEGLIGIBLE_EXPONENT) {
    c = dot_accurate(omega, tangent);
  }
  return c;
}

// Ga(w) = max(w.z, 0) exp(-eta_x (w.x)^2 - eta_y (w.y)^2) (000 app. C; 001 Eq. 2). The factor w.z
// needs no care: its rounding error is absolute (~1e-7) and the ASG is at most 1.
float asg_evaluate(vec3 omega, vec3 x_axis, vec3 y_axis, vec3 z_axis, float eta_x, float eta_y)
{
  float cx = asg_tangent_cosine(omega, x_axis, eta_x);
  float cy = asg_tangent_cosine(omega, y_axis, eta_y);
  return max(dot(omega, z_axis), 0.0) * exp(-eta_x * cx * cx - eta_y * cy * cy);
}

// A unit vector perpendicular to unit z; Duff et al., "Building an orthonormal basis, revisited"
// (JCGT 2017), branchless and exact for unit z. The same lines as reference/asg.py's _any_tangent,
// so both pick the same tangent.
vec3 asg_any_tangent(vec3 z)
{
  float s = z.z >= 0.0 ? 1.0 : -1.0;
  float a = -1.0 / (s + z.z);
  float b = z.x * z.y * a;
  return vec3(1.0 + s * z.x * z.x * a, s * b, -s * z.x);
}

// The microfacet specular lobe at a shading point as an ASG (003; 000 app. C). `view` = w_o points
// from the surface to the viewer. z = 2 (w_o.n) n - w_o (mirror direction), x = normalize(n x w_o)
// (perpendicular to the plane of incidence; a fixed tangent of z when w_o is parallel to n),
// y = z x x, so x cross y = z. eta_x = lam_h / (8 max((w_o.n)^2, COSINE_FLOOR^2)) narrows the lobe
// across the plane at grazing incidence, eta_y = lam_h / 8 (halves of the warped sharpnesses
// lam_h / (4 cos^2) and lam_h / 4, 000 Eq. 7). At grazing incidence w_o.n is a cancelling sum
// whose plain rounding (~6e-8) is 6e-4 of a cosine of 1e-4: dot_accurate keeps eta_x exact to float32.
void asg_specular_lobe(vec3 view, vec3 normal, float roughness, out vec3 x_axis, out vec3 y_axis,
                       out vec3 z_axis, out float eta_x, out float eta_y)
{
  float cos_o = dot_accurate(view, normal);
  z_axis = 2.0 * cos_o * normal - view;
  // n x w_o = n x (w_o -+ n): near normal incidence w_o - n is exact (Sterbenz) and small, so the
  // cross product keeps full relative precision; n x w_o itself has an absolute error of ~6e-8,
  // which at a sine of 1e-6 turns the frame by several degrees.
  vec3 x_raw = cross(normal, view - (cos_o >= 0.0 ? normal : -normal));
  if (length(x_raw) <= ASG_PARALLEL_SINE) {
    x_raw = asg_any_tangent(z_axis);
  }
  // Gram-Schmidt against z, as the reference does (x_raw is perpendicular to z up to rounding).
  x_raw -= dot(x_raw, z_axis) * z_axis;
  x_axis = safe_normalize(x_raw, asg_any_tangent(z_axis));
  y_axis = cross(z_axis, x_axis);
  float lam_h = ndf_sharpness(roughness);
  eta_x = lam_h / (8.0 * max(cos_o * cos_o, COSINE_FLOOR * COSINE_FLOOR));
  eta_y = lam_h / 8.0;
}

// Approximate integral of G(w; p, lam) Ga(w; x, y, z, eta_x, eta_y) over the sphere (000 app. C after
// Xu et al. 2013; 001 Eq. 11), nu = lam / 2:
//   pi / sqrt((eta_x + nu)(eta_y + nu)) * Ga(p; x, y, z, eta_x nu / (eta_x + nu), eta_y nu / (eta_y + nu)).
// nu = lam / 2 because exp(lam (w.p - 1)) = exp(-nu |w - p|^2) (formulas.md section 2; the quadrature
// in docs/accuracy.md confirms it). The square roots are taken separately, as in the reference:
// (eta_x + nu)(eta_y + nu) reaches ~1e27 for grazing glossy lobes (eta_x = 2.5e13), within float32
// but not by a wide margin. eta nu / (eta + nu) is written eta * (nu / (eta + nu)) for the same reason.
float sg_asg_convolution(vec3 sg_axis, float sg_sharpness, vec3 x_axis, vec3 y_axis, vec3 z_axis,
                         float eta_x, float eta_y)
{
  float nu = 0.5 * sg_sharpness;
  float sum_x = eta_x + nu;
  float sum_y = eta_y + nu;
  float reduced_x = sum_x > 0.0 ? eta_x * (nu / sum_x) : 0.0;
  float reduced_y = sum_y > 0.0 ? eta_y * (nu / sum_y) : 0.0;
  float scale = PI / (sqrt(sum_x) * sqrt(sum_y));
  return scale * asg_evaluate(sg_axis, x_axis, y_axis, z_axis, reduced_x, reduced_y);
}

// Approximate integral of amplitude * Ga over the sphere, pi t / sqrt(eta_x eta_y) (001 Eq. 34):
// exact up to ~e^(-min(eta)), an overestimate for small bandwidths (docs/accuracy.md). Separate
// square roots for the same overflow reason as sg_asg_convolution.
float asg_integral(float eta_x, float eta_y, float amplitude)
{
  return PI * amplitude / (sqrt(eta_x) * sqrt(eta_y));
}
