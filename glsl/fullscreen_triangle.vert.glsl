// One triangle that covers the viewport: vertices (-1,-1), (3,-1), (-1,3) in `position`.
// `uv` is the texture coordinate of the fragment's centre in [0, 1]^2.
void main()
{
  uv = position * 0.5 + 0.5;
  gl_Position = vec4(position, 0.0, 1.0);
}
