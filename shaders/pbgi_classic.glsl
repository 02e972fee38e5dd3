// Classic PBGI (paper Section 5.2, with Section 5.3's corrections): per receiver, a depth-first
// stackless walk of the BSH finds the cut; accepted nodes are rasterised into the receiver's
// micro-buffer (lib/microbuffer.glsl). One invocation per receiver of the batch.
//
// llvmpipe stops every loop of an invocation silently after 65,535 iterations in total, so one
// dispatch does a bounded slice of the walk and the host dispatches again until no receiver is
// left: state[i].x is the node to resume from (BSH_END when done). Within a dispatch the walk
// comes first (at most u_steps nodes, at most LIST_CAP accepted nodes, at most u_splat_budget
// entry tests: mb_rect_entries of each accepted rectangle), then one flat loop rasterises the
// accepted nodes, entry by entry (mb_cursor: no inner loop). Re-rasterising a node is
// idempotent (strict depth test), so a slice cut short anywhere resumes at the first node whose
// rasterisation did not finish and nothing is lost or counted twice.
//
// Per node A at distance d, radius r, seen from receiver p with normal n:
//   * below the horizon (dot(c - p, n) <= -r): discard the subtree;
//   * back-facing (Fig. 5, made conservative for the sphere's angular radius b = asin(r / d)):
//     discard when every direction from p into the sphere meets only back faces of the normal
//     cone, i.e. angle(-w, n_A) > alpha_A + b + pi/2  <=>  dot(w, n_A) > sin(alpha_A + b);
//   * solid angle (eq. 4) 2 pi (1 - sqrt(d^2 - r^2) / d), computed as 2 pi s / (1 + sqrt(1 - s))
//     with s = r^2 / d^2 (no cancellation, and no sqrt of a negative); a receiver inside the
//     sphere (d <= r) sees it everywhere: descend, or rasterise a leaf into every micro-pixel;
//   * accept when Omega(A) <= u_omega_stop (= 4 Omega, Section 5.3) - tightened to
//     u_omega_horizon for a node straddling the horizon, so nodes cut by the horizon are small
//     (the rasteriser only ever uses directions above the horizon, and rim micro-pixels are
//     split into thin elevation bands, so a straddling node cannot smear light from below the
//     horizon over a wide edge micro-pixel) - or when A is a leaf; else descend.
#include "lib/common.glsl"
#include "lib/principled.glsl"
#include "lib/bsh_textures.glsl"
#include "lib/microbuffer.glsl"
#include "lib/receivers.glsl"

#ifndef LIST_CAP
#define LIST_CAP 256
#endif

layout(local_size_x = 64) in;

layout(std430, binding = 1) buffer State { uvec4 state[]; };   // next node, visited, flags, tests
layout(std430, binding = 2) buffer Counter { uint remaining; };

uniform uint u_first;          // first receiver of the batch
uniform uint u_count;          // receivers in the batch
uniform int u_m;               // micro-buffer size M
uniform float u_omega_stop;    // 4 * 2 pi / M^2
uniform float u_omega_horizon; // threshold for nodes straddling the horizon
uniform uint u_steps;          // node visits per dispatch
uniform uint u_splat_budget;   // entry tests per dispatch (>= entries per receiver)
uniform float u_inv_cell_area; // 1 / cell_size^2 of the hierarchy (tie-break scale)
uniform uint u_node_count;     // BSH_END

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    uvec4 st = state[i];
    uint end = u_node_count;
    uint node = st.x;
    if (node >= end) return;

    uint rid = u_first + i;
    vec3 p = receiver_position(rid);
    vec3 N = receiver_normal(rid);
    vec3 T, B;
    orthonormal_basis(N, T, B);
    uvec4 full_rect = uvec4(0u, 0u, uint(u_m - 1), uint(u_m - 1));

    uint list_node[LIST_CAP];
    uint list_rect[LIST_CAP];
    uint count = 0u;
    uint cost = 0u;
    uint steps = 0u;

    // ---- walk -----------------------------------------------------------------------------
    while (node < end && steps < u_steps) {
        vec4 s = tnode_sphere(node);
        uvec2 link = tnode_link(node);  // (skip, count | leaf bit)
        vec3 dv = s.xyz - p;
        float d2 = dot(dv, dv);
        float r2 = s.w * s.w;
        float h = dot(dv, N);
        bool leaf = (link.y & BSH_TEX_LEAF_BIT) != 0u;
        uint next = node + 1u;          // descend
        bool accept = false;
        uvec4 rect = full_rect;
        if (h <= -s.w) {
            next = link.x;              // entirely below the horizon
        } else if (d2 > r2) {
            float inv_d = inversesqrt(d2);
            float sin_b = s.w * inv_d;
            float sin_b2 = sin_b * sin_b;
            float cos_b = sqrt(max(1.0 - sin_b2, 0.0));
            vec4 cone = tnode_cone(node);
            float sin_a = sqrt(max(1.0 - cone.w * cone.w, 0.0));
            float cos_ab = cone.w * cos_b - sin_a * sin_b;     // cos(alpha + b)
            float sin_ab = sin_a * cos_b + cone.w * sin_b;     // sin(alpha + b)
            if (cos_ab > 0.0 && dot(dv, cone.xyz) * inv_d > sin_ab) {
                next = link.x;          // back-facing subtree (Fig. 5)
            } else {
                float omega = TWO_PI * sin_b2 / (1.0 + cos_b);
                float limit = abs(h) < s.w ? u_omega_horizon : u_omega_stop;
                if (leaf || omega <= limit) {
                    accept = true;
                    vec3 l = vec3(dot(dv, T), dot(dv, B), h) * inv_d;
                    rect = mb_cone_rect(l, sin_b, cos_b, u_m);
                }
            }
        } else if (leaf) {
            accept = true;              // receiver inside a leaf: it surrounds the receiver
        }
        if (accept) {
            uint c = mb_rect_entries(rect);
            if (count == uint(LIST_CAP) || (count > 0u && cost + c > u_splat_budget)) break;
            list_node[count] = node;
            list_rect[count] = mb_pack_rect(rect);
            count++;
            cost += c;
            next = link.x;
        }
        node = next;
        steps++;
    }

    // ---- rasterise the accepted nodes: one flat loop over (node, entry) ------------------------
    uint k = 0u;                        // list entry
    MbCursor cur;                       // entry within the node's rectangle
    MbNode nd;
    uvec4 rect = full_rect;
    bool load = true;
    uint it;
    for (it = 0u; it < cost; ++it) {
        if (load) {
            uint a = list_node[k];
            vec4 s = tnode_sphere(a);
            vec4 cone = tnode_cone(a);
            nd.dv = s.xyz - p;
            nd.d2 = dot(nd.dv, nd.dv);
            nd.r2 = s.w * s.w;
            nd.axis = cone.xyz;
            nd.sin_a = cone.w > 0.0 ? sqrt(max(1.0 - cone.w * cone.w, 0.0)) : 1.0;
            nd.inv_area = u_inv_cell_area / float(max(tnode_link(a).y & BSH_TEX_COUNT_MASK, 1u));
            nd.index = a;
            rect = mb_unpack_rect(list_rect[k]);
            cur = mb_cursor(rect);
            load = false;
        }
        uint kk = mb_cursor_entry(cur, u_m);
        vec4 tb = mb_table(kk);
        if (tb.w > 0.0) {
            vec3 w = T * tb.x + B * tb.y + N * tb.z;
            uint key = mb_hit_key(nd, w);
            if (key != MB_EMPTY) mb_write(i, kk, key, nd.index);
        }
        if (!mb_cursor_next(cur, rect)) { k++; load = true; }
    }
    // A loop cut short by the driver leaves k < count: resume at the unfinished node.
    uint resume = (it == cost && k == count) ? node : list_node[min(k, count - 1u)];
    if (count == 0u) resume = node;
    uint flags = (resume >= end ? 1u : 0u) | (it == cost ? 0u : 2u);
    state[i] = uvec4(resume, st.y + steps, st.z | flags, st.w + it);
    if (resume < end) atomicAdd(remaining, 1u);
}
