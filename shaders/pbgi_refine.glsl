// Iterative refinement of (node, pixel) pairs for Mipmapped and Hybrid PBGI (paper Sections
// 5.2.1-5.2.2, Fig. 7) as compute passes with atomic append and indirect dispatch (the paper's
// geometry shader + transform feedback, rebuilt on compute; app/pbgi/mipmapped.py says why).
//
// A pair is uvec2 (BSH node A, G-buffer pyramid pixel P). Pending pairs live on a bounded stack;
// one pass pops the top K and processes each popped pair in one invocation:
//   * cull (paper eqs. 6-8, cone vs cone, made to hold for every receiver below P): P's normal
//     cone (axis n, half-angle gamma) and position sphere (c, R) against A's sphere: the
//     directions from any receiver below P into A lie within beta = asin((r_A + R) / d) of
//     w = c_A - c. Drop the pair when A is below every receiver's horizon,
//     angle(n, w) - beta > gamma + pi/2 (eq. 8), or back-facing for every one of them,
//     angle(-w, n_A) > alpha_A + beta + pi/2 (Fig. 5). A coarse cull implies Classic's culls of
//     A (and of its sub-tree) for each receiver below, so it never changes the cut.
//   * a leaf, or a node every receiver below P accepts in one step (Omega(A) from P's nearest
//     point within the straddling threshold), goes to the second stream: an *item* on P's
//     list, finished (here: accepted or culled) by the per-receiver walk (pbgi_finish.glsl);
//   * Hybrid (u_omega_tr > 0): so does a pair whose node is small, Omega(A) <= Omega_tr, or
//     whose pixel is at level 0: the walk finishes its sub-tree per receiver;
//   * visit the children [left(A), P], [right(A), P] when every receiver below P would descend
//     into A in Classic (A is not a leaf and Omega(A) > Omega_stop even from the farthest point
//     of P's sphere; a receiver that would cull A culls A's children too: their spheres and
//     cones lie inside A's), so refining here never changes the cut, and A is larger
//     than P's normal-cone solid angle 2 pi (1 - cos gamma) (the paper's rule, Fig. 7a: a pixel
//     with spread normals is split early so its children can cull);
//   * otherwise go to P's 1-4 child pixels [A, P_k] (Fig. 7b);
//   * at level 0 (P is one receiver) apply Classic's decision for that receiver
//     (lib/pbgi_cut.glsl): discard, descend into the children, or accept: the accepted node is
//     rasterised by the finishing pass (Fig. 7's third case; Mipmapped only).
// Bounds: PREPARE pops K <= (capacity - count) / 4 pairs, so the <= 4 outputs of every popped
// pair always fit, and K <= the second stream's free items, so its <= 1 item always fits too;
// when no children fit (K would be 0), the pass runs with children disabled and every pair goes
// to the second stream instead (one item each). The host runs the finishing pass, which empties
// the second stream, when it is half full or the stack is empty. (An item that still finds the
// stream full is pushed back onto the stack, into a popped slot: never lost.)
// Stages (one file, selected by a define): PREPARE (1 invocation), REFINE (indirect, K),
// FIXUP (1 invocation), MOVE (indirect): FIXUP fills the hole left by the popped pairs with the
// newest outputs so the stack stays contiguous.
#include "lib/common.glsl"
#include "lib/principled.glsl"
#include "lib/bsh_textures.glsl"
#include "lib/microbuffer.glsl"
#include "gen/receivers.glsl"
#include "gen/mip.glsl"
#include "lib/pbgi_cut.glsl"
#include "gen/pair_streams.glsl"

// counters[]: PAIR_COUNTERS (app/pbgi/gpu_layout.py), indexed by the generated C_* words
layout(std430, binding = SSBO_COUNTERS) buffer Counters { uint counters[]; };

#if defined(STAGE_PREPARE) || defined(STAGE_FIXUP)
layout(local_size_x = 1) in;
#else
layout(local_size_x = WORKGROUP_SIZE) in;
#endif

#ifdef STAGE_REFINE
uniform uint u_first;           // first receiver of the batch
uniform int u_m;                // micro-buffer size M
uniform float u_omega_stop;     // 4 * 2 pi / M^2
uniform float u_omega_horizon;  // Classic's threshold for nodes straddling the horizon
uniform float u_omega_tr;       // Hybrid: Omega_tr = factor * 2 pi / M^2; 0 = Mipmapped
uniform float u_pixel_factor;   // refine the node while Omega(A) > factor * Omega(P) (paper: 1)
uniform float u_cull_margin;    // radians: coarse culls must clear the test by this much

float solid_angle(float r, float d) {     // eq. 4, stable; +inf when d <= r
    if (d <= r) return 1e30;
    float s = (r * r) / (d * d);
    return TWO_PI * s / (1.0 + sqrt(max(1.0 - s, 0.0)));
}

float angle_between(vec3 a, vec3 b) { return atan(length(cross(a, b)), dot(a, b)); }

void push_pairs(uint a0, uint p0, uint a1, uint p1, uint n) {
    uint slot = atomicAdd(counters[C_STACK], n);
    pair_store(slot, a0, p0);
    if (n > 1u) pair_store(slot + 1u, a1, p1);
}

void to_second_stream(uint A, uint P) {
    uint idx = atomicAdd(counters[C_S2], 1u);
    if (idx < counters[C_S2_CAP]) {
        uint prev = imageAtomicExchange(heads_img, mip_texel(P), idx);
        item_store(idx, Item(A, prev, P, tnode_link(A).skip));
        atomicAdd(counters[C_TO_S2], 1u);
    } else {                                  // stream full: back on the stack, retried later
        uint slot = atomicAdd(counters[C_STACK], 1u);
        pair_store(slot, A, P);
        atomicAdd(counters[C_PUSHED_BACK], 1u);
    }
}
#endif

void main() {
#ifdef STAGE_PREPARE
    uint count = counters[C_STACK];
    uint cap = counters[C_CAP];
    uint s2 = counters[C_S2], s2_cap = counters[C_S2_CAP];
    uint k = min(count, counters[C_KMAX]);
    k = min(k, s2 < s2_cap ? s2_cap - s2 : 0u);   // every popped pair fits the second stream
    uint room = count < cap ? (cap - count) / 4u : 0u;
    uint allowed = 1u;
    if (room == 0u) { allowed = 0u; counters[C_DISABLED_PASSES] += (k > 0u ? 1u : 0u); }
    else k = min(k, room);
    counters[C_BASE] = count - k;
    counters[C_K] = k;
    counters[C_REFINE_ARGS] = (k + uint(WORKGROUP_SIZE) - 1u) / uint(WORKGROUP_SIZE);
    counters[C_REFINE_ARGS + 1] = 1u;
    counters[C_REFINE_ARGS + 2] = 1u;
    counters[C_ALLOWED] = allowed;
    counters[C_PROCESSED] += k;
    counters[C_PASSES] += (k > 0u ? 1u : 0u);
#endif

#ifdef STAGE_FIXUP
    uint base = counters[C_BASE], k = counters[C_K], total = counters[C_STACK];
    uint n_out = total - (base + k);
    uint moved = min(k, n_out);
    counters[C_PEAK_STACK] = max(counters[C_PEAK_STACK], total);
    counters[C_MOVE_SRC] = total - moved;
    counters[C_MOVE_N] = moved;
    counters[C_MOVE_ARGS] = (moved + uint(WORKGROUP_SIZE) - 1u) / uint(WORKGROUP_SIZE);
    counters[C_MOVE_ARGS + 1] = 1u;
    counters[C_MOVE_ARGS + 2] = 1u;
    counters[C_STACK] = base + n_out;
#endif

#ifdef STAGE_MOVE
    uint j = gl_GlobalInvocationID.x;
    if (j >= counters[C_MOVE_N]) return;
    Pair pr = pair_load(counters[C_MOVE_SRC] + j);
    pair_store(counters[C_BASE] + j, pr.node, pr.pixel);
#endif

#ifdef STAGE_REFINE
    uint j = gl_GlobalInvocationID.x;
    if (j >= counters[C_K]) return;
    bool allowed = counters[C_ALLOWED] != 0u;
    Pair pr = pair_load(counters[C_BASE] + j);
    uint A = pr.node, P = pr.pixel;
    MipLink L = mip_link(P);
    bool hybrid = u_omega_tr > 0.0;

    if (L.count == 0u) {                     // level 0: one receiver, Classic's decision
        uint rid = u_first + L.first;
        vec3 p = receiver_position(rid);
        vec3 N = receiver_normal(rid);
        vec3 T, B;
        mb_frame(N, receiver_pixel(rid), T, B);
        uvec4 rect;
        uint skip;
        uint dec = cut_decide(A, p, N, T, B, u_omega_stop, u_omega_horizon, u_m, rect, skip);
        if (dec == CUT_SKIP) { atomicAdd(counters[C_CULLED], 1u); return; }
        if (hybrid || dec == CUT_ACCEPT || !allowed) {
            if (dec == CUT_ACCEPT) atomicAdd(counters[C_ACCEPTED], 1u);
            to_second_stream(A, P);
            return;
        }
        uint left = A + 1u;
        push_pairs(left, P, tnode_link(left).skip, P, 2u);
        atomicAdd(counters[C_NODE_REFINES], 1u);
        return;
    }

    MipSphere ps = mip_sphere(P);
    MipCone pc = mip_cone(P);
    BshSphere s = tnode_sphere(A);
    bool leaf = (tnode_link(A).count_flags & BSH_TEX_LEAF_BIT) != 0u;
    vec3 w = s.center - ps.center;
    float d = length(w);
    float R = ps.radius;
    bool above_all = false;                  // A entirely above every receiver's horizon
    if (d > s.radius + R) {                       // eqs. 6-8 and Fig. 5 for every receiver below P
        float beta = asin(min((s.radius + R) / d, 1.0));
        float phi = angle_between(pc.axis, w);
        above_all = phi + beta + pc.angle + u_cull_margin < 0.5 * PI;
        if (phi - beta > pc.angle + 0.5 * PI + u_cull_margin) {
            atomicAdd(counters[C_CULLED], 1u);
            return;
        }
        BshCone cone = tnode_cone(A);
        float alpha = acos(clamp(cone.cos_angle, -1.0, 1.0));
        if (alpha + beta + 0.5 * PI + u_cull_margin < PI
                && angle_between(-w, cone.axis) > alpha + beta + 0.5 * PI + u_cull_margin) {
            atomicAdd(counters[C_CULLED], 1u);
            return;
        }
    }
    float omega_c = solid_angle(s.radius, d);
    // Every receiver below P decides A in one step (a leaf, or small enough from P's nearest
    // point - with the straddling threshold unless A is above every receiver's horizon): the
    // refinement is done, the finishing walk accepts (or culls) A per receiver. Hybrid also
    // stops at Omega_tr.
    float limit = above_all ? u_omega_stop : u_omega_horizon;
    bool decided_all = leaf || (d - R > s.radius && solid_angle(s.radius, d - R) <= limit);
    if (decided_all || (hybrid && omega_c <= u_omega_tr)) {
        if (decided_all) atomicAdd(counters[C_ACCEPTED], 1u);
        to_second_stream(A, P);
        return;
    }
    bool descend_all = !leaf && solid_angle(s.radius, d + R) > u_omega_stop;
    float omega_p = TWO_PI * (1.0 - cos(pc.angle));
    if (!allowed) {
        to_second_stream(A, P);
    } else if (descend_all && omega_c > u_pixel_factor * omega_p) {
        uint left = A + 1u;
        push_pairs(left, P, tnode_link(left).skip, P, 2u);
        atomicAdd(counters[C_NODE_REFINES], 1u);
    } else {
        uint n = L.count;
        uint slot = atomicAdd(counters[C_STACK], n);
        for (uint k = 0u; k < n; ++k) pair_store(slot + k, A, L.first + k);
        atomicAdd(counters[C_PIXEL_SPLITS], 1u);
    }
#endif
}
