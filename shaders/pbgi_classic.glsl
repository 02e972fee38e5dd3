// Classic PBGI (paper Section 5.2, with Section 5.3's corrections): per receiver, a depth-first
// stackless walk of the BSH finds the cut; accepted nodes are rasterised into the receiver's
// micro-buffer (lib/microbuffer.glsl). One invocation per receiver of the batch.
//
// llvmpipe stops every loop of an invocation silently after 65,535 iterations in total, so one
// dispatch does a bounded slice of the walk and the host dispatches again until no receiver is
// left: state[i] is a ClassicState (gen/walk_state.glsl), state[i].next the node to resume from
// (BSH_END when done). Within a dispatch the walk
// comes first (at most u_steps nodes, at most LIST_CAP accepted nodes, at most u_splat_budget
// entry tests: mb_rect_entries of each accepted rectangle), then the accepted nodes are
// rasterised, node by node (lib/pbgi_cut.glsl: cut_raster). Re-rasterising a node is
// idempotent (strict depth test), so a slice cut short anywhere resumes at the first node whose
// rasterisation did not finish and nothing is lost or counted twice.
//
// The per-node rules (horizon and back-face culls, eq. 4's solid angle against 4 Omega, the
// straddling threshold) and the rasteriser live in lib/pbgi_cut.glsl, shared with the finishing
// walks of Mipmapped and Hybrid PBGI (pbgi_finish.glsl): the three modes differ only in how
// they reach the cut, never in what the cut is or how it is drawn.
#include "lib/common.glsl"
#include "lib/principled.glsl"
#include "lib/bsh_textures.glsl"
#include "lib/microbuffer.glsl"
#include "gen/receivers.glsl"
#include "gen/walk_state.glsl"

#ifndef LIST_CAP
#define LIST_CAP 256
#endif
#define CUT_LIST_CAP LIST_CAP
#define CUT_ORDERED_WRITES 1          // the walk accepts nodes in index order
#include "lib/pbgi_cut.glsl"

// the local size: gen/bindings.glsl's WORKGROUP_SIZE, or the one app/pbgi/classic.py compiles in
#ifndef CUT_WORKGROUP
#define CUT_WORKGROUP WORKGROUP_SIZE
#endif
layout(local_size_x = CUT_WORKGROUP) in;

layout(std430, binding = SSBO_WALK_STATE) buffer State { ClassicState state[]; };
layout(std430, binding = SSBO_COUNTERS) buffer Counter { uint remaining; };

uniform uint u_first;          // first receiver of the batch
uniform uint u_count;          // receivers in the batch
uniform int u_m;               // micro-buffer size M
uniform float u_omega_stop;    // 4 * 2 pi / M^2
uniform float u_omega_horizon; // threshold for nodes straddling the horizon
uniform uint u_steps;          // node visits per dispatch
uniform uint u_splat_budget;   // entry tests per dispatch (>= entries per receiver)
uniform float u_inv_cell_area; // 1 / cell_size^2 of the hierarchy (tie-break scale)
uniform uint u_node_count;     // BSH_END

// Far-field sharing (Hybrid, app/pbgi/farfield.py): row i's ShareRow (gen/share_rows.glsl) holds
// the ball (centre, D) that splits the tree for row i and the normal whose frame (and horizon)
// row i's micro-buffer uses: its block's cone axis. A node whose sphere lies outside the ball is *far* (so is its whole
// sub-tree: a parent's sphere contains its children's). SHARE_SPLIT 1: row i is a block of
// receivers and walks only the far field (from the block's centre, in its normal-cone frame);
// SHARE_SPLIT 2: row i is a receiver and walks only the near field (D = +inf: everything).
#ifdef SHARE_SPLIT
#include "gen/share_rows.glsl"
#endif

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    ClassicState st = state[i];
    uint end = u_node_count;
    uint node = st.next;
    if (node >= end) return;

    uint rid = u_first + i;
    vec3 p = receiver_position(rid);
    vec3 N = receiver_normal(rid);
#ifdef SHARE_SPLIT
    vec3 ball_center = share_center(i);
    float ball_radius = share_ball(i);
    N = share_frame(i);
    vec3 T, B;
    mb_frame_shared(N, share_seed(i), receiver_pixel(rid), T, B);   // its block's, or its own
#else
    vec3 T, B;
    mb_frame(N, receiver_pixel(rid), T, B);
#endif

    uint count = 0u;
    uint cost = 0u;
    uint steps = 0u;

    // ---- walk -----------------------------------------------------------------------------
    while (node < end && steps < u_steps) {
        uvec4 rect;
        uint skip;
        uint dec = cut_decide(node, p, N, T, B, u_omega_stop, u_omega_horizon, u_m, rect, skip);
#ifdef SHARE_SPLIT
        BshSphere sph = tnode_sphere(node);
        vec3 dc = sph.center - ball_center;
        float rr = ball_radius + sph.radius;
        bool far = dot(dc, dc) >= rr * rr;
#if SHARE_SPLIT == 1
        if (!far) dec = (tnode_link(node).count_flags & BSH_TEX_LEAF_BIT) != 0u ? CUT_SKIP : CUT_DESCEND;
#else
        if (far) dec = CUT_SKIP;
#endif
#endif
        uint next = node + 1u;          // descend
        if (dec == CUT_ACCEPT) {
            if (!cut_list_push(node, rect, count, cost, u_splat_budget)) break;
            next = skip;
        } else if (dec == CUT_SKIP) {
            next = skip;                // below the horizon or back-facing: skip the subtree
        }
        node = next;
        steps++;
    }

    // ---- rasterise the accepted nodes ----------------------------------------------------------
    uint k;
    uint it = cut_raster(count, p, N, T, B, i, u_m, u_inv_cell_area, k);
    // A loop cut short by the driver leaves k < count: resume at the unfinished node.
    uint resume = k == count ? node : cut_list_node[k];
    uint flags = (resume >= end ? WALK_DONE : 0u) | (k == count ? 0u : WALK_CUT_SHORT);
    state[i] = ClassicState(resume, st.visited + steps, st.flags | flags, st.tests + it);
    if (resume < end) atomicAdd(remaining, 1u);
}
