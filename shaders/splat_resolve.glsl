// The splats' screen-space passes (app/render/splat_fill.py: SplatFill runs them), one work item
// per pixel; image units and the work group come from gen/splat_resolve.glsl
// (app/render/gpu_layout.py). Pyramid texels are vec4(radiance, eye depth); depth 0 = empty.
// RESOLVE_PASS (injected):
//   0 NORMALISE: the sums (w c, w) and w z -> level 0 (sum w c / sum w, sum w z / sum w)
//   1 PULL:      level l -> level l+1: each coarse texel is the mean of its filled children that
//                lie within PULL_DEPTH_REL of the nearest one (the front surface; a hole never
//                mixes the wall behind a box into the box)
//   2 PUSH:      coarse level l+1 -> level l: an empty texel takes the bilinear mean of the filled
//                coarse texels around it (front surface again); at level 0 only a texel that is
//                enclosed, with a filled pixel within u_hole pixels in each of 8 directions, so
//                the room's outline against empty space never grows (max hole: u_hole pixels);
//                there a filled pixel enclosed by pixels nearer by SEE_THROUGH_REL (a farther
//                surface seen through a gap of the front one) is replaced the same way
//   3 FINISH:    level 0 less its guard band -> ROOM_TEXEL(radiance x eye-dome shade, 1 | 0);
//                u_edl = 0: shade 1.
// With u_pick (labels, e.g. the provenance view) pull and push take one texel instead of a mean.
// Every loop is bounded by a small constant (llvmpipe's per-invocation iteration budget).
#include "gen/splat_resolve.glsl"

#ifndef RESOLVE_PASS
#define RESOLVE_PASS 0
#endif
#ifndef PULL_DEPTH_REL
#define PULL_DEPTH_REL 0.1
#endif
#ifndef SEE_THROUGH_REL
#define SEE_THROUGH_REL 0.02
#endif
#ifndef MAX_HOLE_PX
#define MAX_HOLE_PX 16
#endif
#ifndef EDL_RESPONSE
#define EDL_RESPONSE 100.0
#endif

layout(local_size_x = SPLAT_TILE, local_size_y = SPLAT_TILE) in;
uniform ivec2 u_size;       // size of the level written

#if RESOLVE_PASS == 0
layout(rgba32f, binding = SPLAT_IMG_SRC) readonly uniform image2D u_accum;
layout(r32f, binding = SPLAT_IMG_AUX) readonly uniform image2D u_depth_sum;
#else
layout(rgba32f, binding = SPLAT_IMG_SRC) readonly uniform image2D u_src;   // PUSH: the coarse level
#endif
#if RESOLVE_PASS == 2
layout(rgba32f, binding = SPLAT_IMG_AUX) readonly uniform image2D u_fine;  // the level being filled
uniform int u_hole;         // level 0: the enclosure test's reach in pixels (> 0); coarser: 0
#endif
#if RESOLVE_PASS == 3
uniform ivec2 u_offset;     // the guard band: output pixel p is level-0 texel p + u_offset
uniform int u_edl;          // 1: eye-dome lighting
uniform float u_edl_radius; // neighbour distance in pixels
#endif
layout(rgba32f, binding = SPLAT_IMG_DST) writeonly uniform image2D u_dst;

uniform int u_pick;         // PULL, PUSH: 1 for labels (categorical colours), never a mix

// the mean of the texels with weight wt > 0 that are within PULL_DEPTH_REL of the nearest
// (u_pick: the one of them with the largest weight, the first on ties)
vec4 front_mean(vec4 t[4], float wt[4]) {
    float zmin = 1e30;
    for (int k = 0; k < 4; ++k) if (wt[k] > 0.0 && t[k].w > 0.0) zmin = min(zmin, t[k].w);
    if (zmin >= 1e30) return vec4(0.0);
    vec4 s = vec4(0.0), best = vec4(0.0);
    float ws = 0.0, wbest = 0.0;
    for (int k = 0; k < 4; ++k) {
        if (wt[k] > 0.0 && t[k].w > 0.0 && t[k].w <= zmin * (1.0 + PULL_DEPTH_REL)) {
            s += wt[k] * t[k];
            ws += wt[k];
            if (wt[k] > wbest) { best = t[k]; wbest = wt[k]; }
        }
    }
    return u_pick != 0 ? best : s / ws;
}

#if RESOLVE_PASS == 2
// Is p (eye depth z; 0: empty) open, surrounded by the front surface? Along at least 3 of the 4
// axes (horizontal, vertical, both diagonals) both directions must meet, within u_hole pixels,
// a filled pixel (p empty) or, p filled, one nearer than z by more than SEE_THROUGH_REL (p is a
// farther surface seen through a gap of the front one; on a plane, however slanted, half the
// directions are farther, so a plane's own pixels are never taken). One open axis is a crack of
// any length (a line of missing splats) and is filled; just outside the room's outline at least
// two axes are open, so the outline keeps its place.
bool enclosed(ivec2 p, float z) {
    const ivec2 dirs[8] = ivec2[8](ivec2(1, 0), ivec2(-1, 0), ivec2(0, 1), ivec2(0, -1),
                                   ivec2(1, 1), ivec2(-1, -1), ivec2(1, -1), ivec2(-1, 1));
    int closed_axes = 0;
    bool both = true;
    for (int d = 0; d < 8; ++d) {
        bool hit = false;
        for (int k = 1; k <= MAX_HOLE_PX; ++k) {
            if (k > u_hole) break;
            ivec2 q = p + k * dirs[d];
            if (any(lessThan(q, ivec2(0))) || any(greaterThanEqual(q, u_size))) break;
            float zq = imageLoad(u_fine, q).w;
            if (zq > 0.0 && (z <= 0.0 || zq * (1.0 + SEE_THROUGH_REL) < z)) { hit = true; break; }
        }
        both = both && hit;
        if ((d & 1) == 1) {                 // the axis' second direction: count, start the next
            closed_axes += both ? 1 : 0;
            both = true;
        }
    }
    return closed_axes >= 3;
}
#endif

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_size))) return;
#if RESOLVE_PASS == 0
    vec4 a = imageLoad(u_accum, p);
    float zs = imageLoad(u_depth_sum, p).r;
    imageStore(u_dst, p, a.w > 0.0 ? vec4(a.rgb / a.w, max(zs / a.w, 1e-30)) : vec4(0.0));
#elif RESOLVE_PASS == 1
    vec4 t[4];
    float wt[4];
    ivec2 src = imageSize(u_src);
    for (int k = 0; k < 4; ++k) {
        ivec2 q = 2 * p + ivec2(k & 1, k >> 1);
        bool inside = all(lessThan(q, src));
        t[k] = inside ? imageLoad(u_src, q) : vec4(0.0);
        wt[k] = inside ? 1.0 : 0.0;
    }
    imageStore(u_dst, p, front_mean(t, wt));
#elif RESOLVE_PASS == 2
    vec4 here = imageLoad(u_fine, p);
    // coarser levels fill every empty texel; level 0 (u_hole > 0) only enclosed ones, and
    // also replaces see-through pixels (enclosed by a nearer surface)
    if ((u_hole == 0 && here.w > 0.0) || (u_hole > 0 && !enclosed(p, here.w))) {
        imageStore(u_dst, p, here);
        return;
    }
    ivec2 coarse = imageSize(u_src);
    vec2 fc = (vec2(p) + 0.5) * 0.5 - 0.5;      // this texel's centre in coarse texels
    ivec2 b = ivec2(floor(fc));
    vec2 f = fc - vec2(b);
    vec4 t[4];
    float wt[4];
    for (int k = 0; k < 4; ++k) {
        ivec2 o = ivec2(k & 1, k >> 1);
        ivec2 q = clamp(b + o, ivec2(0), coarse - 1);
        t[k] = imageLoad(u_src, q);
        wt[k] = (o.x == 1 ? f.x : 1.0 - f.x) * (o.y == 1 ? f.y : 1.0 - f.y) + 1e-6;
    }
    imageStore(u_dst, p, front_mean(t, wt));
#else
    ivec2 ps = p + u_offset;
    ivec2 src_size = imageSize(u_src);
    vec4 here = imageLoad(u_src, ps);
    if (here.w <= 0.0) {
        imageStore(u_dst, p, room_texel_pack(RoomTexel(vec3(0.0), 0.0)));
        return;
    }
    float shade = 1.0;
    if (u_edl != 0) {
        // eye-dome lighting (Boucheny 2009, as in Potree): darken a pixel by how far it lies
        // behind its neighbours in log depth; empty neighbours add nothing
        const vec2 dirs[8] = vec2[8](vec2(1, 0), vec2(-1, 0), vec2(0, 1), vec2(0, -1),
                                     vec2(0.7071, 0.7071), vec2(-0.7071, -0.7071),
                                     vec2(0.7071, -0.7071), vec2(-0.7071, 0.7071));
        float ld = log2(here.w), response = 0.0;
        for (int d = 0; d < 8; ++d) {
            ivec2 q = clamp(ps + ivec2(round(dirs[d] * u_edl_radius)), ivec2(0), src_size - 1);
            float zn = imageLoad(u_src, q).w;
            if (zn > 0.0) response += max(0.0, ld - log2(zn));
        }
        shade = exp(-EDL_RESPONSE * response / 8.0);
    }
    imageStore(u_dst, p, room_texel_pack(RoomTexel(here.rgb * shade, 1.0)));
#endif
}
