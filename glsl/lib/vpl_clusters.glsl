// The glossy VPLs' shadow-map clusters (twin: vsgl_addon/reference/vpl_clusters.py, same names): the
// texels of one VPL_CLUSTER_TEXELS^2 block of one RSM view share an imperfect shadow map.

// Blocks per side of a side^2 RSM view (reference cluster_blocks).
int cluster_blocks(int side)
{
  return max(1, (side + VPL_CLUSTER_TEXELS - 1) / VPL_CLUSTER_TEXELS);
}

// The map of the VPL of RSM texel `texel` of view `view`: view * blocks^2 + the texel's block,
// row-major (reference vpl_cluster_map), so a VPL's map follows from its texel.
int vpl_cluster_map(ivec2 texel, int view, int side)
{
  int blocks = cluster_blocks(side);
  return view * blocks * blocks + (texel.y / VPL_CLUSTER_TEXELS) * blocks + texel.x / VPL_CLUSTER_TEXELS;
}
