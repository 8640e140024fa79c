// Bilateral filters guided by a G-buffer's world positions and normals, one range weight for both
// (float64 twin: vsgl_addon/reference/bilateral.py, same names):
// - joint (cross) bilateral upsampling (Kopf, Cohen, Lischinski, Uyttendaele, "Joint bilateral
//   upsampling", SIGGRAPH 2007, eq. 2): the viewport's low-resolution renders resampled at its
//   full-resolution pixels, bilinear weights of the four nearest texels times the range weight;
// - the cross-bilateral filter at equal resolution (004 section 6: it removes the N x N
//   interleaving pattern of the VPL pass, radius 8 there): a Gaussian window times the range weight.
//
// Guides: position.rgb world position, position.a coverage (> 0: geometry); normal.rgb unit normal.
// The range weight of a neighbour q for a pixel p, d = (x_q - x_p) / scale:
//   exp(-(d_n^2 + tangential |d_t|^2) / 2) * max(n_p . n_q, 0)^normal_power,
// d_n = n_p . d the part off p's tangent plane, d_t the part along it; 0 for background (coverage 0).
// The upsampler weighs both parts (tangential 1: neighbours a texel apart on one surface), the
// denoiser only the part off the plane (tangential 0: its window's Gaussian weighs the distance
// along the surface in pixels).

float bilateral_range_weight(vec3 position, vec3 normal, vec4 neighbour_position, vec3 neighbour_normal,
                             float scale, float tangential, float normal_power)
{
  if (neighbour_position.a <= 0.0) {
    return 0.0;
  }
  vec3 d = (neighbour_position.xyz - position) / max(scale, 1e-30);
  float off_plane = dot(normal, d);
  float along = max(dot(d, d) - off_plane * off_plane, 0.0);
  float c = dot(normal, neighbour_normal);
  // pow(0, 0) is undefined in GLSL: a neighbour facing away or edge-on gets no weight.
  float wn = c > 0.0 ? pow(c, normal_power) : 0.0;
  return exp(-0.5 * min(off_plane * off_plane + tangential * along, 1e4)) * wn;
}

// --- Joint bilateral upsampling ----------------------------------------------------------------
// `footprint`: world size of one low-resolution texel at the pixel; positions are compared in units
// of it (sigma_position footprints is one standard deviation). `normal_power` > 0.

// Below this total weight the four nearest texels are taken to show other surfaces.
#define JBU_MIN_WEIGHT 1e-3

float jbu_range_weight(vec3 position, vec3 normal, vec4 low_position, vec4 low_normal, float footprint,
                       float sigma_position, float normal_power)
{
  return bilateral_range_weight(position, normal, low_position, low_normal.xyz, footprint * sigma_position, 1.0,
                                normal_power);
}

// The upsampler's weights at one pixel. They depend on the guides alone, so the images of one
// render (all of the low guide's size, or a 1x1 black texel) share them: jbu_weights once per pixel,
// jbu_apply per image (Kopf et al. 2007 eq. 2's sum with the weights kept), and a viewport whose
// guides did not change keeps them (glsl/view/jbu_weights.frag.glsl). `kind` 0: the four nearest
// texels from `base`, raw weights `weights` summing to `weight_sum` > JBU_MIN_WEIGHT; 1: the one
// texel `pick`, the best-matching geometry texel of the 4x4 neighbourhood when the four nearest all
// show other surfaces (a thin feature the low image missed); 2: none of the sixteen is geometry.
// Kinds 1 and 2 are written as four-texel weights too (base = pick, weights (1, 0, 0, 0) or 0, sum
// 1), so jbu_apply has one branch-free path: on llvmpipe a branch between the two, or a fallback
// loop every pixel steps into, costs a SIMD group both sides; the sum gives the picked texel's
// float exactly.
struct JBUWeights {
  ivec2 base;
  ivec2 pick;
  vec4 weights;
  float weight_sum;
  int kind;
};

JBUWeights jbu_weights(sampler2D low_position, sampler2D low_normal, vec2 uv, vec3 position, vec3 normal,
                       float footprint, float sigma_position, float normal_power)
{
  JBUWeights jw;
  ivec2 size = textureSize(low_position, 0);
  vec2 q = uv * vec2(size) - 0.5;
  vec2 base_f = floor(q);
  vec2 f = q - base_f;
  jw.base = ivec2(base_f);
  jw.pick = ivec2(0);
  ivec2 hi = size - 1;
  float weight_sum = 0.0;
  for (int k = 0; k < 4; k++) {
    ivec2 o = ivec2(k & 1, k >> 1);
    ivec2 t = clamp(jw.base + o, ivec2(0), hi);
    float ws = (o.x == 0 ? 1.0 - f.x : f.x) * (o.y == 0 ? 1.0 - f.y : f.y);
    float w = ws * jbu_range_weight(position, normal, texelFetch(low_position, t, 0),
                                    texelFetch(low_normal, t, 0), footprint, sigma_position, normal_power);
    jw.weights[k] = w;
    weight_sum += w;
  }
  jw.weight_sum = weight_sum;
  if (weight_sum > JBU_MIN_WEIGHT) {
    jw.kind = 0;
    return jw;
  }
  jw.kind = 2;
  float best = 0.0;
  // One loop of sixteen, not two nested: with nested loops the resolve took 20 % longer on
  // llvmpipe although almost no pixel gets here (benchmarks/results/resolve_weights.md).
  for (int n = 0; n < 16; n++) {
    {
      ivec2 t = clamp(jw.base + ivec2((n & 3) - 1, (n >> 2) - 1), ivec2(0), hi);
      vec4 p = texelFetch(low_position, t, 0);
      if (p.a <= 0.0) {
        continue;
      }
      // Four times wider in position, plus a tie-break towards the nearest texel.
      vec2 dt = vec2(t) - q;
      float w = jbu_range_weight(position, normal, p, texelFetch(low_normal, t, 0), footprint,
                                 4.0 * sigma_position, normal_power) + 1e-6 / (1.0 + dot(dt, dt));
      if (w > best) {
        best = w;
        jw.pick = t;
        jw.kind = 1;
      }
    }
  }
  jw.base = jw.pick;
  jw.weights = vec4(jw.kind == 1 ? 1.0 : 0.0, 0.0, 0.0, 0.0);
  jw.weight_sum = 1.0;
  return jw;
}

// `low` resampled with the weights of jbu_weights. A 1x1 texture (a pass that did not run) reads
// its one texel.
vec4 jbu_apply(JBUWeights jw, sampler2D low)
{
  ivec2 hi = textureSize(low, 0) - 1;
  vec4 sum = vec4(0.0);
  for (int k = 0; k < 4; k++) {
    ivec2 t = clamp(jw.base + ivec2(k & 1, k >> 1), ivec2(0), hi);
    sum += jw.weights[k] * texelFetch(low, t, 0);
  }
  return sum / jw.weight_sum;
}

// jbu_weights and jbu_apply reading RGBA32F images instead of samplers (the viewport's resolve,
// glsl/view/resolve.frag.glsl): the same texels and arithmetic, so the same floats; on llvmpipe an
// imageLoad costs a fraction of a texelFetch (benchmarks/results/view_passes_profile.md).
JBUWeights jbu_weights(restrict image2D low_position, restrict image2D low_normal, vec2 uv, vec3 position,
                       vec3 normal, float footprint, float sigma_position, float normal_power)
{
  JBUWeights jw;
  ivec2 size = imageSize(low_position);
  vec2 q = uv * vec2(size) - 0.5;
  vec2 base_f = floor(q);
  vec2 f = q - base_f;
  jw.base = ivec2(base_f);
  jw.pick = ivec2(0);
  ivec2 hi = size - 1;
  float weight_sum = 0.0;
  for (int k = 0; k < 4; k++) {
    ivec2 o = ivec2(k & 1, k >> 1);
    ivec2 t = clamp(jw.base + o, ivec2(0), hi);
    float ws = (o.x == 0 ? 1.0 - f.x : f.x) * (o.y == 0 ? 1.0 - f.y : f.y);
    float w = ws * jbu_range_weight(position, normal, imageLoad(low_position, t), imageLoad(low_normal, t),
                                    footprint, sigma_position, normal_power);
    jw.weights[k] = w;
    weight_sum += w;
  }
  jw.weight_sum = weight_sum;
  if (weight_sum > JBU_MIN_WEIGHT) {
    jw.kind = 0;
    return jw;
  }
  jw.kind = 2;
  float best = 0.0;
  // One loop of sixteen, not two nested: with nested loops the resolve took 20 % longer on
  // llvmpipe although almost no pixel gets here (benchmarks/results/resolve_weights.md).
  for (int n = 0; n < 16; n++) {
    {
      ivec2 t = clamp(jw.base + ivec2((n & 3) - 1, (n >> 2) - 1), ivec2(0), hi);
      vec4 p = imageLoad(low_position, t);
      if (p.a <= 0.0) {
        continue;
      }
      vec2 dt = vec2(t) - q;
      float w = jbu_range_weight(position, normal, p, imageLoad(low_normal, t), footprint,
                                 4.0 * sigma_position, normal_power) + 1e-6 / (1.0 + dot(dt, dt));
      if (w > best) {
        best = w;
        jw.pick = t;
        jw.kind = 1;
      }
    }
  }
  jw.base = jw.pick;
  jw.weights = vec4(jw.kind == 1 ? 1.0 : 0.0, 0.0, 0.0, 0.0);
  jw.weight_sum = 1.0;
  return jw;
}

vec4 jbu_apply(JBUWeights jw, restrict image2D low)
{
  ivec2 hi = imageSize(low) - 1;
  vec4 sum = vec4(0.0);
  for (int k = 0; k < 4; k++) {
    ivec2 t = clamp(jw.base + ivec2(k & 1, k >> 1), ivec2(0), hi);
    sum += jw.weights[k] * imageLoad(low, t);
  }
  return sum / jw.weight_sum;
}

// The upsampled value of `low` (of the low guide's size) at texture coordinates `uv` of a pixel
// whose guide is (position, normal): falls back to the best-matching geometry texel of the 4x4
// neighbourhood when the four nearest all show other surfaces, and to zero when none of the sixteen
// is geometry.
vec4 joint_bilateral_upsample(sampler2D low, sampler2D low_position, sampler2D low_normal, vec2 uv,
                              vec3 position, vec3 normal, float footprint, float sigma_position,
                              float normal_power)
{
  return jbu_apply(jbu_weights(low_position, low_normal, uv, position, normal, footprint, sigma_position,
                               normal_power), low);
}

// The full-resolution guide's texel under the fragment's texture coordinates `uv`: world position
// (a = coverage) and unit normal.
void jbu_guide_texel(sampler2D guide_position, sampler2D guide_normal, vec2 uv, out vec4 position, out vec3 normal)
{
  ivec2 size = textureSize(guide_position, 0);
  ivec2 pixel = clamp(ivec2(uv * vec2(size)), ivec2(0), size - 1);
  position = texelFetch(guide_position, pixel, 0);
  normal = texelFetch(guide_normal, pixel, 0).xyz;
}

// World size of one low-resolution texel at `position`: the vertical extent of the view over
// `low_height` texels, at the pixel's distance for a perspective camera. `camera` is (position, 1)
// perspective or (direction towards the camera, 0) orthographic; `projection_11` the projection's
// [1][1] (cot of half the vertical field of view, or 2 / the orthographic height).
float jbu_footprint(vec4 camera, vec3 position, float projection_11, float low_height)
{
  float extent = 2.0 / (max(abs(projection_11), 1e-30) * max(low_height, 1.0));
  return camera.w > 0.5 ? distance(camera.xyz, position) * extent : extent;
}

// --- Cross-bilateral filter at equal resolution ------------------------------------------------
// Weight of neighbour q for pixel p (both covered): exp(-|q - p|^2 / (2 s^2)), s = radius / 2, in
// pixels, times the range weight with tangential 0 and scale sigma_plane |x_p - eye| / sqrt(2) (off
// p's tangent plane by sigma_plane of its depth weighs e^-1). Uncovered pixels give 0; the centre's
// weight is 1, so the sum is never 0.
vec3 cross_bilateral(sampler2D image, sampler2D guide_position, sampler2D guide_normal, ivec2 pixel, int radius,
                     vec3 eye, float sigma_plane, float normal_power)
{
  ivec2 size = textureSize(image, 0);
  vec4 centre = texelFetch(guide_position, pixel, 0);
  if (centre.w <= 0.0) {
    return vec3(0.0);
  }
  vec3 n = texelFetch(guide_normal, pixel, 0).xyz;
  float scale = sigma_plane * max(length(centre.xyz - eye), 1e-30) * 0.7071067811865476;
  float inv_space = 1.0 / (0.5 * float(max(radius, 1)) * 0.5 * float(max(radius, 1)) * 2.0);
  vec3 sum = vec3(0.0);
  float weight_sum = 0.0;
  for (int dy = -radius; dy <= radius; dy++) {
    for (int dx = -radius; dx <= radius; dx++) {
      ivec2 q = pixel + ivec2(dx, dy);
      if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) {
        continue;
      }
      float w = exp(-float(dx * dx + dy * dy) * inv_space)
                * bilateral_range_weight(centre.xyz, n, texelFetch(guide_position, q, 0),
                                         texelFetch(guide_normal, q, 0).xyz, scale, 0.0, normal_power);
      sum += w * texelFetch(image, q, 0).rgb;
      weight_sum += w;
    }
  }
  return sum / weight_sum;
}


// cross_bilateral reading RGBA32F images instead of samplers (the VPL pass's denoiser,
// glsl/vpl_culling/vpl_denoise.comp.glsl, (2 radius + 1)^2 texels of three images per pixel): the
// same texels and arithmetic, so the same floats, at a fraction of a texelFetch's cost on llvmpipe.
vec3 cross_bilateral(restrict image2D image, restrict image2D guide_position, restrict image2D guide_normal,
                     ivec2 pixel, int radius, vec3 eye, float sigma_plane, float normal_power)
{
  ivec2 size = imageSize(image);
  vec4 centre = imageLoad(guide_position, pixel);
  if (centre.w <= 0.0) {
    return vec3(0.0);
  }
  vec3 n = imageLoad(guide_normal, pixel).xyz;
  float scale = sigma_plane * max(length(centre.xyz - eye), 1e-30) * 0.7071067811865476;
  float inv_space = 1.0 / (0.5 * float(max(radius, 1)) * 0.5 * float(max(radius, 1)) * 2.0);
  vec3 sum = vec3(0.0);
  float weight_sum = 0.0;
  for (int dy = -radius; dy <= radius; dy++) {
    for (int dx = -radius; dx <= radius; dx++) {
      ivec2 q = pixel + ivec2(dx, dy);
      if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, size))) {
        continue;
      }
      float w = exp(-float(dx * dx + dy * dy) * inv_space)
                * bilateral_range_weight(centre.xyz, n, imageLoad(guide_position, q),
                                         imageLoad(guide_normal, q).xyz, scale, 0.0, normal_power);
      sum += w * imageLoad(image, q).rgb;
      weight_sum += w;
    }
  }
  return sum / weight_sum;
}
