// @require lib/math.glsl
//
// Camera G-buffer pass, fragment stage. Layout (RGBA32F; documented in vsgl_addon/passes/gbuffer.py):
//   gbuffer_position   = (world position, coverage 1)
//   gbuffer_normal     = (world shading normal facing the camera, Principled roughness)
//   gbuffer_base_color = (base colour, image sampled at the UV when present; metallic)
//   gbuffer_material   = (Specular IOR Level, IOR, material index, 1)
// Pixels with no geometry keep the clear value 0 (coverage 0).
//
// camera: xyz = camera position (perspective, w = 1) or the direction towards the camera
// (orthographic, w = 0).

// Base colour image: bilinear, repeat extension, texel centres at (i + 0.5) / W (Blender's Linear
// interpolation), by texel loads (Python textures cannot set their sampler's wrap mode). The same
// sampling as the RSM pass (glsl/rsm/rsm.frag.glsl).
vec3 gbuffer_base_color_sample(vec2 uv)
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
  vec3 towards_camera = camera.w > 0.5 ? camera.xyz - world_position : camera.xyz;
  towards_camera = safe_normalize(towards_camera, vec3(0.0, 0.0, 1.0));
  vec3 geometric = safe_normalize(face_normal_flat, towards_camera);
  float side = dot(geometric, towards_camera) < 0.0 ? -1.0 : 1.0;  // two-sided: face the camera
  vec3 normal = side * safe_normalize(corner_normal, side * geometric);

  vec3 base_color = material_base_color.w > 0.5 ? gbuffer_base_color_sample(texcoord) :
                                                  material_base_color.rgb;
  gbuffer_position = vec4(world_position, 1.0);
  gbuffer_normal = vec4(normal, clamp(material_params.x, 0.0, 1.0));
  gbuffer_base_color = vec4(max(base_color, vec3(0.0)), clamp(material_params.y, 0.0, 1.0));
  gbuffer_material = vec4(material_params.z, material_params.w, material_index, 1.0);
}
