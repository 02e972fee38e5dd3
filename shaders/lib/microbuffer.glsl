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
// tests (see pbgi_classic.glsl's loop). The receiver frame is mb_frame's (below): x along t,
// y along b, z = N, with (t, b) orthonormal_basis(N) (lib/principled.glsl) turned about N.
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
#include "lib/principled.glsl"
#include "gen/microbuffer.glsl"

// The receiver's micro-buffer frame (seed 001, Section 2.3: "rotate each receiver's frame so
// that residual quantisation is noise, never a grid"): orthonormal_basis(N) turned about N by a
// random angle per receiver and pass. In a fixed frame the micro-pixel grid turns smoothly with
// the normal, so the instant a light crosses a micro-pixel's edge - and the instant the cut
// swaps a node for its children - is the same for neighbouring receivers: the shading of a
// smooth surface shows lines and facets along those instants. Turned at random, each receiver
// quantises its own way: the same error as noise, which the passes average
// (app/pbgi/microbuffer.py: set_frame_uniforms). The seed is the receiver's pixel in the whole
// image (u_frame_tile = tile x0, y0, tile width, image width: a tile's receivers get the angles
// one render of the image gives them) and the pass (u_frame_pass). Every shader that writes or
// reads a receiver's own micro-buffer takes its frame from here, so walk, rasteriser and gather
// agree. u_frame_turned 0 keeps orthonormal_basis(N): the point gathers (no passes average
// their noise).
// Hybrid's far-field blocks (app/pbgi/farfield.py) share one micro-buffer among receivers: the
// block's far walk draws it in the frame of its cone axis, the merge copies it into its
// receivers' buffers, and their near walks and gather (FRAME_NORMALS) complete and read it in
// that frame. Those programs take the seed from the row's record instead of a pixel
// (mb_frame_seeded; ShareRow.seed, Frame.seed): FRAME_SEED_BLOCK | the block's square
// (app/pbgi/farfield.py: square_seeds), one turn per block and pass, or SHARE_NONE for a
// receiver without a block (its own pixel's turn).
uniform uvec4 u_frame_tile;
uniform uint u_frame_pass;
uniform bool u_frame_turned;
void mb_frame_seeded(vec3 N, uint seed, out vec3 T, out vec3 B) {
    orthonormal_basis(N, T, B);
    if (!u_frame_turned) return;
    // the turn's (cos, sin) without trigonometry (the Mipmapped refinement takes a frame per
    // (node, receiver) pair): t = tan(phi / 2) uniform in [-1, 1] is phi in [-90, 90] degrees,
    // a hash bit adds a half turn; phi's density then varies by at most 2x around the circle,
    // which decorrelates neighbouring receivers as well as a uniform angle
    uint h = hash_pcg(seed * 7919u + u_frame_pass * 104729u + 0x9e3779b9u);
    float q = float(h & 0xFFFFu) * (2.0 / 65535.0) - 1.0;
    float k = ((h & 0x10000u) != 0u ? -1.0 : 1.0) / (1.0 + q * q);
    float c = (1.0 - q * q) * k, s = 2.0 * q * k;
    vec3 t = T;
    T = c * t + s * B;
    B = c * B - s * t;
}

// The receiver's own frame: seeded by its pixel in the whole image.
void mb_frame(vec3 N, uint tile_pixel, out vec3 T, out vec3 B) {
    mb_frame_seeded(N, image_pixel(u_frame_tile, tile_pixel), T, B);
}

// A row's frame in Hybrid's sharing: its block's turn, or its receiver's own (SHARE_NONE).
void mb_frame_shared(vec3 N, uint seed, uint tile_pixel, out vec3 T, out vec3 B) {
    mb_frame_seeded(N, seed == SHARE_NONE ? image_pixel(u_frame_tile, tile_pixel) : seed, T, B);
}

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

// The grid pixels a node can cover, row by row. A ray through a micro-pixel hits a node's
// sphere (radius r, centre at unit direction l and distance d) exactly when it lies in the cap
// of directions within b = asin(r / d) of l. A cap wholly above the horizon projects onto the
// Nusselt disc as a filled ellipse: centre l.xy cos b, semi-axis sin b across the radial
// direction and sin b * l.z along it (the cap's rim circle seen from above). Its bounding
// rectangle (mb_cone_rect) holds the ellipse's grid pixels but also, for a small or tilted cap,
// three to four times as many that no ray of which can hit (measured: 24% of the tested entries
// hit the sphere on the demo close-up at M = 16), so the rasterisers walk each row's span of
// the ellipse instead - the same hits, hence the same micro-buffer, with a fraction of the
// tests. A cap that reaches the horizon (its projection also takes the strip between the
// ellipse and the disc's rim) or surrounds the receiver keeps the rectangle's rows.
struct MbCap {
    vec2 c;         // ellipse centre, Nusselt disc coordinates
    float qa;       // quadratic form of the ellipse: (dx, dy) inside <=> qa dx^2 + 2 qb dx dy
    float qb;       //   + qc dy^2 <= 1, with qa qc - qb^2 = iab
    float iab;
    float hy;       // half-height
    float wx;       // half-width, reached at dy = +-dyr
    float dyr;
    bool full;      // rows of the rectangle
    vec2 elevation; // the cap's elevations (radians): a pixel's bands outside them are skipped
};

MbCap mb_cap(vec3 dv, float d2, float r2, vec3 T, vec3 B, vec3 N) {
    MbCap k;
    k.full = true;
    k.c = vec2(0.0); k.qa = k.qb = k.iab = k.hy = k.wx = k.dyr = 0.0;
    k.elevation = vec2(-1.0, 4.0);
#ifdef MB_RECT_RASTER
    return k;            // every entry of the rectangle (tests/pbgi/test_pbgi_modes.py compares)
#endif
    if (d2 <= r2 * 1.0001) return k;                    // inside: every direction
    float inv_d = inversesqrt(d2);
    vec3 l = vec3(dot(dv, T), dot(dv, B), dot(dv, N)) * inv_d;
    float sin_b = sqrt(r2) * inv_d;
    // Elevations within b of l's (margin: the index's 16-bit elevations, asin's rounding).
    float el = asin(clamp(l.z, -1.0, 1.0)), b = asin(min(sin_b, 1.0));
    k.elevation = vec2(el - b - 2e-4, el + b + 2e-4);
    if (l.z <= sin_b * 1.001 + 1e-3) return k;          // reaches the horizon
    float cos_b = sqrt(max(1.0 - sin_b * sin_b, 0.0));
    float rho = length(l.xy);
    vec2 v = rho > 1e-6 ? l.xy / rho : vec2(0.0, 1.0);  // radial
    vec2 u = vec2(-v.y, v.x);                           // across
    float a = sin_b * 1.0005 + 1e-6;                    // semi-axes, a hair conservative
    float bm = sin_b * l.z * 1.0005 + 1e-6;
    float ia = 1.0 / (a * a), ib = 1.0 / (bm * bm);
    k.full = false;
    k.c = l.xy * cos_b;
    k.qa = u.x * u.x * ia + v.x * v.x * ib;
    k.qb = u.x * u.y * ia + v.x * v.y * ib;
    k.iab = ia * ib;
    k.hy = sqrt(a * a * u.y * u.y + bm * bm * v.y * v.y);
    k.wx = sqrt(a * a * u.x * u.x + bm * bm * v.x * v.x);
    k.dyr = (a * a * u.x * u.y + bm * bm * v.x * v.y) / k.wx;
    return k;
}

// Grid pixel columns (x0, x1) of row y that the cap can cover, within the rectangle; a row the
// ellipse misses (the rectangle's margin) keeps one pixel, so a row is never empty.
uvec2 mb_cap_row(MbCap k, uint y, uvec4 rect, int m) {
    if (k.full) return rect.xz;
    float fm = float(m);
    float da = max(-1.0 + 2.0 * float(y) / fm - k.c.y - 1e-4, -k.hy);
    float db = min(-1.0 + 2.0 * float(y + 1u) / fm - k.c.y + 1e-4, k.hy);
    if (da > db) return uvec2(rect.x);
    float sa = sqrt(max(k.qa - da * da * k.iab, 0.0)), sb = sqrt(max(k.qa - db * db * k.iab, 0.0));
    float xa = -da * k.qb, xb = -db * k.qb;
    float lo = (-k.dyr >= da && -k.dyr <= db) ? -k.wx : min(xa - sa, xb - sb) / k.qa;
    float hi = (k.dyr >= da && k.dyr <= db) ? k.wx : max(xa + sa, xb + sb) / k.qa;
    int x0 = int(floor((k.c.x + lo + 1.0) * 0.5 * fm - 1e-3));
    int x1 = int(floor((k.c.x + hi + 1.0) * 0.5 * fm + 1e-3));
    x0 = clamp(x0, int(rect.x), int(rect.z));
    x1 = clamp(x1, x0, int(rect.z));
    return uvec2(x0, x1);
}

// Walks the entries of a node's grid pixels one per step (no integer division): the cap's
// span of each row of the rectangle, each pixel's bands in turn. At most mb_rect_entries(rect)
// steps (what the walks budget).
//   MbCursor c = mb_cursor(rect, cap, m);
//   do { uint k = mb_cursor_entry(c, m); ...; } while (mb_cursor_next(c, rect, cap, m));
// Bands: band b of a pixel split into n spans elevations [lo + b step, lo + (b + 1) step] (band 0
// from the horizon), so only bands [b0, b1] can meet the cap's elevations.
struct MbCursor { uint px; uint py; uint band; uint band_last; uint first; uvec2 span; };
void mb_cursor_pixel(inout MbCursor c, MbCap cap) {
    MbBands bb = mb_bands(c.px, c.py);
    const float unit = 0.5 * PI / 65535.0;    // microbuffer.py: ELEVATION_UNIT
    float lo = float(bb.elevation & 0xffffu) * unit;
    float step = max(float(bb.elevation >> 16u) * unit, 1e-6);
    float n = float(bb.count);
    float b0 = clamp(floor((cap.elevation.x - lo) / step), 0.0, n);
    float b1 = clamp(floor((cap.elevation.y - lo) / step), b0, n);
    c.first = bb.first;
    c.band = uint(b0);
    c.band_last = uint(b1);
}
MbCursor mb_cursor(uvec4 rect, MbCap cap, int m) {
    uvec2 span = mb_cap_row(cap, rect.y, rect, m);
    MbCursor c = MbCursor(span.x, rect.y, 0u, 0u, 0u, span);
    mb_cursor_pixel(c, cap);
    return c;
}
uint mb_cursor_entry(MbCursor c, int m) {
    return c.band == 0u ? c.py * uint(m) + c.px : c.first + c.band - 1u;
}
// Advances; false once the rectangle is done.
bool mb_cursor_next(inout MbCursor c, uvec4 rect, MbCap cap, int m) {
    c.band++;
    if (c.band <= c.band_last) return true;
    c.px++;
    if (c.px > c.span.y) {
        c.py++;
        if (c.py > rect.w) return false;
        c.span = mb_cap_row(cap, c.py, rect, m);
        c.px = c.span.x;
    }
    mb_cursor_pixel(c, cap);
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
