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
//                     each through joint bilateral upsampling (Ritschel et al. 2009, Sec. 2.4;
//                     lib/joint_bilateral.glsl, shared with `scanlight render`'s gi_upsample.glsl);
//   else           =  the room's splat colour, or the background where no splat landed.
// Outputs: the linear composite (COMPOSITE_TEXEL, for EXR screenshots) and the display image
// (RGBA8: radiance x 2^EV, tone mapped by u_tonemap, sRGB encoded; or with u_false_colour the
// luminance's EV band, lib/tonemap.glsl false_colour). u_raw shows room colours as they are (false
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
// jbu_upsample, with the weights of app/pbgi/upsample.py
#include "lib/joint_bilateral.glsl"

layout(local_size_x = VIEW_TILE, local_size_y = VIEW_TILE) in;

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
uniform int u_tonemap;         // a TONEMAP_* index (injected from app/render/tonemap.py)
uniform int u_false_colour;    // 1: EV bands of the luminance instead of the tone-mapped colour
uniform int u_raw_room;        // 1: room colours bypass exposure and tone mapping
uniform int u_unavailable;
uniform ivec4 u_label_rect;    // x, y (bottom-left), w, h in pixels; w = 0: no label
uniform vec3 u_background;     // linear radiance where nothing was splatted
uniform int u_divider;         // the A/B compare's divider column (app/ui/compare.py); -1: none.
                               // Each side is its own dispatch clipped to its columns; this
                               // only draws the 2-pixel line on the display image

float linear_depth(float d) {
    float ndc = 2.0 * d - 1.0;
    return 2.0 * u_near * u_far / (u_far + u_near - ndc * (u_far - u_near));
}

vec3 display(vec3 linear_rgb, bool raw) {
    if (raw) return srgb_encode(tonemap_sanitize(linear_rgb));
    if (u_false_colour != 0) return false_colour(linear_rgb, u_exposure);
    return tonemap_to_srgb(linear_rgb, u_exposure, u_tonemap);
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
                vec4 c = jbu_upsample(u_full, u_full_size, u_size, p, g.normal, g.depth, pending);
                if (pending || c.w <= 0.0) {
                    bool unused;
                    c = jbu_upsample(u_preview, u_preview_size, u_size, p, g.normal, g.depth,
                                     unused);
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
    vec3 shown = display(out_rgb, u_raw_room != 0 && !asset);
    if (p.x == u_divider || p.x == u_divider - 1) shown = vec3(0.92);
    imageStore(u_display, p, vec4(shown, 1.0));
#endif
}
#endif
