// A mirror shadow map of one rectangle proxy (vsgl_addon/passes/mrp_visibility.py): the scene's
// depth seen from the light's mirror image through the proxy, keeping only what lies in front of
// the proxy's plane (`plane` = (unit normal of the lit side, offset n.c) in world space, minus a
// tolerance): the ray from the mirrored light to a receiver x crosses the plane at x's specular
// peak p_y (001 Eq. 12), so the first surface this map stores on it is the first one between
// p_y and x. Depth only; the colour output is unused.
void main()
{
  if (dot(plane.xyz, world_position) - plane.w < 0.0) {
    discard;
  }
  mirror_unused = vec4(0.0);
}
