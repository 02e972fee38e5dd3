// Display transform: exposure (stops) -> Khronos PBR Neutral tone mapper -> sRGB encoding.
// Numpy twin: app/render/tonemap.py (same formula; tests/test_tonemap.py compares them).
//
// PBR Neutral (Khronos, 2024) keeps base colours up to ~0.8 unchanged (only a small toe offset
// for dark values) and compresses highlights towards white with mild desaturation.
// Robustness: NaN becomes 0, negatives 0 and values are capped at 1e30 before mapping, so any
// input (HDR panoramas carry negative pixels and 65504s) maps to finite [0, 1].
#ifndef SCANLIGHT_TONEMAP_GLSL
#define SCANLIGHT_TONEMAP_GLSL

const float TONEMAP_MAX_INPUT = 1e30;

vec3 tonemap_sanitize(vec3 c) {
    c = mix(c, vec3(0.0), isnan(c));
    return clamp(c, 0.0, TONEMAP_MAX_INPUT);
}

vec3 tonemap_pbr_neutral(vec3 color) {
    const float start_compression = 0.8 - 0.04;
    const float desaturation = 0.15;
    float x = min(color.r, min(color.g, color.b));
    float offset = x < 0.08 ? x - 6.25 * x * x : 0.04;
    color -= offset;
    float peak = max(color.r, max(color.g, color.b));
    if (peak < start_compression) return color;
    const float d = 1.0 - start_compression;
    float new_peak = 1.0 - d * d / (peak + d - start_compression);
    color *= new_peak / peak;
    float g = 1.0 - 1.0 / (desaturation * (peak - new_peak) + 1.0);
    return mix(color, vec3(new_peak), g);
}

// sRGB OETF (IEC 61966-2-1) of linear [0, 1] (clamped).
vec3 srgb_encode(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    vec3 lo = c * 12.92;
    vec3 hi = 1.055 * pow(max(c, vec3(0.0031308)), vec3(1.0 / 2.4)) - 0.055;
    return mix(hi, lo, lessThanEqual(c, vec3(0.0031308)));
}

// Linear scene radiance -> display-encoded sRGB in [0, 1].
vec3 tonemap_to_srgb(vec3 linear_rgb, float exposure_stops) {
    vec3 c = tonemap_sanitize(tonemap_sanitize(linear_rgb) * exp2(exposure_stops));
    return srgb_encode(tonemap_pbr_neutral(c));
}
#endif
