// Blender's light linking, shadow linking and ray visibility per (light, object), as the passes
// that draw the scene read them: one RGBA32F texel per pair, uploaded by
// vsgl_addon/passes/scene_gpu.py (SceneGPU.light_links, light_links_array), where object o of
// light l sits at (o mod width, l * rows + o div width). Channels (scene_description.LINK_*):
//   x  the object receives the light (light linking)
//   y  the object blocks the light (shadow linking, and the object casts shadows at all)
//   z  the object is seen by diffuse rays: its bounce reaches receivers' diffuse lobes
//   w  the object is seen by glossy rays: its bounce reaches receivers' glossy lobes
// rows <= 0: the scene uses none of them, everything is 1.
vec4 light_links_fetch(sampler2D links, int rows, int light_index, float object_index)
{
  if (rows <= 0) {
    return vec4(1.0);
  }
  int width = textureSize(links, 0).x;
  int object = int(object_index + 0.5);
  return texelFetch(links, ivec2(object % width, light_index * rows + object / width), 0);
}
