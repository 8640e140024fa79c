// @require lib/image.glsl
// @require lib/math.glsl
//
// Camera G-buffer pass, fragment stage: one GBufferTexel per pixel, written to the outputs
// gbuffer_<attachment> by the generated gbuffer_store (attachments and channels declared in
// vsgl_addon/layouts.py GBUFFER; meaning documented in vsgl_addon/passes/gbuffer.py).
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
  GBufferTexel r;
  r.position = world_position;
  r.coverage = 1.0;
  r.normal = normal;
  r.roughness = clamp(material_params.x, 0.0, 1.0);
  r.base_color = max(base_color, vec3(0.0));
  r.metallic = clamp(material_params.y, 0.0, 1.0);
  r.specular_ior_level = material_params.z;
  r.ior = material_params.w;
  r.material_index = material_index;
  r.object_index = object_index_flat;
  gbuffer_store(r);
}
