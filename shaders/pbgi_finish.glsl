// The depth-first finishing walk of Mipmapped and Hybrid PBGI ("a per-pair depth-first walk as in
// Classic", paper Section 5.2.2), one invocation per receiver of the batch.
//
// The refinement passes (pbgi_refine.glsl) leave *items* = sub-tree roots, each on the list of
// one G-buffer pyramid pixel P (head(P) -> item.next -> ... -> NIL, gen/pair_streams.glsl).
// Receiver q owns the items on the lists of every pixel on its path to the top of the pyramid
// and walks each item's sub-tree [A, skip(A)) with Classic's rules and rasteriser
// (lib/pbgi_cut.glsl). One invocation owns one micro-buffer, so writes need no atomics; items
// come in any order and cut_write's tie-break makes the result order-independent.
// Lists are walked top-down (coarsest pixel first): neighbouring receivers - the lanes of one
// SIMD group, Z-ordered - share the coarse lists and so walk the same sub-trees side by side,
// and rasterise the same nodes in the same order (lib/pbgi_cut.glsl: cut_raster, node by node).
//
// llvmpipe's loop budget: like Classic, one dispatch does a bounded slice (u_steps walk steps,
// CUT_LIST_CAP accepted nodes, u_splat_budget micro-pixel tests) and saves where to resume in
// state[i], a FinishState (gen/walk_state.glsl: the current sub-tree, the next item on the list,
// the pixel P whose list it is, counts, flags WALK_DONE / WALK_CUT_SHORT, the level-0 pixel).
// P == NIL: every list of this receiver is finished. A slice whose rasterisation the driver cut
// short is redone from its start (re-rasterising is idempotent) and flagged.
// STAGE_INIT (one invocation per level-0 pixel) points every receiver at the head of the list
// of its top-most pixel before a finishing phase.
#include "lib/common.glsl"
#include "lib/principled.glsl"
#include "lib/bsh_textures.glsl"
#include "lib/microbuffer.glsl"
#include "gen/receivers.glsl"
#include "gen/mip.glsl"
#include "lib/pbgi_cut.glsl"
#include "gen/walk_state.glsl"

layout(local_size_x = WORKGROUP_SIZE) in;

layout(std430, binding = SSBO_WALK_STATE) buffer State { FinishState state[]; };
layout(std430, binding = SSBO_COUNTERS) buffer Counter { uint remaining; };
#define PAIR_STREAMS_READONLY 1
#include "gen/pair_streams.glsl"

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
    for (uint k = 0u; k < level; ++k) g = mip_link(g).parent;
    return g;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
#ifdef STAGE_INIT
    uint slot = mip_link(i).first;           // level-0 pixel i -> its receiver slot
    uint top = i;
    for (uint k = 0u; k < 16u; ++k) {
        uint up = mip_link(top).parent;
        if (up == NIL) break;
        top = up;
    }
    FinishState s = state[slot];
    s.node = 0u;
    s.end = 0u;
    s.next_item = head_load(top);
    s.pixel = top;
    s.flags &= ~WALK_DONE;
    s.pixel0 = i;
    state[slot] = s;
#else
    FinishState s = state[i];
    uint node = s.node, end = s.end, nxt = s.next_item, P = s.pixel, p0 = s.pixel0;
    if (P == NIL) return;

    uint rid = u_first + i;
    vec3 p = receiver_position(rid);
    vec3 N = receiver_normal(rid);
    vec3 T, B;
    mb_frame(N, receiver_pixel(rid), T, B);

    uint count = 0u, cost = 0u, steps = 0u, visited = 0u;
    bool full = false;
    // Outer loop: the next item (sub-tree root) when the current sub-tree is done; inner loop:
    // Classic's walk of the sub-tree.
    while (steps < u_steps && !full) {
        if (node >= end) {
            steps++;
            if (nxt == NIL) {                // this pixel's list is done: the next finer one
                uint level = mip_link(P).level;
                if (level == 0u) { P = NIL; break; }
                P = ancestor(p0, level - 1u);
                nxt = head_load(P);
                continue;
            }
            Item item = item_load(nxt);
            node = item.node;
            end = item.skip;                 // skip(node), stored with the item
            nxt = item.next;
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
    uint it = cut_raster(count, p, N, T, B, i, u_m, u_inv_cell_area, k);
    uint flags = 0u;
    if (k < count) {                         // the driver cut the loop short: redo this slice
        flags = WALK_CUT_SHORT;
        node = s.node; end = s.end; nxt = s.next_item; P = s.pixel;
    }
    if (P == NIL) flags |= WALK_DONE;
    state[i] = FinishState(node, end, nxt, P, s.visited + visited, (s.flags & ~WALK_DONE) | flags,
                           s.tests + it, p0);
    if (P != NIL) atomicAdd(remaining, 1u);
#endif
}
