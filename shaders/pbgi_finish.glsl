// The depth-first finishing walk of Mipmapped and Hybrid PBGI ("a per-pair depth-first walk as in
// Classic", paper Section 5.2.2), one invocation per receiver of the batch.
//
// The refinement passes (pbgi_refine.glsl) leave *items* = sub-tree roots, each on the list of
// one G-buffer pyramid pixel P (head(P) -> item.y -> ... -> NIL, lib/pair_streams.glsl).
// Receiver q owns the items on the lists of every pixel on its path to the top of the pyramid
// and walks each item's sub-tree [A, skip(A)) with Classic's rules and rasteriser
// (lib/pbgi_cut.glsl). One invocation owns one micro-buffer, so writes need no atomics; items
// come in any order and cut_write's tie-break makes the result order-independent.
// Lists are walked top-down (coarsest pixel first): neighbouring receivers - the lanes of one
// SIMD group, Z-ordered - share the coarse lists and so walk the same sub-trees side by side,
// which is why the accepted nodes are rasterised with cut_raster_nested (Classic, whose lanes
// are out of step, uses the flat cut_raster; both give the same entries).
//
// llvmpipe's loop budget: like Classic, one dispatch does a bounded slice (u_steps walk steps,
// CUT_LIST_CAP accepted nodes, u_splat_budget micro-pixel tests) and saves where to resume:
//   state[2i]     = (node, end of the current sub-tree, next item on the list, pixel P)
//   state[2i + 1] = (nodes visited, flags (bit 0 done, bit 1 a loop was cut short), micro-pixel
//                    tests, the receiver's level-0 pixel)
// P == NIL: every list of this receiver is finished. A slice whose rasterisation the driver cut
// short is redone from its start (re-rasterising is idempotent) and flagged.
// STAGE_INIT (one invocation per level-0 pixel) points every receiver at the head of the list
// of its top-most pixel before a finishing phase.
#include "lib/common.glsl"
#include "lib/principled.glsl"
#include "lib/bsh_textures.glsl"
#include "lib/microbuffer.glsl"
#include "lib/receivers.glsl"
#include "lib/mip.glsl"
#include "lib/pbgi_cut.glsl"

#define NIL 0xffffffffu

layout(local_size_x = 64) in;

layout(std430, binding = 1) buffer State { uvec4 state[]; };
layout(std430, binding = 2) buffer Counter { uint remaining; };
#define PAIR_STREAMS_READONLY 1
#include "lib/pair_streams.glsl"

uniform uint u_count;          // receivers in the batch (STAGE_INIT: level-0 pixels)
#ifndef STAGE_INIT
uniform uint u_first;          // first receiver of the batch
uniform int u_m;               // micro-buffer size M
uniform float u_omega_stop;    // 4 * 2 pi / M^2
uniform float u_omega_horizon; // threshold for nodes straddling the horizon
uniform uint u_steps;          // walk steps per dispatch
uniform uint u_splat_budget;   // micro-pixel tests per dispatch (>= M * M)
uniform float u_inv_cell_area; // 1 / cell_size^2 of the hierarchy (tie-break scale)
#endif

// The ancestor of level-0 pixel p0 at ``level`` (<= 16 steps up the pyramid).
uint ancestor(uint p0, uint level) {
    uint g = p0;
    for (uint k = 0u; k < level; ++k) g = mip_link(g).z;
    return g;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
#ifdef STAGE_INIT
    uint slot = mip_link(i).x;               // level-0 pixel i -> its receiver slot
    uint top = i;
    for (uint k = 0u; k < 16u; ++k) {
        uint up = mip_link(top).z;
        if (up == NIL) break;
        top = up;
    }
    uvec4 s1 = state[2u * slot + 1u];
    state[2u * slot] = uvec4(0u, 0u, head_load(top), top);
    state[2u * slot + 1u] = uvec4(s1.x, s1.y & ~1u, s1.z, i);
#else
    uvec4 s0 = state[2u * i];
    uvec4 s1 = state[2u * i + 1u];
    uint node = s0.x, end = s0.y, nxt = s0.z, P = s0.w, p0 = s1.w;
    if (P == NIL) return;

    uint rid = u_first + i;
    vec3 p = receiver_position(rid);
    vec3 N = receiver_normal(rid);
    vec3 T, B;
    orthonormal_basis(N, T, B);

    uint count = 0u, cost = 0u, steps = 0u, visited = 0u;
    bool full = false;
    // Outer loop: the next item (sub-tree root) when the current sub-tree is done; inner loop:
    // Classic's walk of the sub-tree.
    while (steps < u_steps && !full) {
        if (node >= end) {
            steps++;
            if (nxt == NIL) {                // this pixel's list is done: the next finer one
                uint level = mip_link(P).w;
                if (level == 0u) { P = NIL; break; }
                P = ancestor(p0, level - 1u);
                nxt = head_load(P);
                continue;
            }
            uvec4 item = item_load(nxt);
            node = item.x;
            end = item.w;                    // skip(node), stored with the item
            nxt = item.y;
        }
        while (node < end && steps < u_steps) {
            uvec4 rect;
            uint skip;
            uint dec = cut_decide(node, p, N, T, B, u_omega_stop, u_omega_horizon, u_m, rect, skip);
            uint next = node + 1u;
            if (dec == CUT_ACCEPT) {
                if (!cut_list_push(node, rect, count, cost, u_splat_budget)) {
                    full = true;
                    break;
                }
                next = skip;
            } else if (dec == CUT_SKIP) {
                next = skip;
            }
            node = next;
            steps++;
            visited++;
        }
    }

    uint k;
    uint it = cut_raster_nested(count, cost, p, N, T, B, i, u_m, u_inv_cell_area, k);
    uint flags = 0u;
    if (k < count) {                         // the driver cut the loop short: redo this slice
        flags = 2u;
        node = s0.x; end = s0.y; nxt = s0.z; P = s0.w;
    }
    if (P == NIL) flags |= 1u;
    state[2u * i] = uvec4(node, end, nxt, P);
    state[2u * i + 1u] = uvec4(s1.x + visited, (s1.y & ~1u) | flags, s1.z + it, p0);
    if (P != NIL) atomicAdd(remaining, 1u);
#endif
}
