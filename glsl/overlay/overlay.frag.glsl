// The viewport overlay: draws the cached VSGL images (overlay_cache.py) over a 3D viewport.
//
// Inputs (all RGBA32F, the overlay's own resolution, row 0 at the bottom, alpha = coverage):
//   indirect_diffuse, indirect_specular, direct_light, glossy_reflectors   linear radiance,
//   Blender's units (glossy_reflectors: MRP-ASG's part of indirect_specular)
// `mode` (settings.OVERLAY_DISPLAYS order): 0 indirect only, 1 indirect added to the viewport,
// 2 indirect diffuse, 3 indirect specular, 4 direct, 5 direct + indirect, 6 glossy reflectors.
// `scale` = intensity x 2^exposure; the view transform is Blender's "Standard" one (scale, then
// the look's gamma); the framebuffer's sRGB encoding (or ours, `encode_srgb`) makes it display-referred.
// Sampled bilinearly by hand (texelFetch) so a coarse image shows smooth, not blocky, whatever the
// texture's sampler state.

vec4 fetch_bilinear(sampler2D image, vec2 coordinate)
{
  ivec2 size = textureSize(image, 0);
  vec2 p = coordinate * vec2(size) - 0.5;
  vec2 f = fract(p);
  ivec2 i0 = ivec2(floor(p));
  ivec2 hi = size - 1;
  ivec2 a = clamp(i0, ivec2(0), hi);
  ivec2 b = clamp(i0 + ivec2(1), ivec2(0), hi);
  vec4 c00 = texelFetch(image, ivec2(a.x, a.y), 0);
  vec4 c10 = texelFetch(image, ivec2(b.x, a.y), 0);
  vec4 c01 = texelFetch(image, ivec2(a.x, b.y), 0);
  vec4 c11 = texelFetch(image, ivec2(b.x, b.y), 0);
  return mix(mix(c00, c10, f.x), mix(c01, c11, f.x), f.y);
}

vec3 linear_to_srgb(vec3 c)
{
  c = max(c, vec3(0.0));
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

void main()
{
  vec4 diffuse = fetch_bilinear(indirect_diffuse, uv);
  vec4 specular = fetch_bilinear(indirect_specular, uv);
  vec4 direct = fetch_bilinear(direct_light, uv);
  float coverage = clamp(diffuse.a, 0.0, 1.0);
  vec3 radiance;
  if (mode == 2) {
    radiance = diffuse.rgb;
  }
  else if (mode == 3) {
    radiance = specular.rgb;
  }
  else if (mode == 4) {
    radiance = direct.rgb;
  }
  else if (mode == 5) {
    radiance = direct.rgb + diffuse.rgb + specular.rgb;
  }
  else if (mode == 6) {
    radiance = fetch_bilinear(glossy_reflectors, uv).rgb;
  }
  else {
    radiance = diffuse.rgb + specular.rgb;
  }
  vec3 display = max(radiance * scale, vec3(0.0));
  if (gamma != 1.0) {
    display = pow(display, vec3(1.0 / gamma));
  }
  if (encode_srgb != 0) {
    display = linear_to_srgb(display);
  }
  if (mode == 1) {
    // Added (blend ONE, ONE): the light where there is geometry, nothing elsewhere.
    color = vec4(display * coverage, 0.0);
  }
  else {
    // Straight alpha over the viewport: the image where there is geometry.
    color = vec4(display, coverage);
  }
}
