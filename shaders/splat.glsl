// Surface splatting of the room cloud: each point is a disc of its own radius in the plane of its
// normal (a ray-disc intersection per fragment, so the depth is the disc's, not the sprite's).
// Positions arrive relative to the cloud's origin (done in float64 on the CPU) so 1e6 m offsets
// keep precision. Vertex inputs (SPLAT_VERTEX) and the output texel (ROOM_TEXEL) are declared in
// app/render/gpu_layout.py; gen/splat.glsl declares in_position, in_color, in_normal, in_radius
// out_room, out_depth_sum and the texture units SPLAT_TEX_*. app/render/splat.py runs the
// passes (SPLAT_PASS, injected):
//   0 OPAQUE: one depth-tested pass, ROOM_TEXEL(colour x scale, 1) and the eye depth
//             (SplatRenderer.draw; labels, where colours must not mix);
//   1 DEPTH:  the front surface's depth only (visibility);
//   2 ACCUM:  additive; splats within u_eps x radius of the front surface add
//             ROOM_TEXEL(w x colour x scale, w) and w x eye depth (out_depth_sum), where w is a
//             truncated Gaussian of the distance to the disc's centre. splat_resolve.glsl divides.
//   3 FAST:   while the viewer's camera moves: a camera-facing round sprite of the disc's
//             projected size at its centre's depth, opaque, no ray-disc test and no written
//             depth (so llvmpipe rejects hidden fragments early); no hole filling follows.
#include "gen/splat.glsl"

#ifndef SPLAT_PASS
#define SPLAT_PASS 0
#endif
// a disc seen closer to edge-on than |cos| = MIN_COS is tilted towards the camera until it is
// at MIN_COS: a sliver would leave gaps through which the surface behind shows (injected by
// app/render/splat.py)
#ifndef MIN_COS
#define MIN_COS 0.4
#endif
// Gaussian weight exp(-WEIGHT_SHARPNESS (d/r)^2), cut at d = r (about 0.14 at the rim)
#define WEIGHT_SHARPNESS 2.0

uniform mat4 u_proj;
uniform vec2 u_viewport;    // target size in pixels

#ifdef VERTEX_SHADER
uniform mat4 u_view;        // world (relative to the origin) -> eye
uniform float u_radius;     // global splat radius (metres); in_radius scales it per point
uniform float u_max_point;  // the GL's largest point size
uniform float u_near;
flat out vec3 v_center;     // eye space
flat out vec3 v_normal;     // eye space, unit
flat out float v_r;         // world radius
flat out vec3 v_color;
flat out float v_keep;      // FAST: the disc's share of the sprite's half-size
void main() {
    vec3 c = (u_view * vec4(in_position, 1.0)).xyz;
    vec3 n = mat3(u_view) * in_normal;
    // never below a pixel's size at its depth: a smaller disc falls between the pixel centres'
    // rays and vanishes (a lone point, a sparse cloud seen from afar, a small cube-map face)
    float pixel = 2.0 * max(-c.z, u_near) / (u_proj[1][1] * u_viewport.y);
    float r = max(u_radius * in_radius, pixel);
    v_center = c;
    v_normal = dot(n, n) > 0.0 ? normalize(n) : vec3(0.0, 0.0, 1.0);
    v_r = r;
    v_color = in_color;
    gl_Position = u_proj * vec4(c, 1.0);
    // the sprite must hold the disc's projection: bound it by the projection of the disc's
    // bounding cube (its nearest and farthest depths), half-extents about the projected centre
    float zc = -c.z, zn = zc - r, zf = zc + r;
    if (zf <= u_near) {             // wholly behind the near plane
        gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
        gl_PointSize = 1.0;
        return;
    }
    if (zn <= u_near) {
        gl_PointSize = u_max_point;
        return;
    }
    // the disc's bounding sphere projects to an ellipse around the projected centre whose
    // semi-major axis is at most f r / (zn cos^2 t), t the angle off the view axis (zn: its
    // nearest depth); the bounding cube's projection used before was up to several times wider,
    // and every fragment of the sprite pays the ray-disc test (gl_FragDepth: no early depth test)
    float cos_t = zc / length(c);
    float half_px = u_proj[1][1] * 0.5 * u_viewport.y * r / (zn * cos_t * cos_t);
    gl_PointSize = clamp(2.0 * half_px + 2.0, 1.0, u_max_point);
    float r_px = u_proj[1][1] * 0.5 * u_viewport.y * r / zc;
    v_keep = min(1.0, (r_px + 0.5) / (0.5 * gl_PointSize));
}
#endif

#ifdef FRAGMENT_SHADER
flat in vec3 v_center;
flat in vec3 v_normal;
flat in float v_r;
flat in vec3 v_color;
flat in float v_keep;
uniform float u_scale;      // radiance multiplier (exposure is applied later, at tone mapping)
#if SPLAT_PASS == 2
layout(binding = SPLAT_TEX_FRONT) uniform sampler2D u_front;  // the DEPTH pass's window depth
uniform float u_eps;        // a splat counts within u_eps x its radius behind the front surface
float eye_depth(float window) {     // u_proj's inverse along z (symmetric perspective)
    return u_proj[3][2] / ((window * 2.0 - 1.0) + u_proj[2][2]);
}
#endif
void main() {
#if SPLAT_PASS == 3
    vec2 d = gl_PointCoord * 2.0 - 1.0;
    if (dot(d, d) > v_keep * v_keep) discard;
    out_room = room_texel_pack(RoomTexel(v_color * u_scale, 1.0));
    out_depth_sum = -v_center.z;
#else
    vec2 ndc = gl_FragCoord.xy / u_viewport * 2.0 - 1.0;
    vec3 dir = vec3(ndc.x / u_proj[0][0], ndc.y / u_proj[1][1], -1.0);  // eye ray, z = -1
    vec3 v = -normalize(v_center);          // towards the camera
    vec3 n = dot(v_normal, v) < 0.0 ? -v_normal : v_normal;
    float c = dot(n, v);
    if (c < MIN_COS) {
        vec3 t = n - c * v;                 // in-plane part; zero length only if c = 1
        n = dot(t, t) > 1e-12 ? MIN_COS * v + sqrt(1.0 - MIN_COS * MIN_COS) * normalize(t) : v;
    }
    float t = dot(v_center, n) / dot(dir, n);
    vec3 p = t * dir;
    vec3 off = p - v_center;
    float q = dot(off, off) / (v_r * v_r);
    if (q > 1.0 || t <= 0.0) discard;
    vec4 clip = u_proj * vec4(p, 1.0);
    float window = clip.z / clip.w * 0.5 + 0.5;
    if (window < 0.0 || window > 1.0) discard;
    gl_FragDepth = window;
#if SPLAT_PASS == 2
    float front = eye_depth(texelFetch(u_front, ivec2(gl_FragCoord.xy), 0).r);
    if (t > front + u_eps * v_r) discard;     // t = eye depth of p (dir.z = -1)
    float w = exp(-WEIGHT_SHARPNESS * q);
    out_room = room_texel_pack(RoomTexel(v_color * u_scale * w, w));
    out_depth_sum = w * t;
#else
    out_room = room_texel_pack(RoomTexel(v_color * u_scale, 1.0));
    out_depth_sum = t;
#endif
#endif
}
#endif
