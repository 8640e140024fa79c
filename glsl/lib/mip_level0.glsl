// Level 0 of the six RSM quantity planes, each its own RGBA32F texture: the samplers
// `level0_plane0` .. `level0_plane5`, which shaders that @require this file declare (layout in
// glsl/lib/mip_atlas.glsl).

vec4 level0_fetch(int plane, ivec2 texel)
{
  switch (plane) {
    case 0:
      return texelFetch(level0_plane0, texel, 0);
    case 1:
      return texelFetch(level0_plane1, texel, 0);
    case 2:
      return texelFetch(level0_plane2, texel, 0);
    case 3:
      return texelFetch(level0_plane3, texel, 0);
    case 4:
      return texelFetch(level0_plane4, texel, 0);
    default:
      return texelFetch(level0_plane5, texel, 0);
  }
}
