// @require lib/sg.glsl
//
// Reflective shadow map (RSM) pass, fragment stage: one virtual point light (VPL) per texel
// (formulas.md sec. 4; 000 sec. 4). Python side and the meaning of every input:
// vsgl_addon/passes/rsm.py; numpy twin of the texel quantities: vsgl_addon/reference/rsm.py.
//
// Outputs (RGBA32F, the layout VSGL generation reads, vsgl_addon/passes/vsgl_generation.py):
//   rsm_position      = (y, lam_s)         world position, sharpness of the warped specular lobe
//   rsm_normal        = (n, roughness)     shading normal facing the light, Principled roughness
//   rsm_flux_diffuse  = (Phi Rd, Phi_1)    Phi_1 = texel flux for a white light (W), Phi = Phi_1 colour
//   rsm_flux_specular = (Phi Rs, d_omega)  texel solid angle (sr), or its area (m^2) for a sun
//   rsm_specular_axis = (xi_s, 1)          axis of the warped specular lobe, coverage 1
// Texels that see no geometry keep the clear value 0 (coverage 0, flux 0).
//
// Per-view constants come in the 10x1 RGBA32F texture `view_constants` (push constants stay within
// the 128 bytes every backend guarantees): texels 0-2 the rows of mat3 view -> world, 3-5 the rows
// of mat3 world -> light local (inverse of the light's 3x3 world matrix, scale included),
// 6 light_position, 7 light_axis (unit, where the light points), 8 light_params
// (type code, cos half spot angle, 1 / ((1 - cos) spot_blend) or -1, intensity scale),
// 9 light_color.

// Light types (light_params.x); the numbering of rsm.py's LIGHT_TYPE_CODES.
const int LIGHT_POINT = 0;
const int LIGHT_SPOT = 1;
const int LIGHT_SUN = 2;
const int LIGHT_AREA = 3;

// Smallest GGX alpha = roughness^2: roughness 1e-3, the smallest the project models; keeps
// lam_h = 2 / alpha^2 <= 2e12 finite (lam_s <= 5e15 at the cosine floor) for a roughness of 0.
const float ALPHA_MIN = 1e-6;

// Cycles' smoothstepf (intern/cycles/util/math_float.h): 0 below 0, 1 above 1, 3x^2 - 2x^3 between.
float cycles_smoothstep(float x)
{
  if (x <= 0.0) {
    return 0.0;
  }
  if (x >= 1.0) {
    return 1.0;
  }
  return x * x * (3.0 - 2.0 * x);
}

// Blender's spot cone (Cycles, kernel/light/spot.h spot_light_attenuation): the ray in the light's
// local frame with the object scale divided out, z along the spot axis;
// smoothstep((cos - cos_half_spot) / ((1 - cos_half_spot) spot_blend)). light_params.z holds
// 1 / ((1 - cos_half_spot) spot_blend), or a negative value for spot_blend = 0 (a hard edge).
float spot_attenuation(vec3 direction_world, mat3 light_to_local, vec4 light_params)
{
  vec3 local = safe_normalize(light_to_local * direction_world, vec3(0.0, 0.0, 1.0));
  float cos_axis = -local.z;  // lights point down their local -Z
  float cos_half = light_params.y;
  if (light_params.z < 0.0) {
    return cos_axis > cos_half ? 1.0 : 0.0;
  }
  return cycles_smoothstep((cos_axis - cos_half) * light_params.z);
}

// Largest RSM side whose texel solid angles use the exact formula; larger sizes integrate cos^3
// by 3x3 Gauss-Legendre (see texel_solid_angle).
const int EXACT_SOLID_ANGLE_MAX_SIZE = 8;

// Solid angle of the rectangle [0, x] x [0, y] of the image plane at distance 1 (signed).
float corner_solid_angle(float x, float y)
{
  return atan(x * y * inversesqrt(1.0 + x * x + y * y));
}

// Solid angle of the texel centred at p on the image plane at distance 1, half size h:
// the integral of cos^3 over the texel. Small RSMs (size <= EXACT_SOLID_ANGLE_MAX_SIZE) take the
// closed form (four corner rectangles; its float32 cancellation grows as texels shrink, ~1e-4 at
// size 8); larger ones 3x3 Gauss-Legendre on cos^3 = (1 + x^2 + y^2)^(-3/2), within 2e-6 of the
// closed form at size 8 and 1e-7 from 16 on (the midpoint rule, area x cos^3 at the centre, is off
// by 1% per corner texel at 16 and 3e-3 at 32).
float texel_solid_angle(vec2 p, vec2 h, int size)
{
  if (size <= EXACT_SOLID_ANGLE_MAX_SIZE) {
    vec2 lo = p - h;
    vec2 hi = p + h;
    return corner_solid_angle(hi.x, hi.y) - corner_solid_angle(lo.x, hi.y) -
           corner_solid_angle(hi.x, lo.y) + corner_solid_angle(lo.x, lo.y);
  }
  const float node = 0.7745966692414834;  // sqrt(3/5)
  const float weights[3] = float[3](5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0);
  float sum = 0.0;
  for (int i = 0; i < 3; i++) {
    float x = p.x + h.x * node * float(i - 1);
    for (int j = 0; j < 3; j++) {
      float y = p.y + h.y * node * float(j - 1);
      float r2 = 1.0 + x * x + y * y;
      sum += weights[i] * weights[j] * inversesqrt(r2 * r2 * r2);
    }
  }
  return sum * h.x * h.y;
}

vec4 view_constant(int index)
{
  return texelFetch(view_constants, ivec2(index, 0), 0);
}

// Rows r0, r1, r2 as a mat3 (GLSL matrices are built from columns).
mat3 rows_to_mat3(vec3 r0, vec3 r1, vec3 r2)
{
  return transpose(mat3(r0, r1, r2));
}

// Base colour image: bilinear, repeat extension, texel centres at (i + 0.5) / W (Blender's Linear
// interpolation). Texel loads: Python textures cannot set their sampler's wrap mode.
vec3 base_color_sample(vec2 uv)
{
  ivec2 size = textureSize(base_color_image, 0);
  vec2 x = uv * vec2(size) - 0.5;
  vec2 base = floor(x);
  vec2 f = x - base;
  ivec2 i0 = ivec2(base);
  vec3 c[4];
  for (int k = 0; k < 4; k++) {
    ivec2 p = i0 + ivec2(k & 1, k >> 1);
    p = ((p % size) + size) % size;
    c[k] = texelFetch(base_color_image, p, 0).rgb;
  }
  return mix(mix(c[0], c[1], f.x), mix(c[2], c[3], f.x), f.y);
}

void main()
{
  mat3 view_to_world = rows_to_mat3(view_constant(0).xyz, view_constant(1).xyz, view_constant(2).xyz);
  mat3 light_to_local = rows_to_mat3(view_constant(3).xyz, view_constant(4).xyz, view_constant(5).xyz);
  vec3 light_position = view_constant(6).xyz;
  vec3 light_axis = view_constant(7).xyz;
  vec4 light_params = view_constant(8);
  vec3 light_color = view_constant(9).rgb;
  int light_type = int(light_params.x + 0.5);
  float size = view_params.w;
  vec2 half_extent = view_params.yz;
  vec2 ndc = gl_FragCoord.xy / size * 2.0 - 1.0;
  float texel_measure;  // solid angle (perspective) or area on the view plane (orthographic)
  vec3 ray;             // from the light through the texel centre, world space
  if (view_params.x > 0.5) {
    vec2 p = ndc * half_extent;
    texel_measure = texel_solid_angle(p, half_extent / size, int(size + 0.5));
    ray = view_to_world * safe_normalize(vec3(p, -1.0), vec3(0.0, 0.0, -1.0));
  }
  else {
    texel_measure = 4.0 * half_extent.x * half_extent.y / (size * size);
    ray = light_axis;
  }

  // Radiant intensity towards the texel per unit light colour (formulas.md sec. 4): point and spot
  // P / 4 pi (spot: times the cone), area (P / pi) cos theta, sun S (irradiance, W/m^2).
  float intensity = light_params.w;
  if (light_type == LIGHT_SPOT) {
    intensity *= spot_attenuation(ray, light_to_local, light_params);
  }
  else if (light_type == LIGHT_AREA) {
    intensity *= max(dot(ray, light_axis), 0.0);
  }
  float flux_white = intensity * texel_measure;

  // Incoming direction w' (from the surface towards the light).
  vec3 incoming = light_type == LIGHT_SUN ?
                      -light_axis :
                      safe_normalize(light_position - world_position, -ray);
  vec3 geometric = safe_normalize(face_normal_flat, incoming);
  float side = dot(geometric, incoming) < 0.0 ? -1.0 : 1.0;  // two-sided: face the light
  vec3 normal = side * safe_normalize(corner_normal, side * geometric);

  // Principled BSDF base layer (vsgl_addon/reference/rsm.py principled_reflectances).
  // Clamped at 0: a float image may hold negative values, and the RSM's flux must not.
  vec3 base_color = max(material_base_color.w > 0.5 ? base_color_sample(texcoord) :
                                                      material_base_color.rgb, vec3(0.0));
  float roughness = clamp(material_params.x, 0.0, 1.0);
  float metallic = clamp(material_params.y, 0.0, 1.0);
  float ior_ratio = (material_params.w - 1.0) / (material_params.w + 1.0);
  float f0 = clamp(ior_ratio * ior_ratio * 2.0 * max(material_params.z, 0.0), 0.0, 1.0);
  vec3 diffuse_reflectance = base_color * (1.0 - metallic);
  vec3 specular_reflectance = mix(vec3(f0), base_color, metallic);

  vec3 axis;
  float sharpness;
  specular_lobe_warp(incoming, normal, max(roughness * roughness, ALPHA_MIN), axis, sharpness);

  vec3 flux = flux_white * light_color;
  rsm_position = vec4(world_position, sharpness);
  rsm_normal = vec4(normal, roughness);
  rsm_flux_diffuse = vec4(flux * diffuse_reflectance, flux_white);
  rsm_flux_specular = vec4(flux * specular_reflectance, texel_measure);
  rsm_specular_axis = vec4(axis, 1.0);
}
