// @require lib/image.glsl
// @require lib/light_emission.glsl
// @require lib/light_links.glsl
// @require lib/principled.glsl
// @require lib/sg.glsl
//
// Reflective shadow map (RSM) pass, fragment stage: one virtual point light (VPL) per texel
// (formulas.md sec. 4; 000 sec. 4). Python side and the meaning of every input:
// vsgl_addon/passes/rsm.py; numpy twin of the texel quantities: vsgl_addon/reference/rsm.py.
//
// Outputs: one RSMTexel per texel, written to rsm_<attachment> by the generated rsm_store (RGBA32F;
// attachments and channels declared in vsgl_addon/layouts.py RSM, the layout VSGL generation reads):
//   position, specular_sharpness   world position, sharpness of the warped specular lobe
//   normal, roughness              shading normal facing the light, Principled roughness
//   flux_diffuse, flux_white       Phi Rd; Phi_1 = texel flux for a white light (W), Phi = Phi_1 colour
//   flux_specular, texel_measure   Phi Rs; texel solid angle (sr), or its area (m^2) for a sun
//   specular_axis, coverage        axis of the warped specular lobe; 1
// Texels that see no geometry keep the clear value 0 (coverage 0, flux 0).
//
// Per-view constants come in the one-column RGBA32F table `view_constants` (push constants stay
// within the 128 bytes every backend guarantees), fetched as one RSMViewConstants by the generated
// view_constants_load (rows declared in vsgl_addon/layouts.py RSM_VIEW): the rows of mat3
// view -> world and of mat3 world -> light local (inverse of the light's 3x3 world matrix, scale
// included), light_position, light_axis (unit, where the light points), light_params (the light
// parameters of lib/light_emission.glsl), light_color, light_factors (Blender's diffuse and
// specular factors of the light), light_index and light_links_rows (lib/light_links.glsl), and
// sharp_alpha (0, or the caustic roughness alpha_c whose texels' specular flux the VPLs carry).
//
// rsm_mode.x selects what one draw covers, for shadow linking: 0 every object, 1 the objects that
// block the light (they write depth: the shadow map holds only them), 2 the others (depth tested,
// not written: a reflector that casts no shadow). rsm_mode.y keeps the flux of the reflectors seen
// by every ray (0), by diffuse rays only (1) or by glossy rays only (2): the VSGLs for the
// receivers' diffuse and glossy lobes when some object is hidden from one ray type.

// rsm_mode.y == 2 (the glossy receivers' VSGLs) with rectangle proxies (proxy_table, one ProxyRecord
// per column, vsgl_addon/layouts.py PROXY_TABLE): a texel on a proxy keeps no specular flux, which
// MRP-ASG carries to glossy receivers instead (light-paths.md); its diffuse flux stays.

// True when the texel at `position` (geometric normal `geometric`, Principled `roughness`) lies on
// a proxy: in its plane and rectangle within 1e-4 of its size, parallel to it, of its roughness.
bool rsm_on_proxy(vec3 position, vec3 geometric, float roughness)
{
  int count = textureSize(proxy_table, 0).x;
  for (int i = 0; i < count; i++) {
    ProxyRecord p = proxy_table_load(i);
    if (!(p.half_u >= 0.0)) {
      continue;
    }
    float tolerance = 1e-4 * (1.0 + max(p.half_u, p.half_v));
    vec3 d = position - p.center;
    if (abs(dot(d, p.normal)) <= tolerance && abs(dot(d, p.axis_u)) <= p.half_u + tolerance &&
        abs(dot(d, p.axis_v)) <= p.half_v + tolerance && abs(dot(geometric, p.normal)) > 0.999 &&
        abs(roughness - p.roughness) < 1e-4) {
      return true;
    }
  }
  return false;
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

// Rows r0, r1, r2 as a mat3 (GLSL matrices are built from columns).
mat3 rows_to_mat3(vec3 r0, vec3 r1, vec3 r2)
{
  return transpose(mat3(r0, r1, r2));
}

void main()
{
  RSMViewConstants view = view_constants_load(0);
  vec4 links = light_links_fetch(light_links, int(view.light_links_rows + 0.5), int(view.light_index + 0.5),
                                 object_index_flat);
#if RSM_SPLIT_DRAWS
  // Only the two draws of a light with non-blocking objects discard: a shader that may discard
  // loses the early depth test, and with it the one-draw case ran 1.8× slower on llvmpipe
  // (benchmarks/light_build_profile.py), so that case compiles without it (passes/rsm.py).
  bool blocks = links.y > 0.5;
  if ((rsm_mode.x == 1 && !blocks) || (rsm_mode.x == 2 && blocks)) {
    discard;
  }
#endif
  // The texel reflects the light only if its object receives it (light linking) and, for one
  // receiver lobe's VSGLs, is seen by that lobe's rays.
  float lit = links.x * (rsm_mode.y == 1 ? links.z : 1.0) * (rsm_mode.y == 2 ? links.w : 1.0);
  mat3 view_to_world = rows_to_mat3(view.view_to_world_row0, view.view_to_world_row1, view.view_to_world_row2);
  mat3 light_to_local = rows_to_mat3(view.world_to_local_row0, view.world_to_local_row1,
                                     view.world_to_local_row2);
  vec3 light_position = view.light_position;
  vec3 light_axis = view.light_axis;
  vec4 light_params = view.light_params;
  vec3 light_color = view.light_color;
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

  // Phi_1 = I(ray) d_omega: the light's radiant intensity towards the texel per unit light colour
  // (formulas.md sec. 4, lib/light_emission.glsl) times the texel's solid angle; a sun's S (W/m^2) times
  // the texel's area.
  float flux_white = light_intensity(light_params, ray, light_axis, light_to_local) * texel_measure;

  // Incoming direction w' (from the surface towards the light).
  vec3 incoming = light_type == LIGHT_SUN ?
                      -light_axis :
                      safe_normalize(light_position - world_position, -ray);
  vec3 geometric = safe_normalize(face_normal_flat, incoming);
  float side = dot(geometric, incoming) < 0.0 ? -1.0 : 1.0;  // two-sided: face the light
  vec3 normal = side * safe_normalize(corner_normal, side * geometric);

  // Rd and Rs of the Principled BSDF base layer (lib/principled.glsl, calibrated against Cycles;
  // the direct light's model) for the incidence w': the texel is lit from the light, and
  // Phi Rd, Phi Rs are the fluxes its diffuse and specular lobes reflect (formulas.md sec. 4;
  // reference/rsm.py principled_reflectances): Rd = base (1 - metallic)(1 - E_spec(mu')), Rs the
  // specular lobes' directional albedo (real dielectric Fresnel, multiple scattering), so the
  // normalized lobes of 000 Eqs. 6-7 (Rd G/A(lam_d), Rs G/A(lam_s)) re-emit exactly these.
  // Clamped at 0: a float image may hold negative values, and the RSM's flux must not.
  vec3 base_color = max(material_base_color.w > 0.5 ?
                            image_sample_linear_repeat(base_color_image, texcoord) :
                            material_base_color.rgb,
                        vec3(0.0));
  float roughness = clamp(material_params.x, 0.0, 1.0);
  PrincipledTerms terms = principled_terms(base_color, material_params.y, material_params.z,
                                           material_params.w, roughness, dot(normal, incoming));

  // The specular lobe: 000 Eq. 7's spherical warp of the GGX NDF for the incidence w'.
  vec3 axis;
  float sharpness;
  specular_lobe_warp(incoming, normal, terms.alpha, axis, sharpness);

  flux_white *= lit;
  vec3 flux = flux_white * light_color;
  RSMTexel r;
  r.position = world_position;
  r.specular_sharpness = sharpness;
  r.normal = normal;
  r.roughness = roughness;
  // Blender's light factors scale the light's diffuse and glossy reflection, here at the reflector
  // as Cycles does at the first surface the light reaches.
  r.flux_diffuse = flux * terms.diffuse * view.light_factors.x;
  r.flux_white = flux_white;
  r.flux_specular = flux * terms.specular_albedo * view.light_factors.y;
  if (rsm_mode.y == 2 && rsm_on_proxy(world_position, geometric, roughness)) {
    r.flux_specular = vec3(0.0);
  }
  // view.sharp_alpha > 0 (the diffuse receivers' VSGLs with the glossy VPL pass on): a sharp
  // reflector's texel (GGX alpha below it, the VPLs' own test) keeps no specular flux, which its
  // VPL carries to diffuse receivers instead (light-paths.md); its diffuse flux stays.
  if (terms.alpha < view.sharp_alpha) {
    r.flux_specular = vec3(0.0);
  }
  r.texel_measure = texel_measure;
  r.specular_axis = axis;
  r.coverage = 1.0;
  rsm_store(r);
}
