// The viewer's per-pixel composite (compute passes: full-screen fragment passes misbehave on
// llvmpipe). Numpy twin: app/ui/composite.py (tests compare the two).
//
// Three programs from this file, each dispatched over a rectangle (u_offset, u_extent), because
// llvmpipe pays for every instruction of a branch whether or not a pixel takes it:
//   (default)    the whole frame, room only (cheap);
//   ASSET_PASS   the asset's screen rectangle: everything below, room or asset per pixel;
//   LABEL_PASS   the label's rectangle: blends u_label over the display image.
// After a GI update only the asset and label passes run again.
//
// Per viewport pixel p (GL orientation, row 0 at the bottom, every input uploaded that way):
//   asset visible  <=> G-buffer covers p and the asset is not behind the room's splat depth;
//   asset colour   =  the full-resolution GI layer when its taps are rendered, else the preview,
//                     each through joint bilateral upsampling (Ritschel et al. 2009, Sec. 2.4):
//                     bilinear weight x [tap is asset] x exp(-NORMAL_SHARPNESS (1 - n_p.n_q)) x
//                     exp(-|z_p - z_q| / (DEPTH_TOLERANCE z_p)), q = the tap's centre in the
//                     G-buffer (OFF_GUIDE_WEIGHT when q is off the asset);
//                     taps whose bilinear weight is 0 are ignored; with no usable tap, the mean
//                     of whichever of the four taps are asset (thin parts at low res);
//   else           =  the room's splat colour, or the background where no splat landed.
// Outputs: the linear composite (COMPOSITE_TEXEL, for EXR screenshots) and the display image
// (RGBA8: radiance x 2^EV, tone mapped, sRGB encoded). u_raw shows room colours as they are (false
// colour difference maps). u_unavailable hatches the asset and overlays u_label (a text image).
//
// Texture and image units, the texel records (RoomTexel, GuideTexel, GiTexel, CompositeTexel)
// and the work-group size are declared in app/render/gpu_layout.py; gen/viewer_composite.glsl
// declares the samplers u_room ... u_label, the images u_linear and u_display, and room_at,
// guide_at, gi_at, composite_store.

#ifdef COMPUTE_SHADER
#ifdef LABEL_PASS
#define VIEW_DISPLAY_READABLE 1
#endif
#include "gen/viewer_composite.glsl"
#include "lib/tonemap.glsl"

layout(local_size_x = VIEW_TILE, local_size_y = VIEW_TILE) in;

// Weights of the joint bilateral upsampling, injected from app/ui/composite.py (defaults here
// only so the file compiles on its own).
#ifndef NORMAL_SHARPNESS
#define NORMAL_SHARPNESS 8.0
#endif
#ifndef DEPTH_TOLERANCE
#define DEPTH_TOLERANCE 0.05
#endif
#ifndef OFF_GUIDE_WEIGHT
#define OFF_GUIDE_WEIGHT 0.05
#endif
// The asset wins ties with the room within ROOM_DEPTH_SCALE x + ROOM_DEPTH_BIAS (injected too).
#ifndef ROOM_DEPTH_SCALE
#define ROOM_DEPTH_SCALE 1.002
#endif
#ifndef ROOM_DEPTH_BIAS
#define ROOM_DEPTH_BIAS 1e-3
#endif

uniform ivec2 u_size;
uniform ivec2 u_offset;        // this dispatch's rectangle (pixels, GL orientation)
uniform ivec2 u_extent;
uniform ivec2 u_preview_size;
uniform ivec2 u_full_size;
uniform float u_near;          // the splat pass's projection, to linearise its depth
uniform float u_far;
uniform float u_exposure;      // stops (EV)
uniform int u_tonemap;         // 0 = PBR Neutral, 1 = clamp
uniform int u_raw_room;        // 1: room colours bypass exposure and tone mapping
uniform int u_unavailable;
uniform ivec4 u_label_rect;    // x, y (bottom-left), w, h in pixels; w = 0: no label
uniform vec3 u_background;     // linear radiance where nothing was splatted

float linear_depth(float d) {
    float ndc = 2.0 * d - 1.0;
    return 2.0 * u_near * u_far / (u_far + u_near - ndc * (u_far - u_near));
}

// Joint bilateral upsampling of one GI image; returns (rgb, weight). pending: a tap that would
// count has not been rendered yet.
vec4 upsample(sampler2D tex, ivec2 lo, ivec2 p, vec3 n_p, float z_p, out bool pending) {
    pending = false;
    vec2 q = (vec2(p) + 0.5) * vec2(lo) / vec2(u_size) - 0.5;
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
            ivec2 g = clamp(ivec2((vec2(t) + 0.5) * vec2(u_size) / vec2(lo)), ivec2(0), u_size - 1);
            GuideTexel gq = guide_at(g);
            float w = wb;
            if (gq.depth > 0.0) {
                w *= exp(-NORMAL_SHARPNESS * (1.0 - clamp(dot(n_p, gq.normal), -1.0, 1.0)));
                w *= exp(-abs(gq.depth - z_p) / (DEPTH_TOLERANCE * z_p + 1e-4));
            } else {
                w *= OFF_GUIDE_WEIGHT;  // the tap's centre misses the rasterised asset: a weak vote
            }
            w = max(w, 1e-6 * wb);
            acc += w * s.radiance;
            wsum += w;
        }
    }
    if (wsum > 0.0 || pending) return vec4(acc, wsum);
    // Fallback (silhouette thinner than a low-resolution pixel): the mean of the asset taps
    // among the four, whatever their bilinear weight.
    for (int k = 0; k < 4; ++k) {
        ivec2 t = clamp(i0 + ivec2(k & 1, k >> 1), ivec2(0), lo - 1);
        GiTexel s = gi_at(tex, t);
        if (s.status >= 0.5) { acc += s.radiance; wsum += 1.0; }
    }
    return vec4(acc, wsum);
}

vec3 display(vec3 linear_rgb, bool raw) {
    if (raw) return srgb_encode(tonemap_sanitize(linear_rgb));
    if (u_tonemap == 0) return tonemap_to_srgb(linear_rgb, u_exposure);
    return srgb_encode(tonemap_sanitize(tonemap_sanitize(linear_rgb) * exp2(u_exposure)));
}

void main() {
    ivec2 p = u_offset + ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, min(u_offset + u_extent, u_size)))) return;
#ifdef LABEL_PASS
    ivec2 l = p - u_label_rect.xy;
    vec4 t = texelFetch(u_label, l, 0);
    vec4 shown = imageLoad(u_display, p);
    imageStore(u_display, p, vec4(mix(shown.rgb, t.rgb, t.a), 1.0));
#else
    RoomTexel room = room_at(p);
    vec3 room_rgb = room.coverage > 0.0 ? room.radiance : u_background;
    vec3 out_rgb = room_rgb;
    bool asset = false;
#ifdef ASSET_PASS
    GuideTexel g = guide_at(p);
    if (g.depth > 0.0) {
        float room_z = room.coverage > 0.0 ? linear_depth(texelFetch(u_room_depth, p, 0).r) : 1e30;
        if (g.depth <= room_z * ROOM_DEPTH_SCALE + ROOM_DEPTH_BIAS) {
            if (u_unavailable != 0) {
                asset = true;
                out_rgb = vec3(((p.x + p.y) / 6) % 2 == 0 ? 0.10 : 0.16);
            } else {
                bool pending;
                vec4 c = upsample(u_full, u_full_size, p, g.normal, g.depth, pending);
                if (pending || c.w <= 0.0) {
                    bool unused;
                    c = upsample(u_preview, u_preview_size, p, g.normal, g.depth, unused);
                }
                if (c.w > 0.0) {
                    asset = true;
                    out_rgb = c.rgb / c.w;
                }
            }
        }
    }
#endif
    composite_store(p, CompositeTexel(out_rgb, asset ? 1.0 : 0.0));
    imageStore(u_display, p, vec4(display(out_rgb, u_raw_room != 0 && !asset), 1.0));
#endif
}
#endif
