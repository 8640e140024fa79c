// @require lib/bilateral.glsl
//
// The VPL image's cross-bilateral filter (004 section 6; lib/bilateral.glsl), one invocation per
// pixel: removes the N x N interleaving pattern and the culling's noise, keeps depth and normal edges.
void main()
{
  ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(pixel, imageSize(vpl_noisy)))) {
    return;
  }
  vec3 value = cross_bilateral(vpl_noisy, gbuffer_position, gbuffer_normal, pixel, denoise_params.x,
                               denoise_eye.xyz, denoise_eye.w, float(denoise_params.y));
  imageStore(vpl_denoised, pixel, vec4(value, 0.0));
}
