// Image textures as Blender's Image Texture node samples them with Linear interpolation and Repeat
// extension (Cycles kernel/svm/image.h; EEVEE the same): bilinear between the four nearest texel
// centres, texel centres at (i + 0.5) / W, wrapping around at the edges. Read by the passes that
// rasterise the scene's materials (glsl/rsm/rsm.frag.glsl, glsl/gbuffer/gbuffer.frag.glsl), so the
// RSM's VPLs and the camera's G-buffer see the same base colour. Float64 twin:
// vsgl_addon/reference/image.py (same name).
//
// By texel loads and weights computed here, not the sampler's filter: textures made from Python
// cannot set their sampler's wrap mode (Blender's gpu module), and hardware filter weights have
// 8 bits.

// The RGB of `image` at texture coordinates `uv` (row 0 of the image at v = 0).
vec3 image_sample_linear_repeat(sampler2D image, vec2 uv)
{
  ivec2 size = textureSize(image, 0);
  vec2 x = uv * vec2(size) - 0.5;
  vec2 base = floor(x);
  vec2 f = x - base;
  // The lower texel wrapped into [0, size) in float first: GLSL leaves % undefined for negative
  // operands (llvmpipe's result for them is not the C remainder), so % below only sees p >= 0.
  vec2 wrapped = base - vec2(size) * floor(base / vec2(size));
  ivec2 i0 = clamp(ivec2(wrapped), ivec2(0), size - 1);
  vec3 c[4];
  for (int k = 0; k < 4; k++) {
    ivec2 p = (i0 + ivec2(k & 1, k >> 1)) % size;
    c[k] = texelFetch(image, p, 0).rgb;
  }
  return mix(mix(c[0], c[1], f.x), mix(c[2], c[3], f.x), f.y);
}
