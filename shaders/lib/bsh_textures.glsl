// Read-only texture view of the BSH records, built on the GPU from the canonical 40-byte
// records (shaders/bsh_textures.glsl reads them through gen/node_layout.glsl), for the walks.
// Why: on llvmpipe an SSBO load with per-lane addresses is a branchy scalar loop per component
// (~40 ns for a vec4 measured here), a texelFetch is a vector gather (~2.4 ns): the walk reads
// a few nodes per step, so this is the difference between seconds and minutes per frame.
// Node i lives at texel bsh_texel(i) of four textures; their texels are declared in
// app/pbgi/gpu_layout.py (BSH_SPHERE, BSH_CONE, BSH_LINK, BSH_COLOR -> gen/bsh_textures.glsl).
#ifndef SCANLIGHT_BSH_TEXTURES_GLSL
#define SCANLIGHT_BSH_TEXTURES_GLSL
#include "gen/bsh_textures.glsl"

vec4 tnode_sphere(uint i) { return texelFetch(bsh_sphere_tex, bsh_texel(i), 0); }   // (center, radius)
vec4 tnode_cone(uint i) { return texelFetch(bsh_cone_tex, bsh_texel(i), 0); }       // (axis, cos_angle)
uvec2 tnode_link(uint i) { return texelFetch(bsh_link_tex, bsh_texel(i), 0).xy; }   // (skip, count_flags)
vec3 tnode_color(uint i) { return texelFetch(bsh_color_tex, bsh_texel(i), 0).rgb; }
#endif
