// Far-field sharing (Hybrid, app/pbgi/farfield.py): copy a block's far-field micro-buffer into the
// micro-buffers of its receivers, before each receiver walks its own near field into it (depth
// tested, so a near node in front of a far one wins). Every receiver of a block keeps its
// micro-buffer in the block's frame (the frame of its normal-cone axis), so the copy is entry for
// entry; the gather weights each entry with the receiver's own cosine (FRAME_NORMALS in
// pbgi_gather.glsl). The renderer does not empty these micro-buffers first (the copy writes every
// entry, empty ones included); a dispatch with u_clear_unshared empties the rows of receivers
// without a block (share_block(i) == SHARE_NONE) instead. A copied entry's node gets MB_FAR_BIT, so
// the gather can tell the shared far field (scaled by the block's level, app/pbgi/block_levels.py)
// from the receiver's own near field.
#include "lib/microbuffer.glsl"
#include "gen/block_of.glsl"

layout(local_size_x = WORKGROUP_SIZE) in;

// the block micro-buffers (MbEntry texels, as mb_image), one row per block
layout(rg32ui, binding = IMG_SHARE_SOURCE) uniform readonly uimage2D share_image;

uniform uint u_begin;          // batch receivers [u_begin, u_end) are merged by this dispatch
uniform uint u_end;
uniform uint u_block0;         // blocks [u_block0, u_block1) are in share_image, from row 0
uniform uint u_block1;
uniform bool u_clear_unshared;  // empty the rows of unshared receivers (no copy)

void main() {
    uint i = u_begin + gl_GlobalInvocationID.x;
    if (i >= u_end) return;
    uint b = share_block(i);
    uint mm = mb_entries();
    if (u_clear_unshared) {
        if (b != SHARE_NONE) return;
        for (uint k = 0u; k < mm; ++k)
            mb_entry_store(ivec2(int(k), int(i)), MbEntry(MB_EMPTY, MB_EMPTY));
        return;
    }
    if (b == SHARE_NONE || b < u_block0 || b >= u_block1) return;
    int row = int(b - u_block0);
    for (uint k = 0u; k < mm; ++k) {
        MbEntry e = mb_entry_unpack(imageLoad(share_image, ivec2(int(k), row)).xy);
        if (e.node != MB_EMPTY) e.node |= MB_FAR_BIT;
        mb_entry_store(ivec2(int(k), int(i)), e);
    }
}
