// Read-only texture view of the BSH records, built on the GPU from the canonical 40-byte
// records (shaders/bsh_textures.glsl reads them through gen/node_layout.glsl), for the walks.
// Why: on llvmpipe an SSBO load with per-lane addresses is a branchy scalar loop per component,
// a texelFetch is one vector gather; the walk reads a few nodes per step, so the node reads are
// most of its cost (measure with: scanlight bench classic).
// Node i lives at texel bsh_texel(i) of four textures; their texels are declared in
// app/pbgi/gpu_layout.py (BSH_SPHERE, BSH_CONE, BSH_LINK, BSH_COLOR -> gen/bsh_textures.glsl).
#ifndef SCANLIGHT_BSH_TEXTURES_GLSL
#define SCANLIGHT_BSH_TEXTURES_GLSL
#include "gen/bsh_textures.glsl"

BshSphere tnode_sphere(uint i) { return bsh_sphere_unpack(texelFetch(bsh_sphere_tex, bsh_texel(i), 0)); }
BshCone tnode_cone(uint i) { return bsh_cone_unpack(texelFetch(bsh_cone_tex, bsh_texel(i), 0)); }
BshLink tnode_link(uint i) { return bsh_link_unpack(texelFetch(bsh_link_tex, bsh_texel(i), 0)); }
vec3 tnode_color(uint i) { return bsh_color_unpack(texelFetch(bsh_color_tex, bsh_texel(i), 0)).color; }
#endif
