// Read-only texture view of the BSH records, built on the GPU from the canonical 40-byte
// records (shaders/bsh_textures.glsl reads them through gen/node_layout.glsl), for the walks.
// Why: on llvmpipe an SSBO load with per-lane addresses is a branchy scalar loop per component
// (~40 ns for a vec4 measured here), a texelFetch is a vector gather (~2.4 ns): the walk reads
// a few nodes per step, so this is the difference between seconds and minutes per frame.
// Node i lives at texel (i % BSH_TEX_WIDTH, i / BSH_TEX_WIDTH) of four textures:
//   sphere (centre relative to the hierarchy origin, radius), cone (unit axis, cos(half-angle)),
//   link (skip, count | leaf bit, 0, 0) and colour (mean radiance, 0).
#ifndef SCANLIGHT_BSH_TEXTURES_GLSL
#define SCANLIGHT_BSH_TEXTURES_GLSL
#define BSH_TEX_WIDTH_LOG2 12u
#define BSH_TEX_WIDTH 4096u
#define BSH_TEX_LEAF_BIT 0x80000000u
#define BSH_TEX_COUNT_MASK 0x7fffffffu

layout(binding = 1) uniform sampler2D bsh_sphere_tex;
layout(binding = 2) uniform sampler2D bsh_cone_tex;
layout(binding = 3) uniform usampler2D bsh_link_tex;
layout(binding = 4) uniform sampler2D bsh_color_tex;

ivec2 bsh_texel(uint i) { return ivec2(i & (BSH_TEX_WIDTH - 1u), i >> BSH_TEX_WIDTH_LOG2); }
vec4 tnode_sphere(uint i) { return texelFetch(bsh_sphere_tex, bsh_texel(i), 0); }
vec4 tnode_cone(uint i) { return texelFetch(bsh_cone_tex, bsh_texel(i), 0); }
uvec2 tnode_link(uint i) { return texelFetch(bsh_link_tex, bsh_texel(i), 0).xy; }
vec3 tnode_color(uint i) { return texelFetch(bsh_color_tex, bsh_texel(i), 0).rgb; }
#endif
