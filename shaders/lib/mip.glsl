// The G-buffer pyramid's GPU records (app/pbgi/gmip.py), in images (llvmpipe loads image texels
// ~10x faster than SSBO words). Pixel g lives at texel mip_texel(g) of three images:
//   mip_sphere = (bounding-sphere centre of its receivers' positions, radius)
//   mip_cone   = (normal-cone axis, half-angle in radians)
//   mip_link   = (first child pixel | receiver slot at level 0, child count (0 at level 0),
//                 parent pixel or MIP_NIL, level)
// Define MIP_WRITABLE where the geometry is written (the pyramid build).
#ifndef SCANLIGHT_MIP_GLSL
#define SCANLIGHT_MIP_GLSL
#define MIP_NIL 0xffffffffu
#define MIP_WIDTH_LOG2 12u
#define MIP_WIDTH 4096u
#ifndef MIP_UNIT_SPHERE
#define MIP_UNIT_SPHERE 4
#endif
#ifndef MIP_UNIT_CONE
#define MIP_UNIT_CONE 5
#endif
#ifndef MIP_UNIT_LINK
#define MIP_UNIT_LINK 6
#endif
ivec2 mip_texel(uint g) { return ivec2(int(g & (MIP_WIDTH - 1u)), int(g >> MIP_WIDTH_LOG2)); }
#ifdef MIP_WRITABLE
layout(rgba32f, binding = MIP_UNIT_SPHERE) uniform image2D mip_sphere_img;
layout(rgba32f, binding = MIP_UNIT_CONE) uniform image2D mip_cone_img;
#else
layout(rgba32f, binding = MIP_UNIT_SPHERE) uniform readonly image2D mip_sphere_img;
layout(rgba32f, binding = MIP_UNIT_CONE) uniform readonly image2D mip_cone_img;
#endif
layout(rgba32ui, binding = MIP_UNIT_LINK) uniform readonly uimage2D mip_link_img;
vec4 mip_sphere(uint g) { return imageLoad(mip_sphere_img, mip_texel(g)); }
vec4 mip_cone(uint g) { return imageLoad(mip_cone_img, mip_texel(g)); }
uvec4 mip_link(uint g) { return imageLoad(mip_link_img, mip_texel(g)); }
#endif
