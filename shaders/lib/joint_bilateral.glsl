// Joint bilateral upsampling of a reduced-resolution GI image guided by a full-resolution
// G-buffer (Ritschel et al. 2009, Sec. 2.4), shared by the viewer (viewer_composite.glsl) and
// `scanlight render` at a render scale (gi_upsample.glsl), so both weigh taps the same way.
// Numpy twin: app/ui/composite.py (upsample); the weights are app/pbgi/upsample.py's.
//
// Output pixel p (size) with guide normal n_p and eye depth z_p; its four bilinear taps t in the
// low-resolution image (lo), at q = (p + 0.5) lo / size - 0.5. Each tap weighs
//   bilinear x [tap is asset] x exp(-NORMAL_SHARPNESS (1 - n_p.n_q)) x
//   exp(-|z_p - z_q| / (DEPTH_TOLERANCE z_p)),
// with (n_q, z_q) the guide at the tap's centre, or bilinear x OFF_GUIDE_WEIGHT when that centre
// misses the rasterised asset (a weak vote), never below 1e-6 x bilinear. Taps whose bilinear
// weight is 0 are ignored; with no usable tap, the mean of whichever of the four taps are asset
// (a silhouette thinner than a low-resolution pixel).
//
// The including shader declares before the include: GiTexel gi_at(sampler2D, ivec2) and
// GuideTexel guide_at(ivec2) (gen/viewer_texels.glsl's records, GL orientation).

#ifndef SCANLIGHT_LIB_JOINT_BILATERAL_GLSL
#define SCANLIGHT_LIB_JOINT_BILATERAL_GLSL
#include "gen/joint_bilateral.glsl"

// The tap's centre in the full-resolution guide.
ivec2 jbu_guide_pixel(ivec2 t, ivec2 lo, ivec2 size) {
    return clamp(ivec2((vec2(t) + 0.5) * vec2(size) / vec2(lo)), ivec2(0), size - 1);
}

// The weight of one tap of bilinear weight wb > 0 whose centre has the guide texel gq.
float jbu_weight(float wb, vec3 n_p, float z_p, GuideTexel gq) {
    float w = wb;
    if (gq.depth > 0.0) {
        w *= exp(-NORMAL_SHARPNESS * (1.0 - clamp(dot(n_p, gq.normal), -1.0, 1.0)));
        w *= exp(-abs(gq.depth - z_p) / (DEPTH_TOLERANCE * z_p + 1e-4));
    } else {
        w *= OFF_GUIDE_WEIGHT;  // the tap's centre misses the rasterised asset: a weak vote
    }
    return max(w, 1e-6 * wb);
}

// Returns (rgb sum, weight sum) for output pixel p. pending: a tap that would count has not been
// rendered yet (GiTexel.status < 0, the viewer's tiles in progress).
vec4 jbu_upsample(sampler2D tex, ivec2 lo, ivec2 size, ivec2 p, vec3 n_p, float z_p,
                  out bool pending) {
    pending = false;
    vec2 q = (vec2(p) + 0.5) * vec2(lo) / vec2(size) - 0.5;
    ivec2 i0 = ivec2(floor(q));
    vec2 f = q - vec2(i0);
    vec3 acc = vec3(0.0);
    float wsum = 0.0;
    for (int dy = 0; dy < 2; ++dy) {
        for (int dx = 0; dx < 2; ++dx) {
            float wb = (dx == 0 ? 1.0 - f.x : f.x) * (dy == 0 ? 1.0 - f.y : f.y);
            if (wb <= 0.0) continue;
            ivec2 t = clamp(i0 + ivec2(dx, dy), ivec2(0), lo - 1);
            GiTexel s = gi_at(tex, t);
            if (s.status < 0.0) { pending = true; continue; }
            if (s.status < 0.5) continue;
            float w = jbu_weight(wb, n_p, z_p, guide_at(jbu_guide_pixel(t, lo, size)));
            acc += w * s.radiance;
            wsum += w;
        }
    }
    if (wsum > 0.0 || pending) return vec4(acc, wsum);
    // Fallback: the mean of the asset taps among the four, whatever their bilinear weight.
    for (int k = 0; k < 4; ++k) {
        ivec2 t = clamp(i0 + ivec2(k & 1, k >> 1), ivec2(0), lo - 1);
        GiTexel s = gi_at(tex, t);
        if (s.status >= 0.5) { acc += s.radiance; wsum += 1.0; }
    }
    return vec4(acc, wsum);
}
#endif
