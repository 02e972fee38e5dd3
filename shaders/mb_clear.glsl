// Empties the micro-buffers of a batch: every texel of the first u_count rows becomes MB_EMPTY.
// One invocation per row, a loop along it: on llvmpipe an invocation costs far more than a loop
// iteration (one invocation per texel pays the dispatch overhead per texel), and E <= 2,000 stays well below the
// 65,535 iterations an invocation may run.
#include "lib/microbuffer.glsl"
layout(local_size_x = WORKGROUP_SIZE) in;
uniform uint u_width;    // entries per row
uniform uint u_count;    // receivers (rows)
void main() {
    uint row = gl_GlobalInvocationID.x;
    if (row >= u_count) return;
    for (uint k = 0u; k < u_width; ++k)
        mb_entry_store(ivec2(int(k), int(row)), MbEntry(MB_EMPTY, MB_EMPTY));
}
