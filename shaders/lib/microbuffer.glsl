// The micro-buffer shared by every PBGI mode (see app/pbgi/microbuffer.py for the why).
// Storage: an RG32UI image, row i = receiver i of the batch, texel k = entry k: MbEntry (depth key,
// node index), empty = (MB_EMPTY, MB_EMPTY); texels and tables are declared in
// app/pbgi/gpu_layout.py (gen/microbuffer.glsl). (An image rather than an SSBO: llvmpipe reads
// and writes image texels as vectors, SSBO words lane by lane.) Grid pixel (x, y) covers the square [-1 + 2x/M, -1 + 2(x+1)/M]
// x [-1 + 2y/M, ...] of the Nusselt disc. Its entries: k = y * M + x (the band nearest the
// horizon - every grid pixel has it, zero weight outside the disc) and, for pixels near the rim
// that span too much elevation, further bands mb_pixel_bands(x, y).x + 0, 1, ... (see
// app/pbgi/microbuffer.py: one ray per rim pixel over-estimates a light just above the horizon
// up to 2x). mb_table(k) = MbDirection (centroid direction in the receiver frame, cosine-weighted
// solid angle = clipped area of the entry's region); mb_entries() = E, the texels per receiver.
// A rasteriser covers a rectangle of grid pixels with all their bands: mb_rect_entries(rect)
// tests (see pbgi_classic.glsl's loop). The receiver frame is orthonormal_basis(N)
// (lib/principled.glsl): x along t, y along b, z = N.
//
// Node rasterisation (paper Section 5.3): a node is written into every micro-pixel whose
// direction ray hits it (ray-sphere test) and can meet a front face of its normal cone, with a
// depth test on the distance along the ray to the plane through the node centre normal to its
// cone axis (paper Section 5.2.1). Two refinements, both measured against the CPU reference:
// the ray must also cross the slab of half-thickness r sin(alpha) around that plane (the points
// of a node with normal-cone half-angle alpha lie in it, so a flat cluster is a disc, not a
// ball: the depth of a ray that misses the disc used to be clamped into the sphere and put a
// ceiling light *in front of* the ceiling around it), and coplanar ties are broken by
// mb_hit_key's distance term.
#ifndef SCANLIGHT_MICROBUFFER_GLSL
#define SCANLIGHT_MICROBUFFER_GLSL
#include "lib/common.glsl"
#include "gen/microbuffer.glsl"

// (first further band, number of further bands) of grid pixel (x, y).
uvec2 mb_pixel_bands(uint x, uint y) { MbBands b = mb_bands(x, y); return uvec2(b.first, b.count); }
uint mb_extra_prefix(uint x, uint y) { return mb_bands(x, y).prefix; }
MbEntry mb_load(uint receiver, uint k) { return mb_entry_at(ivec2(int(k), int(receiver))); }

// What the per-micro-pixel test needs about one node, seen from one receiver.
struct MbNode {
    vec3 dv;        // node centre - receiver position
    float d2;       // |dv|^2
    float r2;       // radius^2
    vec3 axis;      // normal-cone axis
    float sin_a;    // sin(half-aperture), 1 for apertures >= pi/2 (no per-ray back-face test)
    float inv_area; // 1 / (points below x cell area): the tie-break's scale
    uint index;     // node index (what the micro-pixel stores)
};

// Micro-pixel bounding rectangle (x0, y0, x1, y1 inclusive) of the cone of directions within
// angle b (sin_b, cos_b) of the unit local direction l: the projection is linear in x and y, so
// the x-extent of the cone is [cos(theta_x + b), cos(theta_x - b)] with cos(theta_x) = l.x.
uvec4 mb_cone_rect(vec3 l, float sin_b, float cos_b, int m) {
    vec2 c = l.xy;
    vec2 s = sqrt(max(1.0 - c * c, 0.0));
    vec2 hi = mix(c * cos_b + s * sin_b, vec2(1.0), greaterThan(c, vec2(cos_b)));
    vec2 lo = mix(c * cos_b - s * sin_b, vec2(-1.0), lessThan(c, vec2(-cos_b)));
    float fm = float(m);
    ivec2 p0 = clamp(ivec2(floor((lo + 1.0) * 0.5 * fm - 1e-3)), ivec2(0), ivec2(m - 1));
    ivec2 p1 = clamp(ivec2(floor((hi + 1.0) * 0.5 * fm + 1e-3)), ivec2(0), ivec2(m - 1));
    return uvec4(p0, p1);
}

uint mb_pack_rect(uvec4 r) { return r.x | (r.y << 8u) | (r.z << 16u) | (r.w << 24u); }
uvec4 mb_unpack_rect(uint w) { return uvec4(w & 255u, (w >> 8u) & 255u, (w >> 16u) & 255u, w >> 24u); }
uint mb_rect_area(uvec4 r) { return (r.z - r.x + 1u) * (r.w - r.y + 1u); }   // grid pixels
// Entries (= per-entry tests) of a rectangle of grid pixels: its area plus the further bands,
// from the summed-area table.
uint mb_rect_entries(uvec4 r) {
    return mb_rect_area(r) + mb_extra_prefix(r.z + 1u, r.w + 1u) - mb_extra_prefix(r.z + 1u, r.y)
         - mb_extra_prefix(r.x, r.w + 1u) + mb_extra_prefix(r.x, r.y);
}

// Walks the entries of a rectangle one per step, for flat rasterisation loops (no integer
// division, no inner loop): grid pixels row by row, each pixel's bands in turn.
//   MbCursor c = mb_cursor(rect);
//   for (n = mb_rect_entries(rect) steps) { uint k = mb_cursor_entry(c, m); ...;
//                                           bool more = mb_cursor_next(c, rect); }
struct MbCursor { uint px; uint py; uint band; uvec2 bands; };
MbCursor mb_cursor(uvec4 rect) { return MbCursor(rect.x, rect.y, 0u, mb_pixel_bands(rect.x, rect.y)); }
uint mb_cursor_entry(MbCursor c, int m) {
    return c.band == 0u ? c.py * uint(m) + c.px : c.bands.x + c.band - 1u;
}
// Advances; false once the rectangle is done.
bool mb_cursor_next(inout MbCursor c, uvec4 rect) {
    c.band++;
    if (c.band <= c.bands.y) return true;
    c.band = 0u;
    c.px++;
    if (c.px > rect.z) { c.px = rect.x; c.py++; }
    if (c.py > rect.w) return false;
    c.bands = mb_pixel_bands(c.px, c.py);
    return true;
}

// Depth-test key of a node seen through one micro-pixel along world direction w; MB_EMPTY
// when the ray misses it. The key is the float bits of the depth (non-negative floats order like
// their bits) with the low MB_TIE_BITS mantissa bits replaced by a tie-break: depths within
// ~2^-(23 - MB_TIE_BITS) of each other (coplanar nodes: a light cluster and the ceiling around
// it) are decided by |hit - centre|^2 / (points below the node), the squared distance in units
// of the node's equal-area disc for a uniform scan, instead of by traversal order. Otherwise a
// large bright cluster, whose bounding sphere reaches far beyond its points, wins every tie
// around it and bleeds its light over its neighbours.
#ifndef MB_TIE_BITS
#define MB_TIE_BITS 15
#endif
uint mb_hit_key(MbNode n, vec3 w) {
    float tc = dot(w, n.dv);
    float h2 = n.r2 - (n.d2 - tc * tc);
    if (h2 < 0.0) return MB_EMPTY;             // ray misses the sphere
    float h = sqrt(h2);
    float lo = max(tc - h, 0.0), hi = tc + h;
    float cw = dot(w, n.axis);
    if (hi <= 0.0 || cw > n.sin_a) return MB_EMPTY;  // behind, or only back faces
    // The points lie in the slab |dot(x - c, axis)| <= r sin(alpha) around the plane through
    // the centre (a flat node is a disc, not a ball): clip the ray to it.
    float ha = dot(n.dv, n.axis);
    float e = sqrt(n.r2) * n.sin_a * 1.0001;
    float tp = tc;
    if (abs(cw) > 1e-6) {
        tp = ha / cw;
        float ea = e / abs(cw);
        lo = max(lo, tp - ea);
        hi = min(hi, tp + ea);
    } else if (abs(ha) > e) {
        return MB_EMPTY;
    }
    if (lo > hi) return MB_EMPTY;
    float t = clamp(tp, lo, hi);
    vec3 q = t * w - n.dv;                     // hit point relative to the node centre
    float x = dot(q, q) * n.inv_area;
    float tie = x / (1.0 + x);                 // monotonic in x, in [0, 1)
    const uint tie_max = (1u << MB_TIE_BITS) - 1u;
    return min((floatBitsToUint(t) & ~tie_max) | uint(tie * float(tie_max)), MB_EMPTY - 1u);
}

// Depth-tested write. One invocation owns a receiver's micro-buffer in Classic; a mode where
// several invocations write one micro-buffer needs an atomic variant (imageAtomicMin on the key
// in a pass of its own, then the node index where the key matches).
void mb_write(uint receiver, uint k, uint key, uint node) {
    ivec2 c = ivec2(int(k), int(receiver));
    if (key < mb_entry_at(c).key) mb_entry_store(c, MbEntry(key, node));
}
#endif
