// A viewport's image (vsgl_addon/view_gpu.py): the running sums of the accumulation images times
// `weight` (1 / samples), as the pass `mode` shows them (settings.VIEWPORT_PASSES order: 0 combined,
// 1 direct, 2 indirect, 3 indirect diffuse, 4 indirect specular, 5 indirect caustics, the glossy
// VPLs' part of indirect diffuse; 6 indirect glossy reflectors, MRP-ASG's part of indirect specular).
// `composition` 0 (Rendered shading): opaque, linear, scene-referred, Blender's units; the viewport's
// colour management (view transform, look, exposure, gamma) is applied by Blender afterwards, as to
// F12's render result.
// `composition` 1 and 2 (the overlay over another engine's viewport, which applies no colour
// management to it): Blender's Standard view transform by hand, radiance × `scale` (intensity ×
// 2^exposure) then the look's `gamma`, and the sRGB encoding if the framebuffer does not do it
// (`encode_srgb`); 1 lays it over the viewport by coverage (straight alpha), 2 adds it (ONE, ONE)
// where there is geometry.
vec3 linear_to_srgb(vec3 c)
{
  c = max(c, vec3(0.0));
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

void main()
{
  ivec2 size = textureSize(accum_direct, 0);
  ivec2 pixel = clamp(ivec2(uv * vec2(size)), ivec2(0), size - 1);
  vec4 direct = texelFetch(accum_direct, pixel, 0);
  vec3 diffuse = texelFetch(accum_indirect_diffuse, pixel, 0).rgb;
  vec3 specular = texelFetch(accum_indirect_specular, pixel, 0).rgb;
  vec3 radiance;
  if (mode == 1) {
    radiance = direct.rgb;
  }
  else if (mode == 2) {
    radiance = diffuse + specular;
  }
  else if (mode == 3) {
    radiance = diffuse;
  }
  else if (mode == 4) {
    radiance = specular;
  }
  else if (mode == 5) {
    radiance = texelFetch(accum_indirect_caustics, pixel, 0).rgb;
  }
  else if (mode == 6) {
    radiance = texelFetch(accum_indirect_glossy_reflectors, pixel, 0).rgb;
  }
  else {
    radiance = direct.rgb + diffuse + specular;
  }
  radiance = max(radiance * weight, vec3(0.0));
  // No NaN or Inf may reach a pixel.
  radiance = all(lessThan(radiance, vec3(1e30))) ? radiance : vec3(0.0);
  if (composition == 0) {
    color = vec4(radiance, 1.0);
    return;
  }
  float coverage = clamp(direct.a * weight, 0.0, 1.0);
  vec3 shown = radiance * scale;
  if (gamma != 1.0) {
    shown = pow(shown, vec3(1.0 / gamma));
  }
  if (encode_srgb != 0) {
    shown = linear_to_srgb(shown);
  }
  color = composition == 2 ? vec4(shown * coverage, 0.0) : vec4(shown, coverage);
}
