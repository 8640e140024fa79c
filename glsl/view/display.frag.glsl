// The Rendered viewport's image (vsgl_addon/view_gpu.py): the running sums of the accumulation
// images times `weight` (1 / samples), as the pass `mode` shows them (settings.VIEWPORT_PASSES
// order: 0 combined, 1 direct, 2 indirect, 3 indirect diffuse, 4 indirect specular, 5 indirect
// glossy reflectors: MRP-ASG's part of indirect specular). Linear,
// scene-referred, Blender's units: the viewport's colour management (the scene's view transform,
// look, exposure and gamma) is applied by Blender afterwards, as to F12's render result.
void main()
{
  ivec2 size = textureSize(accum_direct, 0);
  ivec2 pixel = clamp(ivec2(uv * vec2(size)), ivec2(0), size - 1);
  vec3 direct = texelFetch(accum_direct, pixel, 0).rgb;
  vec3 diffuse = texelFetch(accum_indirect_diffuse, pixel, 0).rgb;
  vec3 specular = texelFetch(accum_indirect_specular, pixel, 0).rgb;
  vec3 radiance;
  if (mode == 1) {
    radiance = direct;
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
    radiance = texelFetch(accum_indirect_glossy_reflectors, pixel, 0).rgb;
  }
  else {
    radiance = direct + diffuse + specular;
  }
  radiance = max(radiance * weight, vec3(0.0));
  color = vec4(all(lessThan(radiance, vec3(1e30))) ? radiance : vec3(0.0), 1.0);
}
