// add_out = add_weights.x add_a + add_weights.y add_b (RGB; add_a's alpha), one invocation per
// pixel: the VPL pass's progressive mean over its samples, and the indirect diffuse image with the
// VPL image added (vsgl_addon/passes/vpl_culling.py add_textures), without a read-back.
void main()
{
  ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(pixel, imageSize(add_a)))) {
    return;
  }
  vec4 a = imageLoad(add_a, pixel);
  vec3 b = imageLoad(add_b, pixel).rgb;
  imageStore(add_out, pixel, vec4(add_weights.x * a.rgb + add_weights.y * b, a.a));
}
