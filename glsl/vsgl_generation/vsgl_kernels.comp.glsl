// @require lib/mip_atlas.glsl
// @require lib/vsgl_parameters.glsl
//
// One invocation per VSGL (000 section 3-4, Algorithm 1, app. B.3 and D; 003 for the 2-VSGL mode):
// Fibonacci lattice point (+ Cranley-Patterson rotation), hierarchical warp through the PDF plane
// of the mip chains (glsl/lib/mip_atlas.glsl), kernel level, cluster totals, VSGL parameters. Twin of
// vsgl_addon/reference/vsgl.py `generate_vsgls`, float32 with exact (float32) trilinear weights.
//
// kernel_mode: 0 = modified kernel size (000 Eq. 3 by bisection, Algorithm 1; Eq. 5),
//              1 = original kernel size (000 Eqs. 1 and 4),
//              2 = 003's two VSGLs from the whole-RSM totals (the atlas's top level).
//
// positional_distribution: 0 = per lobe (each lobe at its own power centroid), 1 = shared (000
// app. B.2 as written); see vsgl_addon/reference/vsgl.py POSITIONAL_DISTRIBUTIONS.
//
// Output table `vsgl_table` (RGBA32F, vsgl_count x VSGL_ROW_COUNT), column i = VSGL i: one
// VSGLRecord per column, stored by the generated vsgl_table_store (rows and channels declared in
// vsgl_addon/layouts.py VSGL_TABLE); column 0 of row VSGL_ROW_RSM_TOTAL_POWER holds the RSM's total.
// kernel_texel is the level-0 texel the warp chose (row, column): the centre can round onto the
// texel's far edge ((texel + u) / S in float32 with u just below 1). With plane_split (reference
// `split_planes`), columns vsgl_count + PLANE_SPLIT_EXTRA i + e hold kernel i's extra planes (zero
// records where unused), after the vsgl_count kernels' columns.

const int BISECTION_ITERATIONS = 12;   // 000 section 3.2
const float BELOW_ONE = 0.99999994;     // largest float32 below 1 (1 - 2^-24)
const float SMALLEST_NORMAL = 1.17549435e-38;
const uint GOLDEN_RATIO_CONJUGATE_HIGH = 0x9E3779B9u;  // (sqrt(5) - 1) / 2 in 64-bit fixed point
const uint GOLDEN_RATIO_CONJUGATE_LOW = 0x7F4A7C15u;

const int MOMENT_PLANES = 5;  // 20 moment channels; plane 5 is the PDF
const int PDF_PLANE = 5;

// The 20 moment channels (planes 0-4) of one atlas level at a bilinear tap.
void moments_bilinear(int level, BilinearTap tap, out vec4 m[MOMENT_PLANES])
{
  for (int plane = 0; plane < MOMENT_PLANES; plane++) {
    m[plane] = mip_atlas_bilinear_tap(rsm_size, level, plane, tap);
  }
}

// x_i = ((i + 0.5) / N, frac(i / phi)) + rotation (mod 1) (reference `fibonacci_lattice`), in 32-bit
// fixed point: (2i + 1) 2^31 / N and i (1/phi) are formed exactly (the latter with the 64-bit
// constant), the shift wraps modulo 1 for free, and the 24 leading bits become the float32 point.
vec2 fibonacci_lattice_point(int index)
{
  uint n = uint(vsgl_count);
  uint a = 2u * uint(index) + 1u;
  uint quotient = 0x80000000u / n;
  uint remainder = 0x80000000u % n;
  uint u_fixed = a * quotient + (a * remainder) / n;  // floor(a 2^31 / N), exact for N <= 2^15
  uint carry, low;
  umulExtended(uint(index), GOLDEN_RATIO_CONJUGATE_LOW, carry, low);
  uint v_fixed = uint(index) * GOLDEN_RATIO_CONJUGATE_HIGH + carry;
  u_fixed += uint(lattice_rotation_fixed.x);
  v_fixed += uint(lattice_rotation_fixed.y);
  return vec2(float(u_fixed >> 8u), float(v_fixed >> 8u)) * (1.0 / 16777216.0);
}

// The PDF weight (plane 5, not normalized) of a texel.
float pdf_weight(int level, ivec2 texel)
{
  return mip_atlas_fetch(rsm_size, level, PDF_PLANE, texel).x;
}

// Hierarchical sample warping (reference `warp_hierarchical`): returns uv, sets the level-0 texel
// (column, row). Top-down from the 1x1 level: column by the masses of the 2x2 children's columns,
// then row inside the column; u and v are rescaled to [0, 1) at each step.
vec2 warp_hierarchical(vec2 sample_point, int top, out ivec2 texel)
{
  float u = sample_point.x;
  float v = sample_point.y;
  texel = ivec2(0);
  for (int level = top - 1; level >= 0; level--) {
    ivec2 c0 = 2 * texel;
    float m00 = pdf_weight(level, c0);
    float m01 = pdf_weight(level, c0 + ivec2(1, 0));
    float m10 = pdf_weight(level, c0 + ivec2(0, 1));
    float m11 = pdf_weight(level, c0 + ivec2(1, 1));
    precise float left = m00 + m10;
    precise float total = (left + m01) + m11;
    float p_left = total > 0.0 ? left / total : 0.5;
    bool go_left = u < p_left;
    u = go_left ? u / p_left : (u - p_left) / (1.0 - p_left);
    u = clamp(u, 0.0, BELOW_ONE);
    precise float right = m01 + m11;
    float upper = go_left ? m00 : m01;
    float column = go_left ? left : right;
    float p_upper = column > 0.0 ? upper / column : 0.5;
    bool go_upper = v < p_upper;
    v = go_upper ? v / p_upper : (v - p_upper) / (1.0 - p_upper);
    v = clamp(v, 0.0, BELOW_ONE);
    texel = ivec2(go_left ? c0.x : c0.x + 1, go_upper ? c0.y : c0.y + 1);
  }
  vec2 uv = (vec2(texel) + vec2(u, v)) / float(rsm_size);
  return min(uv, vec2(BELOW_ONE));
}

// One plane filtered at (uv, fractional level): the reference's `mipmap.trilinear`.
vec4 plane_trilinear(int plane, vec2 uv, float level, int top)
{
  int lower, upper;
  float fraction;
  mip_level_split(level, top, lower, upper, fraction);
  return (1.0 - fraction) * mip_atlas_bilinear(rsm_size, lower, plane, uv)
         + fraction * mip_atlas_bilinear(rsm_size, upper, plane, uv);
}

// The kernel holds more than STRADDLE_SHARE of its power on texels beside a depth discontinuity
// (plane 5's second channel) and its surfaces face different ways: reference `vsgl.straddles`.
bool kernel_straddles(vec2 uv, float level, int top)
{
  vec4 p0 = plane_trilinear(0, uv, level, top);
  vec4 p1 = plane_trilinear(1, uv, level, top);
  vec4 p2 = plane_trilinear(2, uv, level, top);
  float weight = luminance(p0.xyz + vec3(p1.zw, p2.x));
  float jump = plane_trilinear(PDF_PLANE, uv, level, top).y;
  // Only surfaces facing different ways (reference NORMAL_AGREEMENT): the diffuse lobes' Toksvig
  // mean direction against one surface's, lambda_d / (lambda_d + 1).
  float diffuse = luminance(p0.xyz);
  float one_surface = DIFFUSE_SHARPNESS / (DIFFUSE_SHARPNESS + 1.0);
  bool disagree = NORMAL_AGREEMENT <= 0.0 || !(diffuse > 0.0)
                  || length(vec3(p0.w, p1.xy)) < NORMAL_AGREEMENT * one_surface * diffuse;
  return weight > 0.0 && jump > STRADDLE_SHARE * weight && disagree;
}

// --- Plane-split clusters (reference vsgl.plane_class_moments, split_planes) ---------------------
const int NORMAL_CLASSES = 6;

// 2 x the dominant axis + 1 where that component is negative; ties take the first axis (np.argmax).
int normal_class(vec3 direction)
{
  vec3 a = abs(direction);
  int axis = 0;
  float largest = a.x;
  if (a.y > largest) {
    axis = 1;
    largest = a.y;
  }
  if (a.z > largest) {
    axis = 2;
  }
  float component = axis == 0 ? direction.x : (axis == 1 ? direction.y : direction.z);
  return 2 * axis + (component < 0.0 ? 1 : 0);
}

// The cluster's diffuse lobes disagree: Toksvig mean direction shorter than NORMAL_AGREEMENT times
// one surface's (reference `normals_disagree`).
bool normals_disagree(vec4 totals[MOMENT_PLANES])
{
  float diffuse = luminance(totals[0].xyz);
  float one_surface = DIFFUSE_SHARPNESS / (DIFFUSE_SHARPNESS + 1.0);
  return diffuse > 0.0 && length(vec3(totals[0].w, totals[1].xy)) < NORMAL_AGREEMENT * one_surface * diffuse;
}

// The trilinear filter of the diffuse moment channels (planes 0, 1.xy and 3) at (uv, level), split
// by the normal class of the texels PLANE_SPLIT_DEPTH levels under each tap (unscaled).
void plane_class_moments(vec2 uv, float level, int top, out vec4 class0[NORMAL_CLASSES],
                         out vec2 class1[NORMAL_CLASSES], out vec4 class3[NORMAL_CLASSES])
{
  for (int c = 0; c < NORMAL_CLASSES; c++) {
    class0[c] = vec4(0.0);
    class1[c] = vec2(0.0);
    class3[c] = vec4(0.0);
  }
  int lower, upper;
  float fraction;
  mip_level_split(level, top, lower, upper, fraction);
  for (int k = 0; k < 2; k++) {
    int tap_level = k == 0 ? lower : upper;
    float share = k == 0 ? 1.0 - fraction : fraction;
    if (!(share > 0.0)) {
      continue;
    }
    BilinearTap tap = bilinear_tap(rsm_size >> tap_level, uv);
    int child = max(tap_level - PLANE_SPLIT_DEPTH, 0);
    int block = 1 << (tap_level - child);
    float per_child = 1.0 / float(block * block);
    for (int t = 0; t < 4; t++) {
      bool right = (t & 1) != 0;
      bool below = (t & 2) != 0;
      ivec2 texel = ivec2(right ? tap.b.x : tap.a.x, below ? tap.b.y : tap.a.y);
      float weight = share * ((below ? tap.f.y : 1.0 - tap.f.y) * (right ? tap.f.x : 1.0 - tap.f.x)) * per_child;
      for (int y = 0; y < block; y++) {
        for (int x = 0; x < block; x++) {
          ivec2 at = texel * block + ivec2(x, y);
          vec4 m0 = mip_atlas_fetch(rsm_size, child, 0, at);
          vec4 m1 = mip_atlas_fetch(rsm_size, child, 1, at);
          vec4 m3 = mip_atlas_fetch(rsm_size, child, 3, at);
          int c = normal_class(vec3(m0.w, m1.xy));
          class0[c] += weight * m0;
          class1[c] += weight * m1.xy;
          class3[c] += weight * m3;
        }
      }
    }
  }
}

float interpolate_levels(float per_level[MIP_ATLAS_MAX_LEVELS], float level, int top)
{
  int lower, upper;
  float fraction;
  mip_level_split(level, top, lower, upper, fraction);
  return (1.0 - fraction) * per_level[lower] + fraction * per_level[upper];
}

void write_vsgl(int column, vec4 totals[MOMENT_PLANES], vec3 fallback_mean, float fallback_variance,
                vec2 center, float level, ivec2 texel)
{
  vec3 diffuse_power = totals[0].xyz;
  vec3 diffuse_direction = vec3(totals[0].w, totals[1].xy);
  vec3 specular_power = vec3(totals[1].zw, totals[2].x);
  vec3 specular_direction = totals[2].yzw;
  vec3 diffuse_amplitude, diffuse_axis, specular_amplitude, specular_axis;
  float diffuse_sharpness, specular_sharpness;
  vsgl_lobe(diffuse_power, diffuse_direction, diffuse_amplitude, diffuse_axis, diffuse_sharpness);
  // Texels' diffuse lobes normalized over their hemisphere (reference vsgl_parameters).
  diffuse_amplitude *= DIFFUSE_HEMISPHERE_SCALE;
  vsgl_lobe(specular_power, specular_direction, specular_amplitude, specular_axis, specular_sharpness);
  vec3 power = diffuse_power + specular_power;
  vec3 mean;
  float variance;
  vec4 combined = totals[3] + totals[4];  // reference `combined_position_moments`
  vsgl_position(luminance(power), combined.xyz, combined.w, fallback_mean, fallback_variance,
                mean, variance);
  vec3 diffuse_mean = mean;
  vec3 specular_mean = mean;
  float diffuse_variance = variance;
  float specular_variance = variance;
  if (positional_distribution == 0) {
    vsgl_position(luminance(diffuse_power), totals[3].xyz, totals[3].w, mean, variance,
                  diffuse_mean, diffuse_variance);
    vsgl_position(luminance(specular_power), totals[4].xyz, totals[4].w, mean, variance,
                  specular_mean, specular_variance);
  }
  VSGLRecord r;
  r.mean = mean;
  r.variance = variance;
  r.diffuse_mean = diffuse_mean;
  r.diffuse_variance = diffuse_variance;
  r.specular_mean = specular_mean;
  r.specular_variance = specular_variance;
  r.diffuse_amplitude = diffuse_amplitude;
  r.diffuse_sharpness = diffuse_sharpness;
  r.diffuse_axis = diffuse_axis;
  r.kernel_level = level;
  r.specular_amplitude = specular_amplitude;
  r.specular_sharpness = specular_sharpness;
  r.specular_axis = specular_axis;
  r.kernel_center = center;
  r.power = power;
  r.kernel_texel = vec2(float(texel.y), float(texel.x));
  vsgl_table_store(column, r);
}

// Mean and variance of the whole RSM (reference `_rsm_fallback`) from top-level position moments.
void rsm_fallback(vec4 top_position, vec3 top_power, out vec3 mean, out float variance)
{
  vsgl_position(luminance(top_power), top_position.xyz, top_position.w, vec3(0.0),
                VARIANCE_FLOOR_ABSOLUTE, mean, variance);
}

void main()
{
  int index = int(gl_GlobalInvocationID.x);
  int top = findMSB(rsm_size);
  float texel_count = float(rsm_size) * float(rsm_size);
  vec4 top_moments[MIP_PLANES];
  for (int plane = 0; plane < MIP_PLANES; plane++) {
    top_moments[plane] = mip_atlas_fetch(rsm_size, top, plane, ivec2(0));
  }
  vec3 top_power = top_moments[0].xyz + vec3(top_moments[1].zw, top_moments[2].x);
  if (index == 0) {
    VSGLRecord whole_rsm;
    whole_rsm.rsm_total_power = texel_count * top_power;
    imageStore(vsgl_table, ivec2(0, VSGL_ROW_RSM_TOTAL_POWER), vsgl_table_pack_rsm_total_power(whole_rsm));
  }

  if (kernel_mode == 2) {
    // 003: column 0 the diffuse lobe, column 1 the specular lobe, from whole-RSM totals (sum = M mean).
    if (index > 1) {
      return;
    }
    vec3 fallback_mean;
    float fallback_variance;
    rsm_fallback(top_moments[3] + top_moments[4], top_power, fallback_mean, fallback_variance);
    vec4 totals[MOMENT_PLANES];
    if (index == 0) {
      totals[0] = texel_count * top_moments[0];
      totals[1] = texel_count * vec4(top_moments[1].xy, 0.0, 0.0);
      totals[2] = vec4(0.0);
      totals[3] = texel_count * top_moments[3];
      totals[4] = vec4(0.0);
    }
    else {
      totals[0] = vec4(0.0);
      totals[1] = texel_count * vec4(0.0, 0.0, top_moments[1].zw);
      totals[2] = texel_count * top_moments[2];
      totals[3] = vec4(0.0);
      totals[4] = texel_count * top_moments[4];
    }
    write_vsgl(index, totals, fallback_mean, fallback_variance, vec2(0.5), float(top),
               ivec2(rsm_size / 2));
    return;
  }
  if (index >= vsgl_count) {
    return;
  }
  vec3 fallback_mean;
  float fallback_variance;
  rsm_fallback(top_moments[3] + top_moments[4], top_power, fallback_mean, fallback_variance);

  // Density p = M x texel probability = PDF weight / top-level mean; uniform for an all-zero PDF.
  float pdf_top = top_moments[PDF_PLANE].x;
  bool uniform_pdf = !(pdf_top > 0.0);
  float pdf_scale = uniform_pdf ? 0.0 : 1.0 / pdf_top;

  ivec2 texel;
  vec2 center = warp_hierarchical(fibonacci_lattice_point(index), top, texel);

  float level;
  float denominator;
  float n = float(vsgl_count);
  if (kernel_mode == 0) {
    // 000 Eq. 3 by bisection (Algorithm 1): 4^l / M p_bar(x, l) = K / N, l in [0, top].
    float per_level[MIP_ATLAS_MAX_LEVELS];
    for (int l = 0; l <= top; l++) {
      per_level[l] = uniform_pdf ? 1.0 : mip_atlas_bilinear(rsm_size, l, PDF_PLANE, center).x * pdf_scale;
    }
    float target = kernel_k / n;
    float level_min = 0.0;
    float level_max = float(top);
    for (int iteration = 0; iteration < BISECTION_ITERATIONS; iteration++) {
      float middle = 0.5 * (level_min + level_max);
      float mass = exp2(2.0 * middle) / texel_count * interpolate_levels(per_level, middle, top);
      if (mass < target) {
        level_min = middle;
      }
      else {
        level_max = middle;
      }
    }
    level = 0.5 * (level_min + level_max);
    if (split_at_jumps != 0) {
      // Reference `vsgl.kernel_level_unstraddled`: down a level at a time off a depth
      // discontinuity, then onto the centre of its own texel if level 0 still straddles.
      for (int step = 0; step <= top && step < MAX_DESCENT; step++) {
        if (!(level > 0.0) || !kernel_straddles(center, level, top)) {
          break;
        }
        level = max(level - 1.0, 0.0);
      }
      if (SNAP_TO_TEXEL != 0 && !(level > 0.0) && kernel_straddles(center, level, top)) {
        center = (vec2(texel) + 0.5) / float(rsm_size);
        for (int l = 0; l <= top; l++) {
          per_level[l] = uniform_pdf ? 1.0 : mip_atlas_bilinear(rsm_size, l, PDF_PLANE, center).x * pdf_scale;
        }
      }
    }
    // Eq. 5: the same kernel filters numerator and denominator.
    denominator = n * interpolate_levels(per_level, level, top);
  }
  else {
    // 000 Eq. 1: 4^l / M = min(K / (N p(x)), 1), p unfiltered at the centre's texel; Eq. 4.
    float p = uniform_pdf ? 1.0 : pdf_weight(0, texel) * pdf_scale;
    p = max(p, SMALLEST_NORMAL);
    float area = min(kernel_k / (n * p), 1.0);
    level = clamp(0.5 * log2(texel_count * area), 0.0, float(top));
    denominator = max(n * p, 1.0);
  }
  denominator = max(denominator, SMALLEST_NORMAL);

  // Cluster totals M F_bar(x, l) / denominator, F_bar trilinear in the moment planes.
  int lower, upper;
  float fraction;
  mip_level_split(level, top, lower, upper, fraction);
  vec4 a[MOMENT_PLANES];
  vec4 b[MOMENT_PLANES];
  moments_bilinear(lower, bilinear_tap(rsm_size >> lower, center), a);
  moments_bilinear(upper, bilinear_tap(rsm_size >> upper, center), b);
  vec4 totals[MOMENT_PLANES];
  for (int plane = 0; plane < MOMENT_PLANES; plane++) {
    vec4 filtered = (1.0 - fraction) * a[plane] + fraction * b[plane];
    totals[plane] = texel_count * filtered / denominator;
  }
  if (plane_split == 0 || kernel_mode != 0) {
    write_vsgl(index, totals, fallback_mean, fallback_variance, center, level, texel);
    return;
  }
  // Plane-split clusters (reference `split_planes`): this kernel's PLANE_SPLIT_EXTRA slots follow
  // the N kernels' columns, written every frame (zero when unused).
  int leaving[PLANE_SPLIT_EXTRA];
  for (int e = 0; e < PLANE_SPLIT_EXTRA; e++) {
    leaving[e] = -1;
  }
  vec4 class0[NORMAL_CLASSES];
  vec2 class1[NORMAL_CLASSES];
  vec4 class3[NORMAL_CLASSES];
  if (normals_disagree(totals)) {
    plane_class_moments(center, level, top, class0, class1, class3);
    float weight[NORMAL_CLASSES];
    int order[NORMAL_CLASSES];
    float sum = 0.0;
    for (int c = 0; c < NORMAL_CLASSES; c++) {
      weight[c] = luminance(class0[c].xyz);
      sum += weight[c];
      order[c] = c;
    }
    // Stable descending insertion sort (np.argsort(-w, kind="stable")).
    for (int i = 1; i < NORMAL_CLASSES; i++) {
      int key = order[i];
      int j = i - 1;
      while (j >= 0 && weight[order[j]] < weight[key]) {
        order[j + 1] = order[j];
        j--;
      }
      order[j + 1] = key;
    }
    float threshold = PLANE_SPLIT_SHARE * sum;
    bool second = weight[order[1]] >= threshold && weight[order[1]] > 0.0;
    if (second) {
      for (int e = 0; e < PLANE_SPLIT_EXTRA; e++) {
        float w = weight[order[e + 1]];
        if (w >= threshold && w > 0.0) {
          leaving[e] = order[e + 1];
        }
      }
      vec4 stay0 = vec4(0.0);
      vec2 stay1 = vec2(0.0);
      vec4 stay3 = vec4(0.0);
      for (int c = 0; c < NORMAL_CLASSES; c++) {
        bool leaves = false;
        for (int e = 0; e < PLANE_SPLIT_EXTRA; e++) {
          leaves = leaves || leaving[e] == c;
        }
        if (!leaves) {
          stay0 += class0[c];
          stay1 += class1[c];
          stay3 += class3[c];
        }
      }
      float scale = texel_count / denominator;
      totals[0] = scale * stay0;
      totals[1] = vec4(scale * stay1, totals[1].zw);
      totals[3] = scale * stay3;
    }
  }
  write_vsgl(index, totals, fallback_mean, fallback_variance, center, level, texel);
  float scale = texel_count / denominator;
  for (int e = 0; e < PLANE_SPLIT_EXTRA; e++) {
    vec4 plane_totals[MOMENT_PLANES];
    for (int plane = 0; plane < MOMENT_PLANES; plane++) {
      plane_totals[plane] = vec4(0.0);
    }
    int c = leaving[e];
    if (c >= 0) {
      plane_totals[0] = scale * class0[c];
      plane_totals[1] = vec4(scale * class1[c], 0.0, 0.0);
      plane_totals[3] = scale * class3[c];
    }
    write_vsgl(vsgl_count + PLANE_SPLIT_EXTRA * index + e, plane_totals, fallback_mean, fallback_variance,
               center, level, texel);
  }
}
