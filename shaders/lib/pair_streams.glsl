// The two streams of Mipmapped/Hybrid PBGI (app/pbgi/mipmapped.py), in images (llvmpipe loads
// image texels ~10x faster than SSBO words), WIDTH 4096 texels per row (lib/mip.glsl's layout):
//   pairs (RG32UI):   the pending (node, pyramid pixel) pairs, a stack;
//   items (RGBA32UI): the second stream, sub-tree roots for the finishing walk:
//                     (node, next item on the same pixel's list or MIP_NIL, pixel, skip(node));
//   heads (R32UI):    per pyramid pixel, the first item of its list or MIP_NIL.
// Needs lib/mip.glsl (mip_texel). Define PAIR_STREAMS_READONLY in the finishing walk.
#ifndef SCANLIGHT_PAIR_STREAMS_GLSL
#define SCANLIGHT_PAIR_STREAMS_GLSL
#ifndef PAIR_UNIT
#define PAIR_UNIT 1
#endif
#ifndef ITEM_UNIT
#define ITEM_UNIT 2
#endif
#ifndef HEAD_UNIT
#define HEAD_UNIT 3
#endif
#ifdef PAIR_STREAMS_READONLY
layout(rgba32ui, binding = ITEM_UNIT) uniform readonly uimage2D items_img;
layout(r32ui, binding = HEAD_UNIT) uniform readonly uimage2D heads_img;
#else
layout(rg32ui, binding = PAIR_UNIT) uniform uimage2D pairs_img;
layout(rgba32ui, binding = ITEM_UNIT) uniform writeonly uimage2D items_img;
layout(r32ui, binding = HEAD_UNIT) uniform uimage2D heads_img;
uvec2 pair_load(uint i) { return imageLoad(pairs_img, mip_texel(i)).xy; }
void pair_store(uint i, uint node, uint pixel) {
    imageStore(pairs_img, mip_texel(i), uvec4(node, pixel, 0u, 0u));
}
void item_store(uint i, uint node, uint next, uint pixel, uint skip) {
    imageStore(items_img, mip_texel(i), uvec4(node, next, pixel, skip));
}
#endif
#ifdef PAIR_STREAMS_READONLY
uvec4 item_load(uint i) { return imageLoad(items_img, mip_texel(i)); }
uint head_load(uint pixel) { return imageLoad(heads_img, mip_texel(pixel)).x; }
#endif
#endif
