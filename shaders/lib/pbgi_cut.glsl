// Classic PBGI's per-receiver rules (paper Section 5.2 with Section 5.3's corrections), shared by
// every depth-first walk: Classic's whole-tree walk and the Mipmapped/Hybrid finishing walks of
// sub-trees. One source for the decision and the rasteriser, so the three modes can only differ
// in how they reach the cut, never in what the cut is or how it is drawn.
//
// Per node A at distance d, radius r, seen from receiver p with normal n:
//   * below the horizon (dot(c - p, n) <= -r): discard the subtree;
//   * a flat leaf (a disc) whose plane the receiver is on or behind: discard;
//   * back-facing (Fig. 5, made conservative for the sphere's angular radius b = asin(r / d)):
//     discard when every direction from p into the sphere meets only back faces of the normal
//     cone, i.e. angle(-w, n_A) > alpha_A + b + pi/2  <=>  dot(w, n_A) > sin(alpha_A + b);
//   * solid angle (eq. 4) 2 pi (1 - sqrt(d^2 - r^2) / d), computed as 2 pi s / (1 + sqrt(1 - s))
//     with s = r^2 / d^2 (no cancellation, and no sqrt of a negative); a receiver inside the
//     sphere (d <= r) sees it everywhere: descend, or rasterise a leaf into every micro-pixel;
//   * accept when Omega(A) <= omega_stop (= 4 Omega, Section 5.3) - capped at omega_horizon
//     for a node straddling the horizon (app/pbgi/microbuffer.py: omega_horizon, at most
//     2 pi / 64), so nodes cut by the horizon are small where the rim bands are coarse (the
//     rasteriser only ever uses directions above the horizon, and rim micro-pixels are split
//     into elevation bands, so a straddling node cannot smear light from below the horizon over
//     a wide edge micro-pixel) - or when A is a leaf; else descend.
//
// Needs: lib/bsh_textures.glsl, lib/microbuffer.glsl. CUT_LIST_CAP sizes the accepted list.
#ifndef SCANLIGHT_PBGI_CUT_GLSL
#define SCANLIGHT_PBGI_CUT_GLSL

#define FLAT_LEAF_SIN 0.01             // sin of the cone half-angle below which a leaf is flat
#define CUT_DESCEND 0u
#define CUT_SKIP 1u
#define CUT_ACCEPT 2u

#ifndef CUT_LIST_CAP
#define CUT_LIST_CAP 64
#endif

// The asset's surfels in a joined tree (app/pbgi/scene_tree.py, NodeTextures.set_uniforms):
// nodes from u_asset_first on, each surfel standing for u_surfel_area (0: no asset).
uniform uint u_asset_first;
uniform float u_surfel_area;
bool cut_is_asset(uint node) { return u_surfel_area > 0.0 && node >= u_asset_first; }
#ifndef CUT_TILE_COVER
#define CUT_TILE_COVER 1.9635         // 5 pi / 8: see cut_node
#endif

// Paper Fig. 5: does every point of a node seen in direction l (unit) within angle b (sin_b,
// cos_b) face away from the receiver? Its normals lie within the cone's half-angle alpha of the
// axis, so all of them do when the angle between -l and the axis exceeds alpha + b.
bool cut_back_facing(BshCone cone, vec3 l, float sin_b, float cos_b) {
    float sin_a = sqrt(max(1.0 - cone.cos_angle * cone.cos_angle, 0.0));
    float cos_ab = cone.cos_angle * cos_b - sin_a * sin_b;     // cos(alpha + b)
    float sin_ab = sin_a * cos_b + cone.cos_angle * sin_b;     // sin(alpha + b)
    return cos_ab > 0.0 && dot(l, cone.axis) > sin_ab;
}

// Decision for node A seen from receiver (p, N) with micro-buffer frame (T, B, N); ``rect`` is
// the micro-pixel rectangle to rasterise when the answer is CUT_ACCEPT, ``skip`` the node after
// A's sub-tree.
uint cut_decide(uint node, vec3 p, vec3 N, vec3 T, vec3 B, float omega_stop,
                float omega_horizon, int m, out uvec4 rect, out uint skip) {
    BshSphere s = tnode_sphere(node);
    BshLink link = tnode_link(node);
    vec3 dv = s.center - p;
    float d2 = dot(dv, dv);
    float r2 = s.radius * s.radius;
    float h = dot(dv, N);
    bool leaf = (link.count_flags & BSH_TEX_LEAF_BIT) != 0u;
    skip = link.skip;
    rect = uvec4(0u, 0u, uint(m - 1), uint(m - 1));
    if (h <= -s.radius) return CUT_SKIP;            // entirely below the horizon
    BshCone cone = tnode_cone(node);
    // A flat leaf (normal cone below FLAT_LEAF_SIN: one point, or coplanar ones) is a disc in
    // the plane through its centre normal to its axis: a receiver on or behind that plane sees
    // only its back (the per-ray test would reject every ray but those within the cone's angle
    // of the plane, whose cosine weight is ~0). This keeps the neighbouring surfels of an asset's
    // convex surface - near, hence large - out of its own receivers' walk and rasteriser.
    float sin_a = sqrt(max(1.0 - cone.cos_angle * cone.cos_angle, 0.0));
    if (leaf && sin_a < FLAT_LEAF_SIN && dot(dv, cone.axis) >= -sqrt(d2) * sin_a)
        return CUT_SKIP;
    if (d2 > r2) {
        float inv_d = inversesqrt(d2);
        float sin_b = s.radius * inv_d;
        float sin_b2 = sin_b * sin_b;
        float cos_b = sqrt(max(1.0 - sin_b2, 0.0));
        if (cut_back_facing(cone, dv * inv_d, sin_b, cos_b)) return CUT_SKIP;
        float omega = TWO_PI * sin_b2 / (1.0 + cos_b);
        float limit = abs(h) < s.radius ? omega_horizon : omega_stop;
        if (leaf || omega <= limit) {
            vec3 l = vec3(dot(dv, T), dot(dv, B), h) * inv_d;
            rect = mb_cone_rect(l, sin_b, cos_b, m);
            return CUT_ACCEPT;
        }
        return CUT_DESCEND;
    }
    return leaf ? CUT_ACCEPT : CUT_DESCEND;   // receiver inside: a leaf surrounds it
}

// The accepted nodes of one slice of a walk and their micro-pixel rectangles (packed).
uint cut_list_node[CUT_LIST_CAP];
uint cut_list_rect[CUT_LIST_CAP];

// Appends an accepted node and its rectangle to the list; false (nothing appended) when the list
// is full or the slice's entry-test budget would overflow - the walk stops and resumes there.
bool cut_list_push(uint node, uvec4 rect, inout uint count, inout uint cost, uint budget) {
    uint c = mb_rect_entries(rect);
    if (count == uint(CUT_LIST_CAP) || (count > 0u && cost + c > budget)) return false;
    cut_list_node[count] = node;
    cut_list_rect[count] = mb_pack_rect(rect);
    count++;
    cost += c;
    return true;
}

// Depth-tested write with a deterministic tie-break: equal keys keep the lower node index, which
// is what a depth-first walk (nodes in index order) gets with a strict test, whatever order the
// nodes arrive in. A walk whose nodes do arrive in index order (Classic's whole-tree walk)
// defines CUT_ORDERED_WRITES and keeps the cheaper strict test (mb_write): the same result.
void cut_write(uint receiver, uint k, uint key, uint node) {
#ifdef CUT_ORDERED_WRITES
    mb_write(receiver, k, key, node);
#else
    ivec2 c = ivec2(int(k), int(receiver));
    MbEntry e = mb_entry_at(c);
    if (key < e.key || (key == e.key && node < e.node)) mb_entry_store(c, MbEntry(key, node));
#endif
}

// What the per-micro-pixel test needs about list entry k.
//
// An accepted inner node of the asset is ray tested against a sphere of its surface's
// *projected area*, not its bounding sphere: the room surrounds a receiver, so a bounding sphere
// too big only moves the depth test's boundary between room clusters, but the asset stands in
// front of the room and a cluster's bounding sphere (twice or more its surface's silhouette for
// a face of a box or a cap of a sphere) would hide room light its surface does not. A cap of
// half-angle alpha (the normal cone) of area A shows pi r^2 = A (1 + cos alpha) / 2 along its
// axis (a flat patch: A; a hemisphere: A / 2), at least A / 4 (a closed surface), times
// CUT_TILE_COVER = 5 pi / 8: neighbouring clusters tile a face as rectangles, not discs, and
// discs of their exact area leave the corners open (9% of a flat face: light leaks through the
// asset). pi / 2 (a square's circumcircle) still left the 2:1 rectangles that every other level
// of a binary tree makes of a flat face open: the blocks' cube tops, which mirror the plate
// behind them, were 1.3-1.6x too bright; 5 pi / 8 is a 2:1 rectangle's circumcircle (blocks,
// 4x4 error against Mitsuba, Classic: rough metal 8.3 -> 6.3% apartment, 7.2 -> 7.1% city;
// diffuse 3.5 -> 2.7%, 4.6 -> 4.6%). The closed form of a sphere occluding the furnace
// (tests/pbgi/test_asset_scene.py) still holds at M = 24 within its limits. r never grows
// beyond the bounding radius, so surfel leaves stay their own discs.
// cut_node_of: the same from the node's records already fetched (pbgi_lobe.glsl).
MbNode cut_node_of(uint a, BshSphere s, BshCone cone, BshLink link, vec3 p, float inv_cell_area) {
    uint points = max(link.count_flags & BSH_TEX_COUNT_MASK, 1u);
    MbNode nd;
    nd.dv = s.center - p;
    nd.d2 = dot(nd.dv, nd.dv);
    nd.r2 = s.radius * s.radius;
    if (cut_is_asset(a)) {
        float shown = max(0.5 * (1.0 + cone.cos_angle), 0.25);
        nd.r2 = min(nd.r2, float(points) * u_surfel_area * shown * (CUT_TILE_COVER * INV_PI));
    }
    nd.axis = cone.axis;
    nd.sin_a = cone.cos_angle > 0.0 ? sqrt(max(1.0 - cone.cos_angle * cone.cos_angle, 0.0)) : 1.0;
    nd.inv_area = inv_cell_area / float(points);
    nd.index = a;
    return nd;
}

MbNode cut_node(uint a, vec3 p, float inv_cell_area) {
    return cut_node_of(a, tnode_sphere(a), tnode_cone(a), tnode_link(a), p, inv_cell_area);
}

// One rasteriser step: node nd against micro-buffer entry kk of a receiver with frame (T, B, N).
void cut_test_entry(MbNode nd, uint kk, vec3 T, vec3 B, vec3 N, uint receiver) {
    MbDirection e = mb_table(kk);
    if (e.weight > 0.0) {
        uint key = mb_hit_key(nd, T * e.dir.x + B * e.dir.y + N * e.dir.z);
        if (key != MB_EMPTY) cut_write(receiver, kk, key, nd.index);
    }
}

// The cap of node a's raster (lib/microbuffer.glsl: mb_cap) - of the sphere the per-entry test
// uses (cut_node), so the spans hold every entry the test can hit.
MbCap cut_cap(MbNode nd, vec3 T, vec3 B, vec3 N) { return mb_cap(nd.dv, nd.d2, nd.r2, T, B, N); }

// Rasterise cut_list_node[0 .. count) (at most the budgeted mb_rect_entries of each rectangle;
// the cap's row spans take fewer) into the micro-buffer of batch receiver ``receiver``, node by
// node: the node's set-up (its record, its cap) runs once per node. A flat loop over (node,
// entry) pairs would keep SIMD lanes that rasterise different nodes busy, but carries the
// set-up, masked, through nearly every iteration (some lane of 8 starts a node in most of
// them), and the cap makes that set-up dear. Returns the iterations done; ``k_out`` = the first
// node not finished (count when all are done: anything less means the driver cut the loop
// short).
// CUT_WALK_ONLY (app/pbgi/gpu_layout.py: WALK_ONLY, `bench profile`): no node is rasterised, so
// a render times its walks alone and the profile can tell the walk from the rasterisation
// (the micro-buffers stay empty: the image of such a render means nothing).
uint cut_raster(uint count, vec3 p, vec3 N, vec3 T, vec3 B, uint receiver, int m,
                float inv_cell_area, out uint k_out) {
    uint it = 0u;
    uint k;
#ifdef CUT_WALK_ONLY
    k_out = count;
    return it;
#endif
    for (k = 0u; k < count; ++k) {
        MbNode nd = cut_node(cut_list_node[k], p, inv_cell_area);
        uvec4 rect = mb_unpack_rect(cut_list_rect[k]);
        MbCap cap = cut_cap(nd, T, B, N);
        MbCursor cur = mb_cursor(rect, cap, m);
        bool more = true;
        uint j = 0u;
        for (; more; ++j) {
            cut_test_entry(nd, mb_cursor_entry(cur, m), T, B, N, receiver);
            more = mb_cursor_next(cur, rect, cap, m);
        }
        it += j;
        if (more) break;                // the driver cut the inner loop short
    }
    k_out = k;
    return it;
}
#endif
