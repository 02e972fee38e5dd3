// The lobe micro-buffer: a second micro-buffer per glossy receiver whose micro-pixels follow its
// specular lobe (seed 001, Section 2.3: BRDF importance-warped micro-buffers). Why and the
// numbers: app/pbgi/lobe.py (tested through the white furnace at every roughness and the
// path-traced sweep: tests/pbgi/test_pbgi_render.py, tests/pbgi/test_glossy_sweep.py).
//
// Mapping. Micro-pixel k = (ring i, sector j), LOBE_RINGS x LOBE_SECTORS of them, lives in
// half-vector space around the receiver's normal: the GGX distribution of normals with the warp's
// alpha a_w puts an equal share of D(h) cos(theta_h) in every ring when rings are uniform in
//     u = tan^2(theta_h) / (a_w^2 + tan^2(theta_h))          (the NDF's CDF in theta_h)
// and sectors uniform in phi. Ring i covers u in u_max [i, i + 1) / LOBE_RINGS; u_max bounds the
// lobe's domain (tan theta_h <= LOBE_DOMAIN x the larger alpha: 99% of a GGX lobe's energy for
// LOBE_DOMAIN 10). A micro-pixel's ray leaves in L = reflect(-V, h) for h at a jittered point of
// the micro-pixel (per receiver and pass: the frame is rotated by a random phi_0 and the point is
// random inside its cell, so residual quantisation is noise, never a grid). Its solid angle in L
// is the Jacobian 4 (V.h) times its solid angle in h,
//     Omega_h = du dphi a_w^2 / (2 (1 - u)^2 (1 + tan^2)^(3/2))     (d omega_h = du dphi / (2 pi D cos))
// which is what the gather weights by and what the cut compares a node's solid angle with.
// Outside the domain the specular lobe stays in the cosine micro-buffer: the two buffers split the
// sphere of directions in h, so nothing is counted twice or lost. Two lobes of very different
// widths (clearcoat over a glossy base) get a piece of the rings each (lobe_frame). An
// anisotropic specular lobe alone is mapped through GGX's slope stretch along the material's
// tangent (lobe_frame_for): the rings and sectors above live in the stretched slope space, where
// the lobe is isotropic, and a micro-pixel's solid angle in h is its slope area (which the
// stretch keeps) times cos^3 of its true half-vector angle; a node's rectangle there is the
// bound of its cone's exact image (lobe_rect_stretched).
//
// Needs lib/common.glsl, lib/principled.glsl.
#ifndef SCANLIGHT_LOBE_GLSL
#define SCANLIGHT_LOBE_GLSL

#ifndef LOBE_DOMAIN
#define LOBE_DOMAIN 10.0
#endif
#define LOBE_MIN_ALPHA 1e-3
#define LOBE_MAX_U 0.99995
#define LOBE_SPLIT_RATIO 3.0     // two lobes this far apart in alpha get a piece each

struct LobeFrame {
    vec3 N, T, B, V;
    float a2;        // warp alpha^2 of the inner piece (the narrowest lobe)
    float u_max;     // the inner piece's end in its u
    float a2o;       // warp alpha^2 of the outer piece (the widest lobe; = a2 with one piece)
    float uo0, uo1;  // the outer piece's u range, in its own u
    float tan2_split;  // tan^2(theta_h) where the inner piece ends (1e30: one piece)
    float tan2_max;    // the domain: tan^2(theta_h) below this
    vec2 st;         // slope stretch (sx, sy), sx sy = 1: (1, 1) but for an anisotropic lobe
    float phi0;      // frame rotation (radians)
    uint seed;       // per receiver and pass
    uint rings, sectors;
    uint split;      // rings of the inner piece (= rings with one piece)
};

// The lobe micro-buffer of a receiver whose narrowest lobe has alpha ``aw`` and widest ``amax``
// (lobe_frame_for picks them from its lobes). One lobe, or two of similar width: one piece, the
// warp of ``aw`` over the whole domain (tan theta_h <= LOBE_DOMAIN amax). Two lobes of very
// different widths (a mirror-like clearcoat over a glossy base): the inner half of the rings is
// warped to the narrow lobe up to its own domain, the outer half to the wide lobe beyond it, so
// neither lobe is left to a few huge micro-pixels (which made fireflies).
// ``tan_floor``: the domain reaches at least tan theta_h = tan_floor (lobe_tan_floor).
LobeFrame lobe_frame(vec3 N, vec3 V, float aw, float amax, float tan_floor, uint pixel, uint pass,
                     uint rings, uint sectors) {
    LobeFrame f;
    f.N = N;
    orthonormal_basis(N, f.T, f.B);
    f.V = V;
    f.st = vec2(1.0);
    aw = max(aw, LOBE_MIN_ALPHA);
    amax = max(amax, aw);
    float d2 = LOBE_DOMAIN * LOBE_DOMAIN;
    f.a2 = aw * aw;
    f.seed = hash_pcg(pixel * 9781u + pass * 6271u + 17u);
    f.phi0 = TWO_PI * hash_unit(hash_pcg(f.seed));
    f.rings = rings;
    f.sectors = sectors;
    float t2 = max(d2 * amax * amax, tan_floor * tan_floor);
    if (amax > LOBE_SPLIT_RATIO * aw && rings >= 2u) {
        float t1 = d2 * f.a2;
        f.u_max = t1 / (f.a2 + t1);
        f.a2o = amax * amax;
        f.uo0 = t1 / (f.a2o + t1);
        f.uo1 = min(t2 / (f.a2o + t2), LOBE_MAX_U);
        f.tan2_split = t1;
        f.split = rings / 2u;
    } else {
        f.u_max = min(t2 / (f.a2 + t2), LOBE_MAX_U);
        f.a2o = f.a2;
        f.uo0 = 0.0;
        f.uo1 = f.u_max;
        f.tan2_split = 1e30;
        f.split = rings;
    }
    f.tan2_max = f.a2o * f.uo1 / (1.0 - f.uo1);
    return f;
}

// Which lobes of a receiver the lobe micro-buffer takes: x = the GGX specular lobe (roughness
// below ``glossy_below``: rougher lobes the cosine micro-buffer resolves), y = the clearcoat (any:
// its alpha <= 0.1 is always too narrow for the cosine micro-buffer). Sheen, diffuse and
// subsurface stay in the cosine micro-buffer.
bvec2 lobe_terms(PrincipledPrepared q, float glossy_below) {
    return bvec2(q.roughness < glossy_below, q.clearcoat > 0.0);
}

// How much of the specular lobe the lobe micro-buffer takes: all of it up to (1 - LOBE_BLEND)
// glossy_below, then linearly less, none at glossy_below; the cosine micro-buffer takes the rest.
// Switching at one roughness left a seam on the roughness slider (the two buffers' estimates
// differ by a few percent there: +4% in one 0.001 step of the room sweep).
#define LOBE_BLEND 0.3
float lobe_spec_share(PrincipledPrepared q, float glossy_below) {
    return clamp((glossy_below - q.roughness) / (LOBE_BLEND * glossy_below), 0.0, 1.0);
}

// The pixel a receiver's frame is seeded by: its pixel in the whole image, from its pixel in
// the tile (LobeSettings.seed_tile: x0, y0, tile width, image width), so that a tile's seeds are
// the ones one render of the image gives the same pixels, not the same in every tile.
uniform uvec4 u_lobe_tile;
uint lobe_seed_pixel(uint tile_pixel) { return image_pixel(u_lobe_tile, tile_pixel); }

// The domain's floor: what the cosine micro-buffer leaves of a lobe it must not hold. Outside the
// domain the cosine micro-buffer takes the lobe's tail, one value of f cos at each micro-pixel's
// centre times the micro-pixel's solid angle. A lobe much narrower than a micro-pixel (roughness
// below ~0.1) has a domain (LOBE_DOMAIN alpha) smaller than one micro-pixel, so a centre that
// falls just outside it samples the lobe near its peak for the whole micro-pixel: a receiver
// in the white furnace 29% too bright at roughness 0 (M 24, Classic with frames turned per
// receiver, lib/microbuffer.glsl: mb_frame - the fixed frame hid it in most receivers, not
// all: 9%). So the domain reaches at least LOBE_FLOOR_PIXELS half-diagonals of a cosine
// micro-pixel beyond the mirror direction, where the lobe has fallen to nothing: a micro-pixel
// of side 2 / M in the Nusselt plane spans (2 / M) / cos(theta) radially and 2 / M across at
// polar angle theta (the mirror direction's cos theta = N.V), and half-vector angles are half
// the reflected ones. u_lobe_cosine_m: the M of the cosine micro-buffer that takes the tail
// (0: no floor, the domain is LOBE_DOMAIN alpha). LOBE_MAX_U still caps it (141 alpha).
#define LOBE_FLOOR_PIXELS 2.0
#define LOBE_FLOOR_MIN_COS 0.25
uniform int u_lobe_cosine_m;
float lobe_tan_floor(float n_dot_v) {
    if (u_lobe_cosine_m <= 0) return 0.0;
    float c = max(n_dot_v, LOBE_FLOOR_MIN_COS);
    float half_diagonal = sqrt(1.0 + 1.0 / (c * c)) / float(u_lobe_cosine_m);   // reflected
    return LOBE_FLOOR_PIXELS * 0.5 * half_diagonal;
}

// The frame for those lobes: the warp follows the narrowest, the domain covers the widest.
// An anisotropic specular lobe alone (no clearcoat in the buffer) is mapped through the slope
// stretch of GGX: slopes m' = (sx m.x, sy m.y) along the material's tangent X and bitangent Y,
// sx = ax / a_w, sy = ay / a_w, a_w = sqrt(ax ay); the stretch has determinant 1, so the
// anisotropic lobe in m' is the isotropic lobe of a_w in m, and the rings and sectors of that
// lobe put an equal share of the anisotropic lobe in every micro-pixel (an isotropic warp of an
// anisotropic lobe left micro-pixels far wider than the lobe across it: fireflies).
LobeFrame lobe_frame_for(PrincipledPrepared q, bvec2 terms, uint pixel, uint pass, uint rings,
                         uint sectors) {
    float aw = 1.0, amax = 0.0;
    if (terms.x) { aw = sqrt(q.ax * q.ay); amax = max(q.ax, q.ay); }
    if (terms.y) { aw = min(aw, q.cc_alpha); amax = max(amax, q.cc_alpha); }
#ifdef PRINCIPLED_NO_ANISOTROPY
    return lobe_frame(q.N, q.V, aw, amax, lobe_tan_floor(q.n_dot_v), pixel, pass, rings,
                      sectors);
#else
    bool stretch = terms.x && !terms.y && abs(q.ax - q.ay) > 1e-3 * aw;
    LobeFrame f = lobe_frame(q.N, q.V, aw, stretch ? aw : amax, lobe_tan_floor(q.n_dot_v), pixel,
                             pass, rings, sectors);
    if (stretch) {
        f.T = q.X;
        f.B = q.Y;
        f.st = vec2(q.ax, q.ay) / aw;
    }
    return f;
#endif
}

// A program for materials without anisotropy (app/pbgi/gather.py: absent_features) leaves the
// stretch's code out: llvmpipe pays for untaken branches (23% of a glossy frame here).
#ifdef PRINCIPLED_NO_ANISOTROPY
bool lobe_stretched(LobeFrame f) { return false; }
#else
bool lobe_stretched(LobeFrame f) { return f.st.x != 1.0 || f.st.y != 1.0; }
#endif

// The half-vector h (any length, above the surface) as its mapping's slope m (before the
// stretch): m = (h.T / sx, h.B / sy) / h.N.
vec2 lobe_slope(LobeFrame f, vec3 h) {
    return vec2(dot(h, f.T), dot(h, f.B)) / (f.st * dot(h, f.N));
}

// Is incoming direction w (unit, world) inside the lobe micro-buffer's domain? Its lobes are
// then gathered there, not from the cosine micro-buffer.
bool lobe_inside(LobeFrame f, vec3 w) {
    vec3 h = w + f.V;
    float hn = dot(h, f.N);
    if (hn <= 0.0) return false;
    if (lobe_stretched(f)) {
        vec2 m = lobe_slope(f, h);
        return dot(m, m) < f.tan2_max;
    }
    float h2 = dot(h, h);
    float tan2 = max(h2 - hn * hn, 0.0) / (hn * hn);
    return tan2 < f.tan2_max;
}

// A piece of the mapping: its warp alpha^2, its first u, its u per ring, its first ring.
struct LobePiece { float a2, u0, du; uint r0; };

LobePiece lobe_piece(LobeFrame f, bool outer) {
    if (!outer) return LobePiece(f.a2, 0.0, f.u_max / float(f.split), 0u);
    return LobePiece(f.a2o, f.uo0, (f.uo1 - f.uo0) / float(f.rings - f.split), f.split);
}

// The micro-pixel solid angle in h at tan^2 theta_h (d omega_h = du dphi / (2 pi D cos)).
float lobe_omega_h(LobePiece p, float tan2, float dphi) {
    float one_u = 1.0 - tan2 / (p.a2 + tan2);
    return p.du * dphi * p.a2 / (2.0 * one_u * one_u * (1.0 + tan2) * sqrt(1.0 + tan2));
}

// The same through the stretch: the micro-pixel's area in slope space (the stretch keeps it)
// at the mapping's tan^2 ``tan2``, times cos^3 of the true half-vector angle (tan^2 ``true2``):
// d omega_h = d(slope area) cos^3 theta_h.
float lobe_omega_h_stretched(LobePiece p, float tan2, float true2, float dphi) {
    float one_u = 1.0 - tan2 / (p.a2 + tan2);
    return p.du * dphi * p.a2 / (2.0 * one_u * one_u * (1.0 + true2) * sqrt(1.0 + true2));
}

// The ring of half-vector angle tan^2 (monotone in theta_h across both pieces).
uint lobe_ring(LobeFrame f, float tan2) {
    bool outer = tan2 >= f.tan2_split;
    LobePiece p = lobe_piece(f, outer);
    float u = tan2 >= 1e29 ? 1.0 : tan2 / (p.a2 + tan2);
    uint last = outer ? f.rings - 1u : f.split - 1u;
    return uint(clamp(floor((u - p.u0) / p.du) + float(p.r0), float(p.r0), float(last)));
}

// Micro-pixel k's ray (world L, unit) and its solid angle in L; omega 0 when L is below the
// horizon or the micro-pixel is empty.
void lobe_cell(LobeFrame f, uint k, out vec3 L, out float omega) {
    uint i = k / f.sectors, j = k - i * f.sectors;
    uint h = hash_pcg(f.seed ^ (k * 2654435761u));
    float xi1 = hash_unit(h), xi2 = hash_unit(hash_pcg(h));
    LobePiece p = lobe_piece(f, i >= f.split);
    float dphi = TWO_PI / float(f.sectors);
    float u = p.u0 + (float(i - p.r0) + xi1) * p.du;
    float phi = f.phi0 + (float(j) + xi2) * dphi;
    float tan2 = p.a2 * u / (1.0 - u);
    vec3 H;
    float om_h;
    if (lobe_stretched(f)) {
        vec2 m = sqrt(tan2) * vec2(cos(phi), sin(phi)) * f.st;     // the true slope
        H = normalize(f.T * m.x + f.B * m.y + f.N);
        om_h = lobe_omega_h_stretched(p, tan2, dot(m, m), dphi);
    } else {
        float c2 = 1.0 / (1.0 + tan2);                   // cos^2 theta_h
        float ch = sqrt(c2), sh = sqrt(max(1.0 - c2, 0.0));
        H = f.T * (sh * cos(phi)) + f.B * (sh * sin(phi)) + f.N * ch;
        om_h = lobe_omega_h(p, tan2, dphi);
    }
    float vh = dot(f.V, H);
    L = 2.0 * vh * H - f.V;
    omega = (vh > 0.0 && dot(L, f.N) > 0.0) ? 4.0 * vh * om_h : 0.0;
}

// The band of polar angles th -/+ bh: its lowest angle ``lo`` and tan^2 of both ends (1e30 past
// the horizon); false when it lies wholly outside the domain.
bool lobe_band(LobeFrame f, float th, float bh, out float lo, out float tan2_lo,
               out float tan2_hi) {
    lo = max(th - bh, 0.0);
    float hi = th + bh;
    float tlo = tan(lo);
    tan2_lo = lo >= 0.5 * PI ? 1e30 : tlo * tlo;
    float thi = tan(min(hi, 0.5 * PI - 1e-4));
    tan2_hi = hi >= 0.5 * PI ? 1e30 : thi * thi;
    return tan2_lo < f.tan2_max;
}

// The sectors (first, count) a disc of angular radius ``bh`` covers around the mapping's polar
// angle ``th`` (its lowest ``lo``) and azimuth ``phic`` (from phi0): every sector when the disc
// reaches the pole.
uvec2 lobe_sectors(LobeFrame f, float th, float lo, float bh, float phic, float dphi) {
    uint s0 = 0u, ns = f.sectors;
    float sth = sin(th);
    if (lo > 0.0 && sin(bh) < sth) {
        float half_w = asin(clamp(sin(bh) / sth, 0.0, 1.0));
        float a = (phic - half_w) / dphi, c = (phic + half_w) / dphi;
        float fa = floor(a);
        uint cnt = uint(floor(c) - fa) + 1u;
        if (cnt < f.sectors) {          // (GLSL's % is undefined for negative operands)
            s0 = uint(int(fa) + 8 * int(f.sectors)) % f.sectors;
            ns = cnt;
        }
    }
    return uvec2(s0, ns);
}

// The micro-pixels a node may cover: node direction l (unit, world) with angular radius
// b (sin_b, cos_b). Returns (ring0, ring1, sector0, sectors) packed 8 bits each, 0xFFFFFFFF when
// the node lies outside the lobe's domain; ``omega_min`` = the smallest micro-pixel solid angle
// (in L) it covers (the cut compares the node with it).
uint lobe_rect_stretched(LobeFrame f, vec3 l, float sin_b, float cos_b, out float omega_min);

uint lobe_rect_of(LobeFrame f, vec3 l, float sin_b, float cos_b, out float omega_min,
                  bool sectors);
uint lobe_rect(LobeFrame f, vec3 l, float sin_b, float cos_b, out float omega_min) {
    return lobe_rect_of(f, l, sin_b, cos_b, omega_min, true);
}

// lobe_rect's rings and omega_min (and whether the node is in the domain), with every sector:
// what the walk decides on, without the sectors' trigonometry (pbgi_lobe.glsl:
// LOBE_ACCEPTED_TABLE). Through the stretch it is lobe_rect itself.
uint lobe_rect_rings(LobeFrame f, vec3 l, float sin_b, float cos_b, out float omega_min) {
    return lobe_rect_of(f, l, sin_b, cos_b, omega_min, false);
}

uint lobe_rect_of(LobeFrame f, vec3 l, float sin_b, float cos_b, out float omega_min,
                  bool sectors) {
    if (lobe_stretched(f)) return lobe_rect_stretched(f, l, sin_b, cos_b, omega_min);
    vec3 s = l + f.V;
    float len = length(s);
    omega_min = 0.0;
    float cos_d = 0.5 * len;                            // V.h_c = l.h_c
    float b = atan(sin_b, cos_b);
    float den = 2.0 * cos_d - b;
    uint full = (f.rings - 1u) << 8u | (f.sectors << 24u);
    float dphi = TWO_PI / float(f.sectors);
    if (den < 0.05) {                                   // the node spans the reflection's pole
        omega_min = 4.0 * max(cos_d, 1e-3) * lobe_omega_h(lobe_piece(f, false), 0.0, dphi);
        return full;
    }
    float bh = b / den;                                 // angular radius in h (a bound)
    vec3 hc = s / len;
    float ch = dot(hc, f.N);
    float th = acos(clamp(ch, -1.0, 1.0));
    float lo, tan2_lo, tan2_hi;
    if (!lobe_band(f, th, bh, lo, tan2_lo, tan2_hi)) return 0xFFFFFFFFu;   // outside
    uint r0 = lobe_ring(f, tan2_lo);
    uint r1 = lobe_ring(f, tan2_hi);
    bool outer = tan2_lo >= f.tan2_split;
    float om = lobe_omega_h(lobe_piece(f, outer), tan2_lo, dphi);
    if (!outer && tan2_hi >= f.tan2_split)             // it reaches into the outer piece too
        om = min(om, lobe_omega_h(lobe_piece(f, true), f.tan2_split, dphi));
    omega_min = 4.0 * cos_d * om;
    if (!sectors) return r0 | (r1 << 8u) | (f.sectors << 24u);
    uvec2 sec = lobe_sectors(f, th, lo, bh, atan(dot(hc, f.B), dot(hc, f.T)) - f.phi0, dphi);
    return r0 | (r1 << 8u) | (sec.x << 16u) | (sec.y << 24u);
}

// lobe_rect through the stretch (one piece), tight. Directions L in the node's cone (axis l,
// half-angle b) are the points of a spherical cap; the ray from -V through L (-V on the sphere,
// outside the cap) has direction d = L + V, and the mapping's slope of L is a central projection
// of d, m = (d.T / sx, d.B / sy) / d.N. The same rays from -V cross the flat disc that closes the
// cap (centre cos_b l, radius sin_b, in the plane x.l = cos_b), and that disc lies inside its
// circumscribed 12-gon (vertex radius sin_b / cos(pi / 12)). A projective map keeps a convex
// polygon convex where d.N > 0, and the stretch is linear, so the cap's image in the mapping
// lies inside the convex polygon of the 12 vertices' slopes: its rings run from the polygon's
// distance to the origin (0 when it holds the origin: the lobe's axis, every sector) to its
// farthest vertex, its sectors over its vertices' azimuths. No sampling error: the bound is
// exact but for the 12-gon's 1 / cos(pi / 12) = 1.035 and a relative margin LOBE_RECT_EPS on
// the slope radius and in azimuth for float rounding (a micro-pixel's ray goes through normalize
// and reflect before it meets the node: ~1e-6). Where the polygon comes within delta of the
// horizon (d.N -> 0, the slopes unbounded) the disc widened by the stretch's largest
// magnification stands in (lobe_rect_stretched_wide). Straight-line code: llvmpipe's loop
// budget (65,535 iterations per invocation) is the lobe walk's, and a loop here spent it.
// Tests: tests/pbgi/test_lobe_anisotropic.py (brute force over every micro-pixel's rays: none a
// node can hit is outside; 1.19 micro-pixels per hit one, the widened disc 1.68; a 20% cut of the
// slope radius, the azimuths or the rectangle, or the 12-gon inscribed, misses some).
// Why it pays: the smallest micro-pixel a node covers is the tight rectangle's, so the cut
// accepts coarser nodes (fewer visits) and each tests fewer micro-pixels; the widened disc made
// an anisotropic glossy frame several times the isotropic one (README, "anisotropic", measured).
#define LOBE_RECT_EPS 1e-3

// lobe_rect through the stretch, wide: the node's disc of angular radius bh in true h maps to
// the mapping's space by h -> normalize(M h), M = diag(1 / sx, 1 / sy, 1), whose angular
// magnification is at most smax / |M h| (smax = max(sx, sy), M's largest singular value), and
// |M h| >= |M h_c| - smax bh over the disc (and >= 1 / smax, M's smallest): the rectangle covers
// the disc's image. Its smallest micro-pixel: the least slope area (at the lowest ring) times
// the least cos^3 (at the disc's largest true angle).
uint lobe_rect_stretched_wide(LobeFrame f, vec3 l, float sin_b, float cos_b, out float omega_min) {
    vec3 s = l + f.V;
    float len = length(s);
    float cos_d = 0.5 * len;                            // V.h_c = l.h_c
    float b = atan(sin_b, cos_b);
    float den = 2.0 * cos_d - b;
    uint full = (f.rings - 1u) << 8u | (f.sectors << 24u);
    float dphi = TWO_PI / float(f.sectors);
    float smax = max(f.st.x, f.st.y);
    LobePiece p = lobe_piece(f, false);
    if (den < 0.05) {                                   // the node spans the reflection's pole
        omega_min = 4.0 * max(cos_d, 1e-3)
                    * lobe_omega_h_stretched(p, 0.0, f.tan2_max * smax * smax, dphi);
        return full;
    }
    float bh = b / den;                                 // angular radius in true h (a bound)
    vec3 hc = s / len;
    vec3 q = vec3(dot(hc, f.T) / f.st.x, dot(hc, f.B) / f.st.y, dot(hc, f.N));
    float ql = length(q);
    float bm = min(bh * smax / max(ql - smax * bh, 1.0 / smax), PI);   // in the mapping
    vec3 hm = q / ql;
    float th = acos(clamp(hm.z, -1.0, 1.0));
    float lo, tan2_lo, tan2_hi;
    if (!lobe_band(f, th, bm, lo, tan2_lo, tan2_hi)) return 0xFFFFFFFFu;   // outside
    uint r0 = lobe_ring(f, tan2_lo);
    uint r1 = lobe_ring(f, tan2_hi);
    float tt = tan(min(acos(clamp(dot(hc, f.N), -1.0, 1.0)) + bh, 0.5 * PI - 1e-4));
    omega_min = 4.0 * cos_d * lobe_omega_h_stretched(p, tan2_lo, tt * tt, dphi);
    uvec2 sec = lobe_sectors(f, th, lo, bm, atan(hm.y, hm.x) - f.phi0, dphi);
    return r0 | (r1 << 8u) | (sec.x << 16u) | (sec.y << 24u);
}

// A monotone stand-in for the angle of w (not 0) in (-2, 2] (the "diamond angle": no atan per
// vertex), and its inverse.
float lobe_diamond(vec2 w) {
    float p = w.y / (abs(w.x) + abs(w.y));
    return w.x >= 0.0 ? p : (w.y >= 0.0 ? 2.0 - p : -2.0 - p);
}
float lobe_diamond_angle(float p) {
    float a = abs(p);
    return atan(a <= 1.0 ? p : sign(p) * (2.0 - a), 1.0 - a);
}

// The polygon's figures, edge by edge: farthest vertex, least distance to the origin, whether
// the origin is on both sides of its edges (outside it), its vertices' diamond angles about mc.
struct LobePoly { vec2 prev; float r2max, true2, dmin2, pmin, pmax; bool pos, neg; };

vec2 lobe_poly_vertex(inout LobePoly P, vec3 d, vec2 st) {
    vec2 mt = d.xy / d.z;                               // the true slope
    P.true2 = max(P.true2, dot(mt, mt));
    return mt / st;
}

void lobe_poly_edge(inout LobePoly P, vec2 c, vec2 mc) {
    vec2 a = P.prev, e = c - a;
    float cr = a.x * c.y - a.y * c.x;
    P.pos = P.pos || cr > 0.0;
    P.neg = P.neg || cr < 0.0;
    vec2 q = a + clamp(-dot(a, e) / max(dot(e, e), 1e-30), 0.0, 1.0) * e;
    P.dmin2 = min(P.dmin2, dot(q, q));
    P.r2max = max(P.r2max, dot(c, c));
    float pa = lobe_diamond(vec2(dot(mc, c), mc.x * c.y - mc.y * c.x));
    P.pmin = min(P.pmin, pa);
    P.pmax = max(P.pmax, pa);
    P.prev = c;
}

#define LOBE_POLY_STEP(c, s) lobe_poly_edge(P, lobe_poly_vertex(P, d0 + (c) * E1 + (s) * E2, f.st), mc)

uint lobe_rect_stretched(LobeFrame f, vec3 l, float sin_b, float cos_b, out float omega_min) {
    vec3 s = l + f.V;
    float cos_d = 0.5 * length(s);                      // V.h_c = l.h_c
    float smax = max(f.st.x, f.st.y);
    // The 12-gon in the receiver's frame (T, B, N), as d = P + V; delta: every d with
    // d.N < delta has |m| > sqrt(tan2_max) (|d| >= g, the distance from -V to the disc's plane,
    // and |m| >= |d.TB| / (smax d.N)), so a polygon above it holds all of the node in the domain.
    mat3 toF = transpose(mat3(f.T, f.B, f.N));
    vec3 e1, e2;
    orthonormal_basis(l, e1, e2);
    float rad = sin_b * 1.03527618;                     // 1 / cos(pi / 12)
    vec3 d0 = toF * (cos_b * l + f.V);
    vec3 E1 = toF * (rad * e1), E2 = toF * (rad * e2);
    float g = cos_b + dot(f.V, l);
    float delta = g / sqrt(1.0 + smax * smax * f.tan2_max);
    if (2.0 * cos_d - atan(sin_b, cos_b) < 0.05 || g <= 0.0
            || d0.z - length(vec2(E1.z, E2.z)) < delta)
        return lobe_rect_stretched_wide(f, l, sin_b, cos_b, omega_min);
    vec2 mc = d0.xy / (d0.z * f.st);                    // the disc's centre: inside the polygon
    LobePoly P;
    P.r2max = 0.0; P.true2 = 0.0; P.dmin2 = 1e30; P.pmin = 2.0; P.pmax = -2.0;
    P.pos = false; P.neg = false;
    vec2 first = lobe_poly_vertex(P, d0 + E1, f.st);
    P.prev = first;
    LOBE_POLY_STEP(0.8660254, 0.5);
    LOBE_POLY_STEP(0.5, 0.8660254);
    LOBE_POLY_STEP(0.0, 1.0);
    LOBE_POLY_STEP(-0.5, 0.8660254);
    LOBE_POLY_STEP(-0.8660254, 0.5);
    LOBE_POLY_STEP(-1.0, 0.0);
    LOBE_POLY_STEP(-0.8660254, -0.5);
    LOBE_POLY_STEP(-0.5, -0.8660254);
    LOBE_POLY_STEP(0.0, -1.0);
    LOBE_POLY_STEP(0.5, -0.8660254);
    LOBE_POLY_STEP(0.8660254, -0.5);
    lobe_poly_edge(P, first, mc);
    bool axis = !(P.pos && P.neg) || P.dmin2 <= LOBE_RECT_EPS * LOBE_RECT_EPS * P.r2max;
    float tan2_lo = axis ? 0.0 : P.dmin2 * (1.0 - 2.0 * LOBE_RECT_EPS);
    if (tan2_lo >= f.tan2_max) return 0xFFFFFFFFu;     // outside
    float tan2_hi = P.r2max * (1.0 + 2.0 * LOBE_RECT_EPS);
    uint r0 = lobe_ring(f, tan2_lo);
    uint r1 = lobe_ring(f, tan2_hi >= f.tan2_max ? 1e30 : tan2_hi);
    float dphi = TWO_PI / float(f.sectors);
    float true2 = min(P.true2, smax * smax * min(tan2_hi, f.tan2_max));
    omega_min = 4.0 * cos_d * lobe_omega_h_stretched(lobe_piece(f, false), tan2_lo, true2, dphi);
    uint s0 = 0u, ns = f.sectors;
    if (!axis) {
        float phic = atan(mc.y, mc.x) - f.phi0;
        float fa = floor((phic + lobe_diamond_angle(P.pmin) - LOBE_RECT_EPS) / dphi);
        uint cnt = uint(floor((phic + lobe_diamond_angle(P.pmax) + LOBE_RECT_EPS) / dphi) - fa) + 1u;
        if (cnt < f.sectors) {          // (GLSL's % is undefined for negative operands)
            s0 = uint(int(fa) + 8 * int(f.sectors)) % f.sectors;
            ns = cnt;
        }
    }
    return r0 | (r1 << 8u) | (s0 << 16u) | (ns << 24u);
}
#undef LOBE_POLY_STEP

// A cheap first cull for the walk, before lobe_rect's trigonometry: every direction of the
// lobe's domain lies within 2 theta_max of the mirror direction R = reflect(-V, N) (L is V
// reflected about h, and two reflections about h = N and h compose to a rotation by twice the
// angle between them, which moves no direction farther than that), so a node whose cone (axis
// l, angular radius b) lies wholly outside that cone of R holds no direction of the domain.
// theta_max: the domain's tan^2 bound, through the stretch's largest magnification for an
// anisotropic lobe. The node is culled when angle(l, R) > 2 theta_max + b, i.e. l.R below
// cos(2 theta_max + b) while that angle is below pi (its sine positive); a margin of
// LOBE_CONE_EPS in the cosine for float rounding. Nothing it culls can be hit by a lobe ray.
#define LOBE_CONE_EPS 1e-4
struct LobeCone { vec3 R; float c2, s2; };    // cos and sin of 2 theta_max

LobeCone lobe_cone(LobeFrame f) {
    float smax = max(f.st.x, f.st.y);
    float t2 = f.tan2_max * smax * smax;          // tan^2 theta_max (true half-vector)
    float c = 1.0 / (1.0 + t2);                   // cos^2 theta_max
    // cos 2t = 2 cos^2 t - 1, sin 2t = 2 sin t cos t
    return LobeCone(2.0 * dot(f.N, f.V) * f.N - f.V, 2.0 * c - 1.0,
                    2.0 * sqrt(max(c * (1.0 - c), 0.0)));
}

bool lobe_cone_outside(LobeCone k, vec3 l, float sin_b, float cos_b) {
    float sa = k.s2 * cos_b + k.c2 * sin_b;       // sin(2 theta_max + b)
    float ca = k.c2 * cos_b - k.s2 * sin_b;       // cos(2 theta_max + b)
    return sa > 0.0 && dot(l, k.R) < ca - LOBE_CONE_EPS;
}

uint lobe_rect_cells(uint r) { return (((r >> 8u) & 255u) - (r & 255u) + 1u) * (r >> 24u); }

// Walks the cells of a packed rectangle (rings r0..r1 x ns sectors from s0, wrapping) one per
// step without integer division (llvmpipe runs it lane by lane):
//   LobeCursor c = lobe_cursor(f, r);  ... c.cell ...;  lobe_cursor_next(f, c, r);
struct LobeCursor { uint cell; uint row_start; uint k; };   // cell, its ring's first cell, k-th of the ring
LobeCursor lobe_cursor(LobeFrame f, uint r) {
    uint row = (r & 255u) * f.sectors;
    return LobeCursor(row + ((r >> 16u) & 255u), row, 0u);
}
void lobe_cursor_next(LobeFrame f, inout LobeCursor c, uint r) {
    c.k++;
    if (c.k == (r >> 24u)) {                       // next ring, first sector
        c.k = 0u;
        c.row_start += f.sectors;
        c.cell = c.row_start + ((r >> 16u) & 255u);
    } else {
        c.cell++;
        if (c.cell == c.row_start + f.sectors) c.cell = c.row_start;   // wrap
    }
}
#endif
