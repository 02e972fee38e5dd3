// Applies tonemap_to_srgb (u_tonemap: a TONEMAP_* index; u_tonemap < 0: false_colour) to an array
// of colours (tests compare it with app/render/tonemap.py).
// in_rgb[i].xyz = linear colour; out_rgb[i] = (display sRGB, 1 = completed).
#include "lib/tonemap.glsl"

layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer InBuf { vec4 in_rgb[]; };
layout(std430, binding = 1) writeonly buffer OutBuf { vec4 out_rgb[]; };

uniform uint u_count;
uniform float u_exposure_stops;
uniform int u_tonemap;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    vec3 c = u_tonemap < 0 ? false_colour(in_rgb[i].xyz, u_exposure_stops)
                           : tonemap_to_srgb(in_rgb[i].xyz, u_exposure_stops, u_tonemap);
    out_rgb[i] = vec4(c, 1.0);
}
