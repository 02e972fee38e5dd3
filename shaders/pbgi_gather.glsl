// Final gather (paper eq. 9), shared by every mode: per receiver,
//   L_out(w_o) = sum_k f(w_k, w_o) L_k Omega_k (n . w_k)
// with the Disney Principled BRDF (lib/principled.glsl). Omega_k (n . w_k) is the micro-pixel's
// cosine-weighted solid angle from the table (its own solid angle, clipped at the horizon).
// With FRAME_NORMALS the micro-buffer is in the frame of another normal A (frames[i]: Hybrid's
// far-field sharing gives a block of receivers one frame); the weight becomes the cosine-weighted
// solid angle about the receiver's own normal, max(n . F_k, 0) with F_k the integral of w over the
// entry's region (app/pbgi/microbuffer.py's flux table; = Omega_ij (n . w_ij) for A = n). Only
// entries the receiver's horizon cuts are approximate, and directions above n's horizon but
// below A's are missing: a sliver as wide as the angle between n and A.
// L_k comes from the micro-buffer (the node's float32 colour) or, with RADIANCE_CUBEMAP, from the
// environment cube map in the same direction (the look-dev baseline): the two differ only in
// where the incoming radiance is read, never in how it is integrated.
// out_rgba[pixel] = (L_out, 1); alpha = -1 marks a gather loop the driver cut short.
#include "lib/common.glsl"
#include "lib/principled.glsl"
#include "lib/receivers.glsl"
#include "lib/bsh_textures.glsl"
#include "lib/microbuffer.glsl"

layout(local_size_x = 64) in;

layout(std430, binding = 6) readonly buffer Materials { vec4 materials[]; };  // 4 vec4 each
layout(std430, binding = 7) buffer Output { vec4 out_rgba[]; };

uniform uint u_first;
uniform uint u_count;
uniform int u_m;               // micro-buffer size M (the entry table is bound per M)
uniform vec3 u_camera;         // camera position relative to the hierarchy origin
#ifdef FRAME_NORMALS
layout(std430, binding = 8) readonly buffer Frames { vec4 frames[]; };   // per batch receiver
layout(binding = 7) uniform sampler2D mb_flux_tex;                        // (flux, solid angle)
#endif
#ifdef RADIANCE_CUBEMAP
layout(binding = 0) uniform samplerCube u_env;
uniform float u_env_texel_omega;   // solid angle of one cube-map texel at a face centre
#endif

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    uint rid = u_first + i;
    vec3 p = receiver_position(rid);
    vec3 N = receiver_normal(rid);
    vec4 tr = receiver_tangent_roughness(rid);
    vec4 bm = receiver_base_metallic(rid);
    uint mat = receiver_material(rid);
    PrincipledParams P = principled_from_vec4s(materials[4u * mat], materials[4u * mat + 1u],
                                               materials[4u * mat + 2u], materials[4u * mat + 3u].x);
    P.base_color = bm.rgb;
    P.metallic = bm.w;
    P.roughness = tr.w;

    vec3 V = normalize(u_camera - p);
    vec3 X = tr.xyz - N * dot(N, tr.xyz);
    vec3 T, B;
    orthonormal_basis(N, T, B);          // the micro-buffer frame
    X = dot(X, X) > 1e-12 ? normalize(X) : T;
    vec3 Y = cross(N, X);
#ifdef FRAME_NORMALS
    vec3 A = frames[i].xyz;
    orthonormal_basis(A, T, B);
    vec3 n_local = vec3(dot(N, T), dot(N, B), dot(N, A));   // the receiver's normal, A's frame
#else
    vec3 A = N;
#endif

    PrincipledPrepared Q = principled_prepare(P, V, N, X, Y);
    uint mm = mb_entries();
    vec3 sum = vec3(0.0);
    uint k;
    for (k = 0u; k < mm; ++k) {
        vec4 tb = mb_table(k);
        if (tb.w <= 0.0) continue;
        vec3 w = T * tb.x + B * tb.y + A * tb.z;
#ifdef FRAME_NORMALS
        vec4 fl = texelFetch(mb_flux_tex, ivec2(int(k), 0), 0);
        float weight = max(dot(n_local, fl.xyz), 0.0);
        if (weight <= 0.0) continue;
#else
        float weight = tb.w;
#endif
#ifdef RADIANCE_CUBEMAP
        float lod = 0.5 * log2(max(tb.w / max(tb.z, 1e-3) / u_env_texel_omega, 1.0));
        vec3 L = textureLod(u_env, w, lod).rgb;
#else
        uint node = mb_load(i, k).y;
        if (node == MB_EMPTY) continue;
        vec3 L = tnode_color(node);
#endif
        sum += principled_brdf_prepared(Q, w) * L * weight;
    }
    out_rgba[receiver_pixel(rid)] = vec4(sum, k == mm ? 1.0 : -1.0);
}
