// Empties the micro-buffers of a batch: every texel of the first u_count rows becomes MB_EMPTY.
#include "lib/microbuffer.glsl"
layout(local_size_x = 64, local_size_y = 1) in;
uniform uint u_width;    // M * M
uniform uint u_count;    // receivers (rows)
void main() {
    uvec2 g = gl_GlobalInvocationID.xy;
    if (g.x >= u_width || g.y >= u_count) return;
    imageStore(mb_image, ivec2(g), uvec4(MB_EMPTY, MB_EMPTY, 0u, 0u));
}
