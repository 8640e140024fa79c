// Shared numerics for the SG, ASG and GGX libraries (float32 on every GPU).
//
// GLSL has no expm1: 1 - exp(-x) loses all its digits for small x (at x = 1e-6, exp(-x) rounds to
// 1 - 1.0133e-6 in float32, a 1.3% error), and the SG integral 2 pi (1 - e^(-2 lam)) / lam needs it
// for lam down to 1e-6 (000 app. A). Measured on llvmpipe: see tests/test_glsl_math.py.

const float PI = 3.14159265358979323846;
const float TWO_PI = 6.28318530717958647693;
const float FOUR_PI = 12.5663706143591729539;

// Below this |x| expm1 sums its Taylor series, above it takes exp(x) - 1. Measured on llvmpipe
// (tests/test_glsl_math.py): the series to x^8/8! is within 1.2e-7 relative of expm1 for
// |x| < 0.5 (truncation 0.5^8/9! = 1e-8); exp(x) - 1 is within ~1e-6 beyond, where it no longer
// cancels (it is 5e-6 off at x = 0.06, 1e-4 at 1e-3, 100% at 1e-7).
const float EXPM1_SERIES_LIMIT = 0.5;

// e^x - 1 with full relative precision near 0 (GLSL has no expm1).
float expm1(float x)
{
  if (abs(x) < EXPM1_SERIES_LIMIT) {
    return x * (1.0 + x * (1.0 / 2.0 + x * (1.0 / 6.0 + x * (1.0 / 24.0 + x * (1.0 / 120.0 +
           x * (1.0 / 720.0 + x * (1.0 / 5040.0 + x * (1.0 / 40320.0))))))));
  }
  return exp(x) - 1.0;
}

// (1 - e^(-x)) / x for x >= 0, 1 at x = 0: the integral of an SG divided by its naive bound
// (000 app. A). Finite for every x >= 0 including +inf (-> 0).
float one_minus_exp_ratio(float x)
{
  return x > 0.0 ? -expm1(-x) / x : 1.0;
}

// erfc(x) = 1 - erf(x) (GLSL has none): the Chebyshev fit of Press et al., Numerical Recipes
// (2nd ed., section 6.2, erfcc), fractional error below 1.2e-7 for every x; erfc(-x) = 2 - erfc(x).
// Underflows to 0 beyond x ~ 9.2 (float32), where erfc is below 1e-38.
float erfc(float x)
{
  float z = abs(x);
  float t = 1.0 / (1.0 + 0.5 * z);
  float r = t * exp(-z * z - 1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 +
            t * (-0.18628806 + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 +
            t * (-0.82215223 + t * 0.17087277)))))))));
  return x >= 0.0 ? r : 2.0 - r;
}

// v / |v|, or `fallback` when v is 0 (or denormal: the GPU flushes those to 0) and v / |v| would
// be NaN. Scaled by the largest component first so that dot(v, v) neither underflows (|v| < 1e-19)
// nor overflows (|v| > 1.8e19).
vec3 safe_normalize(vec3 v, vec3 fallback)
{
  float largest = max(max(abs(v.x), abs(v.y)), abs(v.z));
  if (!(largest > 0.0)) {
    return fallback;
  }
  vec3 scaled = v / largest;
  return scaled * inversesqrt(dot(scaled, scaled));
}

// |v| without underflow or overflow of the squares (see safe_normalize).
float safe_length(vec3 v)
{
  float largest = max(max(abs(v.x), abs(v.y)), abs(v.z));
  if (!(largest > 0.0)) {
    return 0.0;
  }
  vec3 scaled = v / largest;
  return largest * sqrt(dot(scaled, scaled));
}

// --- Twice the precision where a cancellation meets a large factor -------------------------------
//
// A dot product of unit vectors that cancels to a small value (a grazing cosine, the tangent
// coordinate of a direction inside a sharp lobe) carries an absolute error of up to ~1e-7 from the
// rounding of its O(1) products; multiplied by a sharpness of 1e6-1e13 that is a large relative
// error of the result (measured: 3e-4 for the warped sharpness at a cosine of 2e-4, 3% for a lobe of
// sharpness 5e9). The error-free transformations below give such values as if computed in twice the
// precision. `precise` keeps the compiler from contracting a * b + c into an fma or reassociating,
// either of which breaks them. No fma is needed: llvmpipe computes fma() as a rounded product and
// sum, so Dekker's product (with Veltkamp's split) is the portable choice. A compiler that ignored
// `precise` would simplify the error terms to 0 (or to an exact fma), never to something worse than
// the plain float32 result. Components must stay below ~1e34 in magnitude (4097 a must not overflow).

// a + b = s + e exactly (Knuth's TwoSum), returned as vec2(s, e).
vec2 two_sum(float a, float b)
{
  precise float s = a + b;
  precise float b_virtual = s - a;
  precise float e = (a - (s - b_virtual)) + (b - b_virtual);
  return vec2(s, e);
}

// a = high + low exactly, each with at most 12 significant bits (Veltkamp's split, 4097 = 2^12 + 1).
vec2 split_float(float a)
{
  precise float c = 4097.0 * a;
  precise float high = c - (c - a);
  precise float low = a - high;
  return vec2(high, low);
}

// a b = p + e exactly (Dekker 1971), returned as vec2(p, e).
vec2 two_product(float a, float b)
{
  precise float p = a * b;
  vec2 sa = split_float(a);
  vec2 sb = split_float(b);
  precise float e = ((sa.x * sb.x - p) + sa.x * sb.y + sa.y * sb.x) + sa.y * sb.y;
  return vec2(p, e);
}

// a.b as an unevaluated sum vec2(high, low), as accurate as if computed in twice the precision and
// rounded (Ogita, Rump and Oishi, "Accurate sum and dot product", SIAM J. Sci. Comput. 2005, Dot2).
vec2 dot_accurate2(vec3 a, vec3 b)
{
  vec2 px = two_product(a.x, b.x);
  vec2 py = two_product(a.y, b.y);
  vec2 pz = two_product(a.z, b.z);
  vec2 s = two_sum(px.x, py.x);
  vec2 t = two_sum(s.x, pz.x);
  precise float low = ((px.y + py.y) + (pz.y + s.y)) + t.y;
  precise float high = t.x + low;
  return vec2(high, low - (high - t.x));
}

// a.b rounded once from twice the precision (see dot_accurate2).
float dot_accurate(vec3 a, vec3 b)
{
  vec2 d = dot_accurate2(a, b);
  precise float rounded = d.x + d.y;
  return rounded;
}
