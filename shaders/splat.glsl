// Point splatting of the room cloud: each point is a round, depth-tested, world-sized disc facing
// the camera. Output is linear HDR radiance (RGBA32F target); alpha = 1 marks covered pixels.
// Positions arrive relative to u_origin (done in float64 on the CPU) so 1e6 m offsets keep precision.
// Vertex inputs (SPLAT_VERTEX) and the output texel (ROOM_TEXEL) are declared in
// app/render/gpu_layout.py; gen/splat.glsl declares in_position, in_color and out_room.
#include "gen/splat.glsl"

#ifdef VERTEX_SHADER
uniform mat4 u_view;        // world (relative to the origin) -> eye
uniform mat4 u_proj;
uniform float u_radius;     // world-space splat radius (metres)
uniform float u_pixels_per_unit;  // viewport height / (2 tan(fov/2))
out vec3 v_color;
void main() {
    vec4 eye = u_view * vec4(in_position, 1.0);
    gl_Position = u_proj * eye;
    float dist = max(-eye.z, 1e-4);
    gl_PointSize = clamp(2.0 * u_radius * u_pixels_per_unit / dist, 2.0, 64.0);
    v_color = in_color;
}
#endif

#ifdef FRAGMENT_SHADER
in vec3 v_color;
uniform float u_scale;      // radiance multiplier (exposure is applied later, at tone mapping)
void main() {
    vec2 d = gl_PointCoord * 2.0 - 1.0;
    if (dot(d, d) > 1.0) discard;
    out_room = room_texel_pack(RoomTexel(v_color * u_scale, 1.0));
}
#endif
