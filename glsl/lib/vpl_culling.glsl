// @require lib/ggx.glsl
//
// Stochastic light culling of glossy VPLs (formulas.md section 7). Paper 004 = Tokuyoshi and Harada,
// "Stochastic light culling for VPLs on GGX microsurfaces" (EGSR 2017), Eqs. 2-17. Twins of
// vsgl_addon/reference/vpl_culling.py (same names, same semantics, float32).

// delta xi floor: xi = 0 would give an infinite range; with it a unit-flux radius stays < 1e15.
const float VPL_DELTA_XI_MIN = 1e-30;
const float VPL_DIFFUSE_CENTRE = 0.43869133765083085;  // (1/3)^(3/4)
const float VPL_DIFFUSE_RADIUS = 0.6204032394013997;   // (4/27)^(1/4)

// PCG-RXS-M-XS 32-bit hash (Jarzynski and Olano 2020).
uint pcg_hash(uint v)
{
  uint state = v * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

// The one uniform xi in (0, 1) of a VPL for a seed and frame (004 Eqs. 2-3: per light, not per
// pixel). 23 bits, (h + 1/2) / 2^23: h + 1/2 < 2^23 is exact in float32, never 0 or 1.
float vpl_xi(uint index, uint seed, uint frame)
{
  uint seed_hash = pcg_hash(seed ^ pcg_hash(frame));
  uint h = pcg_hash(index + seed_hash);
  return (float(h >> 9u) + 0.5) * (1.0 / 8388608.0);
}

// The member of block k (VPLs k S ... k S + S - 1) a strided preview shades, in [0, S).
uint strided_vpl_jitter(uint k, uint seed, uint stride)
{
  return pcg_hash(k + pcg_hash(seed)) % stride;
}

// p = min(I / (delta l^2), 1) (004 Eq. 2); 1 at l = 0 with I > 0, 0 where I = 0.
float acceptance_probability(float intensity, float distance_squared, float delta)
{
  float den = delta * distance_squared;
  float p = den > 0.0 ? intensity / den : (intensity > 0.0 ? 1.0 : 0.0);
  return clamp(p, 0.0, 1.0);
}

// l_max = sqrt(I / (delta xi)) (004 Eq. 5).
float light_range(float intensity, float delta, float xi)
{
  return sqrt(max(intensity, 0.0) / max(delta * xi, VPL_DELTA_XI_MIN));
}

// w_u = 2 (w_i . n) n - w_i (004 Eq. 10).
vec3 mirror_direction(vec3 incoming, vec3 normal)
{
  return 2.0 * dot(incoming, normal) * normal - incoming;
}

// r = sqrt(Phi Fmax G1dist(w_i) / (4 pi delta xi |w_i.n|)) (004 Eq. 12), G1dist/|c| = 2 / (|c| + s),
// finite at grazing incidence.
float ggx_range_radius(float cos_incidence, float roughness, float flux, float delta, float xi, float fmax)
{
  float c = abs(cos_incidence);
  float g1_over_cos = 2.0 / ggx_g1_denominator(c, roughness * roughness);
  float num = max(flux, 0.0) * fmax * g1_over_cos;
  return sqrt(num / (4.0 * PI * max(delta * xi, VPL_DELTA_XI_MIN)));
}

// Bounding spheroid (004 Eqs. 13-15): semi-axes ((1 + a^2)/(2a) r, r, r), rotation rows
// (w_u, w_w x w_u, w_w), w_w = w_u x n / |w_u x n| (any perpendicular at normal incidence, where the
// spheroid is symmetric about w_u), centre q + (1 - a^2)/(2a) r w_u.
void ggx_spheroid(vec3 position, vec3 normal, vec3 incoming, float roughness, float flux, float delta,
                  float xi, float fmax, out vec3 centre, out vec3 semi_axes, out vec3 w_u, out vec3 w_v,
                  out vec3 w_w)
{
  w_u = safe_normalize(mirror_direction(incoming, normal), normal);
  // ggx_cosine: at grazing incidence a plain float32 dot is off by ~1e-7, which moves r by ~1e-7/alpha.
  float r = ggx_range_radius(ggx_cosine(incoming, normal), roughness, flux, delta, xi, fmax);
  vec3 cross_ = cross(w_u, normal);
  float length_ = length(cross_);
  vec3 helper = abs(w_u.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
  w_w = length_ > 1e-6 ? cross_ / length_ : normalize(cross(w_u, helper));
  w_v = cross(w_w, w_u);
  float a2 = roughness * roughness;
  semi_axes = vec3((1.0 + a2) / (2.0 * roughness) * r, r, r);
  centre = position + ((1.0 - a2) / (2.0 * roughness) * r) * w_u;
}

// Diffuse VPL: centre q + (1/3)^(3/4) R0 n, radius (4/27)^(1/4) R0, R0 = sqrt(Phi k / (pi delta xi)).
float diffuse_sphere(vec3 position, vec3 normal, float flux_reflectance, float delta, float xi, out vec3 centre)
{
  float r0 = sqrt(max(flux_reflectance, 0.0) / (PI * max(delta * xi, VPL_DELTA_XI_MIN)));
  centre = position + (VPL_DIFFUSE_CENTRE * r0) * normal;
  return VPL_DIFFUSE_RADIUS * r0;
}

// (n.c + d) / |diag(a) R n|: the signed distance of the unit sphere's centre from the plane after
// stretching by S = R^T diag(1/a) R (004 Eq. 16); the ellipsoid reaches the inside when >= -1.
float ellipsoid_plane_distance(vec3 plane_normal, float plane_offset, vec3 centre, vec3 semi_axes,
                               vec3 w_u, vec3 w_v, vec3 w_w)
{
  vec3 rn = vec3(dot(w_u, plane_normal), dot(w_v, plane_normal), dot(w_w, plane_normal));
  float support = length(semi_axes * rn);
  return (dot(plane_normal, centre) + plane_offset) / max(support, 1e-30);
}

// Exact ellipsoid-frustum test (twin of reference ellipsoid_frustum_overlap_exact): stretched by
// x' = diag(1/a) R (x - c) (004 Eq. 16) the ellipsoid is the unit sphere and the frustum, an affine
// image, is still a convex polyhedron; they meet iff its distance from the origin is <= 1. Outside
// every plane's reach (h_k < -1, Eq. 16's plane test) there is no overlap; inside all planes the
// centre is in the frustum; otherwise the closest point is the foot -h_k m_k of a face k (m_k its
// stretched unit normal) that every other plane j holds (h_j - h_k m_j.m_k >= 0), or lies on one of
// the 12 edges. planes[6] and corners[8] as reference tile_frustum_planes / tile_frustum_corners.
// `slack` widens the plane test; the face and edge tests widen by float32 rounding of the stretch,
// which grows with the stretched extent and |c| / a_min; where that extent is not representable
// (a_min ~ 0) the plane test's answer stands, so the test stays conservative.
bool ellipsoid_frustum_overlap_exact(vec4 planes[6], vec3 corners[8], vec3 centre, vec3 semi_axes, vec3 w_u,
                                     vec3 w_v, vec3 w_w, float slack)
{
  float h[6];
  vec3 m[6];
  bool inside = true;
  for (int k = 0; k < 6; k++) {
    vec3 n = planes[k].xyz;
    vec3 stretched = semi_axes * vec3(dot(w_u, n), dot(w_v, n), dot(w_w, n));
    float support = max(length(stretched), 1e-30);
    h[k] = (dot(n, centre) + planes[k].w) / support;
    m[k] = stretched / support;
    if (!(h[k] >= -1.0 - slack)) {
      return false;
    }
    inside = inside && h[k] >= 0.0;
  }
  if (inside) {
    return true;
  }
  float a_min = min(semi_axes.x, min(semi_axes.y, semi_axes.z));
  if (!(a_min > 0.0)) {
    return true;
  }
  vec3 local[8];
  float extent = 0.0;
  bool bounded = true;
  for (int i = 0; i < 8; i++) {
    vec3 d = corners[i] - centre;
    local[i] = vec3(dot(w_u, d), dot(w_v, d), dot(w_w, d)) / semi_axes;
    float l = length(local[i]);
    bounded = bounded && l < 1e12;
    extent = bounded ? max(extent, l) : extent;
  }
  if (!bounded) {
    return true;
  }
  float tolerance = slack + 4e-6 * (extent + length(centre) / a_min);
  for (int k = 0; k < 6; k++) {
    if (h[k] < 0.0) {
      bool foot = true;
      for (int j = 0; j < 6; j++) {
        foot = foot && (j == k || h[j] - h[k] * dot(m[j], m[k]) >= -tolerance);
      }
      if (foot) {
        return true;
      }
    }
  }
  const ivec2 edges[12] = ivec2[12](ivec2(0, 1), ivec2(1, 2), ivec2(2, 3), ivec2(3, 0), ivec2(4, 5), ivec2(5, 6),
                                    ivec2(6, 7), ivec2(7, 4), ivec2(0, 4), ivec2(1, 5), ivec2(2, 6), ivec2(3, 7));
  float limit = (1.0 + tolerance) * (1.0 + tolerance);
  for (int e = 0; e < 12; e++) {
    vec3 a = local[edges[e].x];
    vec3 s = local[edges[e].y] - a;
    float t = clamp(-dot(a, s) / max(dot(s, s), 1e-30), 0.0, 1.0);
    vec3 p = a + t * s;
    if (!(dot(p, p) > limit)) {
      return true;
    }
  }
  return false;
}

// Unshadowed f1 <w_o, n_q> <-w_o, n_x> / l^2 of a glossy VPL at a diffuse receiver (F = 1; the RGB
// weight is albedo/pi * Phi Rs) and, in `intensity`, the acceptance intensity scalar_flux f1 <w_o, n_q>.
float glossy_vpl_geometry(vec3 receiver, vec3 receiver_normal, vec3 position, vec3 normal, vec3 incoming,
                          float roughness, float scalar_flux, out float intensity, out float distance_squared)
{
  vec3 d = receiver - position;
  distance_squared = dot(d, d);
  vec3 w_o = safe_normalize(d, normal);
  float f1 = microfacet_brdf(incoming, w_o, normal, roughness, 1.0);
  float cos_q = max(dot(w_o, normal), 0.0);
  float cos_x = max(-dot(w_o, receiver_normal), 0.0);
  intensity = scalar_flux * f1 * cos_q;
  return distance_squared > 0.0 ? f1 * cos_q * cos_x / distance_squared : 0.0;
}
