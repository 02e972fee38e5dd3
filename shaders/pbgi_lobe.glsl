// The lobe micro-buffer's walk (lib/lobe.glsl, app/pbgi/lobe.py): per glossy receiver, a
// depth-first stackless walk of the whole BSH with Classic's culls (horizon, back-facing normal
// cones) plus the lobe's own: a node whose half-vector cone lies outside the lobe's domain is
// skipped with its sub-tree. A node is accepted when its solid angle is at most u_stop_factor
// times the smallest lobe micro-pixel it covers (a narrow lobe descends to the leaves near the
// reflection and stays coarse away from it), or when it is a leaf; accepted nodes are ray cast
// through every micro-pixel of their ring x sector rectangle (mb_hit_key: the ray against the
// node's disc, a leaf's grown by the scan's point spacing, so a leaf larger than a micro-pixel is
// a closed surface, not one dot), depth
// tested. The same walk serves every mode (Classic, Mipmapped, Hybrid): only the cosine
// micro-buffer differs between them.
//
// Resumable like pbgi_classic.glsl (llvmpipe ends every loop of an invocation after 65,535
// iterations in total): state[i] is a ClassicState; a receiver that needs no lobe buffer is done
// at once.
//
// LOBE_ACCEPTED_TABLE 1 (app/pbgi/lobe.py: LobeWalkTuning, llvmpipe's): llvmpipe runs the code
// of every branch of a loop's body on every iteration, taken or not, so work that only some
// iterations need is moved out of the loops that would pay it on all of them:
// - the walk decides on a node's rings alone (lobe_rect_rings: the smallest micro-pixel it
//   covers, and whether it is in the domain); the sectors of its rectangle, and an accepted inner
//   node's second rectangle (of its own sphere), are computed once per accepted node in a loop of
//   their own, which also drops a node whose own sphere misses the domain;
// - that loop also prepares each accepted node's ray-cast record (cut_node) into a table, so the
//   flat ray-cast loop reads it instead of fetching and deriving it on every micro-pixel;
// - the receiver's row of the lobe buffer is kept in the invocation's memory while it is ray cast
//   and stored once at the end, instead of an image load (and store) per hit.
// The micro-buffers, the walk's visits and its ray tests are the same as with 0, which a GPU
// takes (there every branch costs only where taken, and these tables are spilled local memory):
// tests/pbgi/test_lobe_tuning.py.
#define LOBE_BUFFER 1
#include "lib/common.glsl"
#include "lib/principled.glsl"
#include "lib/bsh_textures.glsl"
#include "lib/microbuffer.glsl"
#include "lib/lobe.glsl"
#include "lib/lobe_size.glsl"
#include "gen/receivers.glsl"
#include "gen/materials.glsl"
#include "gen/walk_state.glsl"
#include "lib/receiver_shading.glsl"

#ifndef LIST_CAP
#define LIST_CAP 256
#endif
#define CUT_LIST_CAP LIST_CAP
#include "lib/pbgi_cut.glsl"

layout(local_size_x = WORKGROUP_SIZE) in;

layout(std430, binding = SSBO_WALK_STATE) buffer State { ClassicState state[]; };
layout(std430, binding = SSBO_COUNTERS) buffer Counter { uint remaining; };

uniform uint u_first;           // first receiver of the batch
uniform uint u_count;           // receivers in the batch
uniform uint u_rings;           // lobe micro-buffer: rings ...
uniform uint u_sectors;         // ... x sectors
uniform uint u_pass;            // jitter pass
uniform float u_glossy_below;   // roughness below which the GGX lobe is in the lobe buffer
uniform float u_stop_factor;    // accept a node of solid angle <= this x the micro-pixel's
uniform uint u_steps;           // node visits per dispatch
uniform uint u_splat_budget;    // ray tests per dispatch
uniform float u_inv_cell_area;  // 1 / cell_size^2 (tie-break scale)
uniform uint u_node_count;      // BSH_END
uniform vec3 u_camera;          // camera position relative to the hierarchy origin
uniform float u_leaf_radius;    // a leaf is a disc of at least this radius (the scan's surface)

// LOBE_RAY_TABLE 1: every micro-pixel's ray and solid angle (lobe_cell: two hashes and the
// warp's trigonometry) once per receiver and dispatch, not once per node that covers it: a
// micro-pixel is ray cast against ~10-30 accepted nodes. A CPU rasteriser keeps that table in the
// invocation's stack; on a GPU it is local memory, dearer than the trigonometry it saves, and
// LOBE_RAY_TABLE 0 computes each ray where it is cast (app/pbgi/lobe.py: LobeWalkTuning).
// LOBE_CELLS = rings x sectors: app/pbgi/lobe.py compiles one program per size (the defaults
// here only let the file build on its own).
#ifndef LOBE_CELLS
#define LOBE_CELLS 64
#endif
#ifndef LOBE_RAY_TABLE
#define LOBE_RAY_TABLE 1
#endif
#if LOBE_RAY_TABLE
vec4 lobe_rays[LOBE_CELLS];
#endif
#ifndef LOBE_ACCEPTED_TABLE
#define LOBE_ACCEPTED_TABLE 1
#endif
#if LOBE_ACCEPTED_TABLE
vec4 accepted_sphere[CUT_LIST_CAP];   // MbNode: dv, r2 (a leaf's grown by u_leaf_radius)
vec4 accepted_cone[CUT_LIST_CAP];     // MbNode: axis, sin_a
float accepted_inv_area[CUT_LIST_CAP];
uint row_key[LOBE_CELLS];             // the receiver's row while it is ray cast
uint row_node[LOBE_CELLS];
#endif

vec4 lobe_ray(LobeFrame F, uint cell) {
#if LOBE_RAY_TABLE
    return lobe_rays[cell];
#else
    vec3 L;
    float omega;
    lobe_cell(F, cell, L, omega);
    return vec4(L, omega);
#endif
}

void lobe_write(uint receiver, uint k, uint key, uint node) {
#if LOBE_ACCEPTED_TABLE
    if (key < row_key[k]) {
        row_key[k] = key;
        row_node[k] = node;
    }
#else
    ivec2 c = ivec2(int(k), int(receiver));
    if (key < lobe_entry_at(c).key) lobe_entry_store(c, MbEntry(key, node));
#endif
}

// Node a's ray-cast record from p: cut_node's, a room leaf's disc grown by u_leaf_radius (the
// scan's surface, as the walk's culls had it; the asset's surfels are discs already).
MbNode lobe_cast_node(uint a, BshSphere s, BshCone cone, BshLink link, vec3 p) {
    MbNode nd = cut_node_of(a, s, cone, link, p, u_inv_cell_area);
    if ((link.count_flags & BSH_TEX_LEAF_BIT) != 0u && !cut_is_asset(a)) {
        float r = sqrt(nd.r2) + u_leaf_radius;
        nd.r2 = r * r;
    }
    return nd;
}

// Accepted node ``a`` (a leaf: its sphere grown by u_leaf_radius) as seen from p: its rectangle
// of micro-pixels (0xFFFFFFFF: outside the domain) and its ray-cast record. The same figures as
// the walk's own (LOBE_ACCEPTED_TABLE 0), expression for expression; one lobe_rect for both kinds
// of node and one fetch of each record (llvmpipe would run a call in each branch).
uint accepted_rect(LobeFrame F, uint a, vec3 p, out MbNode nd) {
    BshSphere s = tnode_sphere(a);
    BshLink link = tnode_link(a);
    nd = lobe_cast_node(a, s, tnode_cone(a), link, p);
    bool leaf = (link.count_flags & BSH_TEX_LEAF_BIT) != 0u;
    float grow = cut_is_asset(a) ? 0.0 : u_leaf_radius;
    float r = s.radius + grow;
    if (!leaf) r -= grow;                                  // (the walk's own_r, rounding too)
    vec3 dv = s.center - p;
    float d2 = dot(dv, dv);
    float inv_d = inversesqrt(d2);
    float sin_b, cos_b;
    if (leaf) {                                            // as the walk's culls had it
        sin_b = r * inv_d;
        cos_b = sqrt(max(1.0 - sin_b * sin_b, 0.0));
    } else {                                               // its own sphere, as its acceptance
        float sin_o2 = min(r * r / d2, 1.0);
        sin_b = sqrt(sin_o2);
        cos_b = sqrt(1.0 - sin_o2);
    }
    float om;
    uint rect = lobe_rect(F, dv * inv_d, sin_b, cos_b, om);
    return (leaf && d2 <= r * r) ? (F.rings - 1u) << 8u | (F.sectors << 24u)   // inside it
                                 : rect;
}

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
    PrincipledPrepared Q = receiver_prepared(rid, p, N, u_camera);
    bvec2 terms = lobe_terms(Q, u_glossy_below);
    if (!any(terms) || Q.n_dot_v <= 0.0) {
        state[i] = ClassicState(end, st.visited, st.flags | WALK_DONE, st.tests);
        return;
    }
    uvec2 size = lobe_size(Q, terms, u_glossy_below, u_rings, u_sectors);
    LobeFrame F = lobe_frame_for(Q, terms, lobe_seed_pixel(receiver_pixel(rid)), u_pass, size.x,
                                  size.y);
    LobeCone K = lobe_cone(F);
#if LOBE_RAY_TABLE
    uint cells_used = size.x * size.y;
    for (uint c = 0u; c < uint(LOBE_CELLS); ++c) {
        if (c == cells_used) break;
        vec3 L;
        float omega;
        lobe_cell(F, c, L, omega);
        lobe_rays[c] = vec4(L, omega);
    }
#endif

    uint count = 0u, cost = 0u, steps = 0u;
    while (node < end && steps < u_steps) {
        BshSphere s = tnode_sphere(node);
        BshLink link = tnode_link(node);
        bool leaf = (link.count_flags & BSH_TEX_LEAF_BIT) != 0u;
        // Every point is a disc of u_leaf_radius (the scan's surface), so a leaf - a cluster of
        // points - is ray cast as a disc of its sphere's radius + u_leaf_radius, and the culls of
        // an inner node bound its points' discs the same way; with the sphere alone a narrow
        // lobe loses the disc edges that stick out of it: holes in a mirror. The cut's
        // acceptance compares an inner node's own sphere.
        float grow = cut_is_asset(node) ? 0.0 : u_leaf_radius;   // surfels: discs already
        s.radius += grow;
        float own_r = leaf ? s.radius : s.radius - grow;
        vec3 dv = s.center - p;
        float d2 = dot(dv, dv);
        float r2 = s.radius * s.radius;
        uint next = node + 1u;
        uint rect = 0xFFFFFFFFu;
        bool accept = false;
        if (dot(dv, N) <= -s.radius) {
            next = link.skip;                              // below the horizon
        } else if (d2 > r2) {
            float inv_d = inversesqrt(d2);
            float sin_b = s.radius * inv_d;
            float sin_b2 = sin_b * sin_b;
            float cos_b = sqrt(max(1.0 - sin_b2, 0.0));
            float om_min;
            if (lobe_cone_outside(K, dv * inv_d, sin_b, cos_b)
                    || cut_back_facing(tnode_cone(node), dv * inv_d, sin_b, cos_b)) {
                next = link.skip;           // outside the lobe's cone, or back-facing (Fig. 5)
            } else {
#if LOBE_ACCEPTED_TABLE
                rect = lobe_rect_rings(F, dv * inv_d, sin_b, cos_b, om_min);   // every sector
#else
                rect = lobe_rect(F, dv * inv_d, sin_b, cos_b, om_min);
#endif
                if (rect == 0xFFFFFFFFu) {
                    next = link.skip;                      // outside the lobe's domain
                } else {
                    float sin_o2 = min(own_r * own_r / d2, 1.0);
                    float omega = TWO_PI * sin_o2 / (1.0 + sqrt(1.0 - sin_o2));
                    accept = leaf || omega <= u_stop_factor * om_min;
#if !LOBE_ACCEPTED_TABLE
                    if (accept && !leaf) {                 // drawn as its own sphere
                        float sin_o = sqrt(sin_o2), om;
                        rect = lobe_rect(F, dv * inv_d, sin_o, sqrt(1.0 - sin_o2), om);
                        if (rect == 0xFFFFFFFFu) { accept = false; next = link.skip; }
                    }
#endif
                }
            }
        } else if (leaf) {                                 // receiver inside a leaf
            accept = true;
            rect = (F.rings - 1u) << 8u | (F.sectors << 24u);
        }
        if (accept) {
            uint c = lobe_rect_cells(rect);
            if (count == uint(CUT_LIST_CAP) || (count > 0u && cost + c > u_splat_budget)) break;
            cut_list_node[count] = node;
            cut_list_rect[count] = rect;
            count++;
            cost += c;
            next = link.skip;
        }
        node = next;
        steps++;
    }

#if LOBE_ACCEPTED_TABLE
    // ---- the accepted nodes' rectangles and ray-cast records; the row ----------------------
    // (the walk's rectangles had every sector, so its budget check above was conservative)
    uint kept = 0u;
    cost = 0u;
    for (uint a = 0u; a < uint(CUT_LIST_CAP); ++a) {
        if (a == count) break;
        uint an = cut_list_node[a];
        MbNode rec;
        uint rc = accepted_rect(F, an, p, rec);
        if (rc != 0xFFFFFFFFu) {                           // (an inner node's own sphere may miss)
            cut_list_node[kept] = an;
            cut_list_rect[kept] = rc;
            accepted_sphere[kept] = vec4(rec.dv, rec.r2);
            accepted_cone[kept] = vec4(rec.axis, rec.sin_a);
            accepted_inv_area[kept] = rec.inv_area;
            cost += lobe_rect_cells(rc);
            kept++;
        }
    }
    count = kept;
    uint row_cells = size.x * size.y;
    for (uint c = 0u; c < uint(LOBE_CELLS); ++c) {
        if (c == row_cells) break;
        MbEntry e = lobe_entry_at(ivec2(int(c), int(i)));
        row_key[c] = e.key;
        row_node[c] = e.node;
    }
#endif
    // ---- ray cast the accepted nodes through their micro-pixels: one flat loop --------------
    uint k = 0u, n = 0u, it;
    MbNode nd;
    uint rect = 0u, cells = 0u;
    LobeCursor cur;
    bool load = true;
#ifdef CUT_WALK_ONLY
    it = cost;                          // the walk alone (lib/pbgi_cut.glsl: cut_raster)
    k = count;
#else
    for (it = 0u; it < cost; ++it) {
        if (load) {
#if LOBE_ACCEPTED_TABLE
            vec4 sph = accepted_sphere[k], cone = accepted_cone[k];
            nd = MbNode(sph.xyz, dot(sph.xyz, sph.xyz), sph.w, cone.xyz, cone.w,
                        accepted_inv_area[k], cut_list_node[k]);
#else
            uint a = cut_list_node[k];
            nd = lobe_cast_node(a, tnode_sphere(a), tnode_cone(a), tnode_link(a), p);
#endif
            rect = cut_list_rect[k];
            cells = lobe_rect_cells(rect);
            cur = lobe_cursor(F, rect);
            n = 0u;
            load = false;
        }
        uint cell = cur.cell;
        lobe_cursor_next(F, cur, rect);
        vec4 ray = lobe_ray(F, cell);
        if (ray.w > 0.0) {
            uint key = mb_hit_key(nd, ray.xyz);
            if (key != MB_EMPTY) lobe_write(i, cell, key, nd.index);
        }
        if (++n == cells) { k++; load = true; }
    }
#endif
#if LOBE_ACCEPTED_TABLE
    for (uint c = 0u; c < uint(LOBE_CELLS); ++c) {
        if (c == row_cells) break;
        lobe_entry_store(ivec2(int(c), int(i)), MbEntry(row_key[c], row_node[c]));
    }
#endif
    uint resume = (it == cost && k == count) ? node : cut_list_node[min(k, count - 1u)];
    if (count == 0u) resume = node;
    uint flags = (resume >= end ? WALK_DONE : 0u) | (it == cost ? 0u : WALK_CUT_SHORT);
#ifdef CUT_WALK_ONLY
    it = 0u;                            // nothing was ray cast
#endif
    state[i] = ClassicState(resume, st.visited + steps, st.flags | flags, st.tests + it);
    if (resume < end) atomicAdd(remaining, 1u);
}
