// `scanlight render` at a render scale: the GI rendered at reduced resolution, upsampled to the
// camera's resolution with the viewer's joint bilateral weights (lib/joint_bilateral.glsl),
// guided by the full-resolution G-buffer of the asset (app/pbgi/upsample.py builds it from the
// PBGI G-buffer's receivers). A compute pass: full-screen fragment passes misbehave on llvmpipe.
// Numpy twin: tests/support/upsample.py (tests/pbgi/test_upsample.py compares the two).
//
// Per output pixel p (GL orientation, row 0 at the bottom, both inputs uploaded that way):
//   off the guide (depth 0)  -> (0, 0, 0, 0);
//   on the guide             -> (rgb, 1), alpha = the full-resolution coverage, rgb = the joint
//                               bilateral mean of the four taps (jbu_upsample, its four-tap
//                               fallback included); when none of the four taps is asset (a part
//                               thinner than a low-resolution pixel), the mean of the asset taps
//                               of the nearest square ring around them, up to FALLBACK_RINGS
//                               rings out; with none there either, black, and counted in
//                               u_unfilled (the stats say how many).
// Units, the work group and the accessors gi_at / guide_at: gen/gi_upsample.glsl
// (app/pbgi/upsample.py).

#ifdef COMPUTE_SHADER
#include "gen/gi_upsample.glsl"
#include "lib/joint_bilateral.glsl"

layout(local_size_x = UPSAMPLE_TILE, local_size_y = UPSAMPLE_TILE) in;

uniform ivec2 u_size;          // output (camera) resolution
uniform ivec2 u_lo;            // the GI image's resolution

// The mean of the asset taps on the square ring r around the four taps i0 .. i0 + 1
// (x or y in i0 - r .. i0 + 1 + r, on its border); taps outside the image are skipped.
vec4 ring_mean(ivec2 i0, int r) {
    vec3 acc = vec3(0.0);
    float n = 0.0;
    int side = 2 + 2 * r;
    for (int k = 0; k < side * side; ++k) {        // at most (2 + 2 FALLBACK_RINGS)^2 taps
        ivec2 d = ivec2(k % side, k / side) - r;
        if (d.x > -r && d.x < 1 + r && d.y > -r && d.y < 1 + r) continue;  // inside the ring
        ivec2 t = i0 + d;
        if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, u_lo))) continue;
        GiTexel s = gi_at(u_gi, t);
        if (s.status >= 0.5) { acc += s.radiance; n += 1.0; }
    }
    return vec4(acc, n);
}

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_size))) return;
    GuideTexel g = guide_at(p);
    vec4 outv = vec4(0.0);
    if (g.depth > 0.0) {
        bool pending;    // never: the GI image is complete
        vec4 c = jbu_upsample(u_gi, u_lo, u_size, p, g.normal, g.depth, pending);
        if (c.w <= 0.0) {
            ivec2 i0 = ivec2(floor((vec2(p) + 0.5) * vec2(u_lo) / vec2(u_size) - 0.5));
            for (int r = 1; r <= FALLBACK_RINGS && c.w <= 0.0; ++r) c = ring_mean(i0, r);
        }
        if (c.w > 0.0) {
            outv = vec4(c.rgb / c.w, 1.0);
        } else {
            outv = vec4(0.0, 0.0, 0.0, 1.0);
            atomicAdd(unfilled, 1u);
        }
    }
    imageStore(u_out, p, outv);
}
#endif
