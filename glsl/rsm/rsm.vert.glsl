// Reflective shadow map (RSM) pass, vertex stage: world-space triangles of the scene (one vertex per
// triangle corner, sorted by material) seen from one RSM view of a light (vsgl_addon/passes/rsm.py).
// The light's view-projection is the only transform: positions are already in world space.
void main()
{
  world_position = position;
  corner_normal = normal;
  face_normal_flat = face_normal;
  texcoord = uv;
  gl_Position = view_projection * vec4(position, 1.0);
}
