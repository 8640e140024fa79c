// The scene's world-space triangles (one vertex per triangle corner, sorted by material:
// vsgl_addon/passes/scene_gpu.py SceneGPU) seen through one view-projection: a light's RSM view
// (vsgl_addon/passes/rsm.py) or the camera (vsgl_addon/passes/gbuffer.py). Positions are already
// in world space, so the view-projection is the only transform; the face normal goes flat to the
// fragment stage, which flips the shading normal to face the viewer (two-sided surfaces).
void main()
{
  world_position = position;
  corner_normal = normal;
  face_normal_flat = face_normal;
  object_index_flat = object_index;
  texcoord = uv;
  gl_Position = view_projection * vec4(position, 1.0);
}
