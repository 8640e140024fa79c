// @require lib/image.glsl
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

void main()
{
  vec3 towards_camera = camera.w > 0.5 ? camera.xyz - world_position : camera.xyz;
  towards_camera = safe_normalize(towards_camera, vec3(0.0, 0.0, 1.0));
  vec3 geometric = safe_normalize(face_normal_flat, towards_camera);
  float side = dot(geometric, towards_camera) < 0.0 ? -1.0 : 1.0;  // two-sided: face the camera
  vec3 normal = side * safe_normalize(corner_normal, side * geometric);

  vec3 base_color = material_base_color.w > 0.5 ?
                        image_sample_linear_repeat(base_color_image, texcoord) :
                        material_base_color.rgb;
  gbuffer_position = vec4(world_position, 1.0);
  gbuffer_normal = vec4(normal, clamp(material_params.x, 0.0, 1.0));
  gbuffer_base_color = vec4(max(base_color, vec3(0.0)), clamp(material_params.y, 0.0, 1.0));
  gbuffer_material = vec4(material_params.z, material_params.w, material_index, 1.0);
}
