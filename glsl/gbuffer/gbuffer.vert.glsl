// Camera G-buffer pass, vertex stage: the scene's world-space triangles (one vertex per corner,
// sorted by material: vsgl_addon/passes/rsm.py SceneGPU) seen by the camera
// (vsgl_addon/passes/gbuffer.py).
void main()
{
  world_position = position;
  corner_normal = normal;
  face_normal_flat = face_normal;
  texcoord = uv;
  gl_Position = view_projection * vec4(position, 1.0);
}
