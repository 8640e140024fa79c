// The indirect specular image of a frame with rectangle proxies, on the GPU (the renderer's numpy
// composition in FrameRenderer.render_view, for views whose images stay textures): where MRP-ASG
// serves the pixel (glossy_reflectors.a > 0), or everywhere when `gated` is 0, the VSGLs of the
// RSM without the proxies' specular flux (glossy_specular) plus the proxies' light; elsewhere the
// VSGLs of every reflector (whole_specular), which carry the proxies' light themselves
// (light-paths.md: each path counted once).

void main()
{
  ivec2 pixel = ivec2(gl_FragCoord.xy);
  vec4 reflectors = texelFetch(glossy_reflectors, pixel, 0);
  vec4 glossy = texelFetch(glossy_specular, pixel, 0);
  vec3 vsgl = (gated != 0 && !(reflectors.a > 0.0)) ? texelFetch(whole_specular, pixel, 0).rgb : glossy.rgb;
  indirect_specular = vec4(vsgl + reflectors.rgb, glossy.a);
}
