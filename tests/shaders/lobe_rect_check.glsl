// Checks lib/lobe.glsl's lobe_rect against brute force (tests/pbgi/test_lobe_anisotropic.py).
// Per case i: cases[4 i .. 4 i + 3] = (N, rings), (V, sectors), (X, ax), (Y, ay) and
// nodes[i] = (l, sin_b): a receiver's frame (the lobe frame of lobe_frame_for: stretched along
// X, Y when ax != ay) and a node seen in direction l at angular radius b. Every micro-pixel is
// sampled at S x S points of its cell (the positions its jittered ray can take, through the
// same warp as lobe_cell); a micro-pixel "hits" when one of its rays lies in the node's cone
// (|L x l| <= sin b, L.l > 0: the node's sphere, which holds its disc). Output per case:
// (rect, hit micro-pixels, hit ones outside rect, hit ones outside the rectangle shrunk by
// u_shrink of its rings and sectors) and (micro-pixels in rect, 0, culled by lobe_cone_outside,
// 1): w = 1 marks a completed invocation.
#include "lib/common.glsl"
#include "lib/principled.glsl"
#include "lib/lobe.glsl"

layout(local_size_x = 16) in;

layout(std430, binding = 0) readonly buffer CaseBuf { vec4 cases[]; };
layout(std430, binding = 1) readonly buffer NodeBuf { vec4 nodes[]; };
layout(std430, binding = 2) writeonly buffer OutBuf { uvec4 out_data[]; };

uniform uint u_count;
uniform uint u_samples;     // S
uniform float u_shrink;     // e.g. 0.2

// The ray of micro-pixel (i, j) at (xi1, xi2) of its cell: lobe_cell's warp with a given point;
// 0 where lobe_cell gives it no solid angle (below the horizon: never ray cast).
vec3 cell_ray(LobeFrame f, uint i, uint j, float xi1, float xi2) {
    LobePiece p = lobe_piece(f, i >= f.split);
    float u = p.u0 + (float(i - p.r0) + xi1) * p.du;
    float phi = f.phi0 + (float(j) + xi2) * (TWO_PI / float(f.sectors));
    float t = sqrt(p.a2 * u / (1.0 - u));
    vec3 H = normalize(f.T * (t * cos(phi) * f.st.x) + f.B * (t * sin(phi) * f.st.y) + f.N);
    float vh = dot(f.V, H);
    vec3 L = 2.0 * vh * H - f.V;
    return vh > 0.0 && dot(L, f.N) > 0.0 ? L : vec3(0.0);   // lobe_cell's omega 0: never cast
}

bool in_rect(LobeFrame f, uint r, uint i, uint j) {
    uint r0 = r & 255u, r1 = (r >> 8u) & 255u, s0 = (r >> 16u) & 255u, ns = r >> 24u;
    return i >= r0 && i <= r1 && (j + f.sectors - s0) % f.sectors < ns;
}

// The rectangle with u_shrink of its rings and of its sectors taken off, half at each end.
uint shrunk(uint r) {
    uint r0 = r & 255u, r1 = (r >> 8u) & 255u, s0 = (r >> 16u) & 255u, ns = r >> 24u;
    uint nr = r1 - r0 + 1u;
    uint cr = uint(floor(u_shrink * float(nr) + 0.5)), cs = uint(floor(u_shrink * float(ns) + 0.5));
    cr = min(cr, nr - 1u);
    cs = min(cs, ns - 1u);
    r0 += cr / 2u;
    r1 -= cr - cr / 2u;
    s0 += cs / 2u;
    ns -= cs;
    return r0 | (r1 << 8u) | (s0 << 16u) | (ns << 24u);
}

void main() {
    uint c = gl_GlobalInvocationID.x;
    if (c >= u_count) return;
    vec4 a = cases[4u * c], b = cases[4u * c + 1u], x = cases[4u * c + 2u], y = cases[4u * c + 3u];
    uint rings = uint(a.w), sectors = uint(b.w);
    float aw = sqrt(x.w * y.w);
    LobeFrame f = lobe_frame(a.xyz, b.xyz, aw, max(x.w, y.w), 0.0, c, 0u, rings, sectors);
    if (abs(x.w - y.w) > 1e-3 * aw) {                 // lobe_frame_for's stretch
        f = lobe_frame(a.xyz, b.xyz, aw, aw, 0.0, c, 0u, rings, sectors);
        f.T = x.xyz;
        f.B = y.xyz;
        f.st = vec2(x.w, y.w) / aw;
    }
    vec3 l = nodes[c].xyz;
    float sin_b = nodes[c].w, cos_b = sqrt(max(1.0 - sin_b * sin_b, 0.0));
    float om;
    uint r = lobe_rect(f, l, sin_b, cos_b, om);
    uint rs = r == 0xFFFFFFFFu ? r : shrunk(r);
    uint hits = 0u, miss = 0u, miss_s = 0u;
    float inv = 1.0 / float(u_samples);
    for (uint i = 0u; i < rings; ++i) {
        for (uint j = 0u; j < sectors; ++j) {
            bool hit = false;
            for (uint s = 0u; s < u_samples * u_samples && !hit; ++s) {
                uint sy = s / u_samples, sx = s - sy * u_samples;
                vec3 L = cell_ray(f, i, j, (float(sx) + 0.5) * inv, (float(sy) + 0.5) * inv);
                hit = dot(L, l) > 0.0 && length(cross(L, l)) <= sin_b;   // (cos b is 1 in float below ~3e-4)
            }
            if (!hit) continue;
            hits++;
            if (r == 0xFFFFFFFFu || !in_rect(f, r, i, j)) miss++;
            if (rs == 0xFFFFFFFFu || !in_rect(f, rs, i, j)) miss_s++;
        }
    }
    out_data[2u * c] = uvec4(r, hits, miss, miss_s);
    bool culled = lobe_cone_outside(lobe_cone(f), l, sin_b, cos_b);
    out_data[2u * c + 1u] = uvec4(r == 0xFFFFFFFFu ? 0u : lobe_rect_cells(r), 0u,
                                  culled ? 1u : 0u, 1u);
}
