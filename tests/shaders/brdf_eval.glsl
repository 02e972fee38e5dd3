// Evaluates principled_brdf for arrays of cases (tests compare it with app/pbgi/brdf.py).
// Per case i: params[13 i .. 13 i + 12] in the packing of lib/principled.glsl, dirs[5 i + k]
// = L, V, N, X, Y (xyz). Output: out_data[2 i] = (f.rgb, 1) and out_data[2 i + 1] = (0, 0, 0, 1)
// for u_mode 0 (given X, Y), 1 (principled_brdf_iso: frame from orthonormal_basis(N)) and
// 3 (as 0, parameters unpacked with principled_from_vec4s), 4 (principled_prepare +
// principled_brdf_prepared, the gather's split);
// for u_mode 2 the two outputs are orthonormal_basis(N) = (t, 1), (b, 1).
// w = 1 marks a completed invocation.
#include "lib/principled.glsl"

layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer ParamBuf { float params[]; };
layout(std430, binding = 1) readonly buffer DirBuf { vec4 dirs[]; };
layout(std430, binding = 2) writeonly buffer OutBuf { vec4 out_data[]; };

uniform uint u_count;
uniform int u_mode;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    float v[PRINCIPLED_PARAM_COUNT];
    uint base = i * uint(PRINCIPLED_PARAM_COUNT);
    for (int k = 0; k < PRINCIPLED_PARAM_COUNT; ++k) v[k] = params[base + uint(k)];
    PrincipledParams p = u_mode == 3
        ? principled_from_vec4s(vec4(v[0], v[1], v[2], v[3]), vec4(v[4], v[5], v[6], v[7]),
                                vec4(v[8], v[9], v[10], v[11]), v[12])
        : principled_from_floats(v);
    vec3 L = dirs[5u * i].xyz, V = dirs[5u * i + 1u].xyz, N = dirs[5u * i + 2u].xyz;
    vec3 X = dirs[5u * i + 3u].xyz, Y = dirs[5u * i + 4u].xyz;
    if (u_mode == 2) {
        vec3 t, b;
        orthonormal_basis(N, t, b);
        out_data[2u * i] = vec4(t, 1.0);
        out_data[2u * i + 1u] = vec4(b, 1.0);
        return;
    }
    vec3 f = u_mode == 1 ? principled_brdf_iso(p, L, V, N)
           : u_mode == 4 ? principled_brdf_prepared(principled_prepare(p, V, N, X, Y), L)
           : principled_brdf(p, L, V, N, X, Y);
    out_data[2u * i] = vec4(f, 1.0);
    out_data[2u * i + 1u] = vec4(0.0, 0.0, 0.0, 1.0);
}
