// Display transform: exposure (stops) -> a tone mapper -> sRGB encoding; and the false-colour EV
// view. Numpy twin: app/render/tonemap.py (same formulas; tests/render/test_tonemap.py compares
// them for every tone mapper).
//
// The tone mappers' indices (TONEMAP_PBR_NEUTRAL, TONEMAP_ACES, ...) and the false-colour bands
// are generated from the Python registry (gen/tonemap.glsl: app.render.tonemap.glsl_header), so the
// order is declared once, there. See that module for which ACES fit and which AgX.
// Robustness: NaN becomes 0, negatives 0 and values are capped at 1e30 before mapping, so any
// input (HDR panoramas carry negative pixels and 65504s) maps to finite [0, 1].
#ifndef SCANLIGHT_TONEMAP_GLSL
#define SCANLIGHT_TONEMAP_GLSL

#include "gen/tonemap.glsl"

const float TONEMAP_MAX_INPUT = 1e30;

vec3 tonemap_sanitize(vec3 c) {
    c = mix(c, vec3(0.0), isnan(c));
    return clamp(c, 0.0, TONEMAP_MAX_INPUT);
}

// Khronos PBR Neutral (2024): base colours up to ~0.8 unchanged (only a small toe offset for
// dark values), highlights compressed towards white with mild desaturation.
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

// Stephen Hill's fitted ACES RRT + sRGB ODT (BakingLab ACES.hlsl). Matrix rows as in the HLSL
// (mul(M, v)); the fit's input is capped at 1e15 so v * v stays inside float32.
vec3 tonemap_aces(vec3 c) {
    vec3 v = vec3(dot(vec3(0.59719, 0.35458, 0.04823), c),
                  dot(vec3(0.07600, 0.90834, 0.01566), c),
                  dot(vec3(0.02840, 0.13383, 0.83777), c));
    v = min(v, vec3(1e15));
    vec3 a = v * (v + 0.0245786) - 0.000090537;
    vec3 b = v * (0.983729 * v + 0.4329510) + 0.238081;
    v = a / b;
    return clamp(vec3(dot(vec3(1.60475, -0.53108, -0.07367), v),
                      dot(vec3(-0.10208, 1.10813, -0.00605), v),
                      dot(vec3(-0.00327, -0.07276, 1.07602), v)), 0.0, 1.0);
}

// AgX base (sobotka/AgX config.ocio: inset, log2 over -12.47393 .. 4.026069 = 0.18 x 2^-10 ..
// 0.18 x 2^6.5), Wrensch's polynomial fit of the default-contrast sigmoid, the outset (the
// inset's inverse) and a 2.2 power back to display-linear.
vec3 tonemap_agx(vec3 c) {
    const float min_ev = -12.47393;
    const float max_ev = 4.026069;
    vec3 v = vec3(dot(vec3(0.842479062253094, 0.0784335999999992, 0.0792237451477643), c),
                  dot(vec3(0.0423282422610123, 0.878468636469772, 0.0791661274605434), c),
                  dot(vec3(0.0423756549057051, 0.0784336, 0.879142973793104), c));
    v = clamp(log2(max(v, vec3(exp2(min_ev)))), min_ev, max_ev);
    vec3 x = (v - min_ev) / (max_ev - min_ev);
    vec3 x2 = x * x;
    vec3 x4 = x2 * x2;
    vec3 y = 15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2
             + 0.1191 * x - 0.00232;
    y = clamp(y, 0.0, 1.0);
    y = vec3(dot(vec3(1.1968790051201739, -0.09802088114013677, -0.09902974407972047), y),
             dot(vec3(-0.052896851757456176, 1.1519031299041727, -0.09896117684484335), y),
             dot(vec3(-0.05297163551444379, -0.0980434501171241, 1.151073672641161), y));
    return pow(clamp(y, 0.0, 1.0), vec3(2.2));
}

// sRGB OETF (IEC 61966-2-1) of linear [0, 1] (clamped).
vec3 srgb_encode(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    vec3 lo = c * 12.92;
    vec3 hi = 1.055 * pow(max(c, vec3(0.0031308)), vec3(1.0 / 2.4)) - 0.055;
    return mix(hi, lo, lessThanEqual(c, vec3(0.0031308)));
}

// Sanitised, exposed radiance through tone mapper `which` (a TONEMAP_* index), display-linear.
vec3 tonemap_curve(vec3 c, int which) {
    if (which == TONEMAP_ACES) return tonemap_aces(c);
    if (which == TONEMAP_AGX) return tonemap_agx(c);
    if (which == TONEMAP_CLAMP) return clamp(c, 0.0, 1.0);
    return tonemap_pbr_neutral(c);
}

// Linear scene radiance -> display-encoded sRGB in [0, 1].
vec3 tonemap_to_srgb(vec3 linear_rgb, float exposure_stops, int which) {
    vec3 c = tonemap_sanitize(tonemap_sanitize(linear_rgb) * exp2(exposure_stops));
    return srgb_encode(tonemap_curve(c, which));
}

vec3 tonemap_to_srgb(vec3 linear_rgb, float exposure_stops) {
    return tonemap_to_srgb(linear_rgb, exposure_stops, TONEMAP_PBR_NEUTRAL);
}

// False-colour EV view: luminance x 2^EV in stops around FALSE_COLOUR_GREY, as the display colour
// of its band (FALSE_COLOUR_EDGES ascending; FALSE_COLOUR_RGB one more than the edges).
vec3 false_colour(vec3 linear_rgb, float exposure_stops) {
    float y = dot(tonemap_sanitize(linear_rgb), TONEMAP_LUMA) * exp2(exposure_stops);
    // y = 0 (log2 undefined) is below every band
    float ev = y > 0.0 ? log2(min(y, TONEMAP_MAX_INPUT) / FALSE_COLOUR_GREY) : -1e30;
    const float edges[] = FALSE_COLOUR_EDGES;
    const vec3 colours[] = FALSE_COLOUR_RGB;
    int band = 0;
    for (int i = 0; i < FALSE_COLOUR_BANDS - 1; ++i) band += ev >= edges[i] ? 1 : 0;
    return colours[band];
}
#endif
