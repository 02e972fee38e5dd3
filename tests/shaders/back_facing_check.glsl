// Evaluates lib/pbgi_cut.glsl's cut_back_facing (paper Fig. 5) per case, for
// tests/pbgi/test_pbgi_microbuffer.py: cases[2 i] = (cone axis, cos of its half-angle alpha),
// cases[2 i + 1] = (unit direction l from the receiver to the node, sin b of the node's angular
// radius). Output per case: 1 culled, 0 kept, + 2 marks a completed invocation.
#include "lib/common.glsl"
#include "lib/bsh_textures.glsl"
#include "lib/microbuffer.glsl"
#include "lib/pbgi_cut.glsl"

layout(local_size_x = 16) in;

layout(std430, binding = 0) readonly buffer CaseBuf { vec4 cases[]; };
layout(std430, binding = 1) writeonly buffer OutBuf { uint out_data[]; };

uniform uint u_count;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    vec4 a = cases[2u * i], d = cases[2u * i + 1u];
    float sin_b = d.w;
    bool culled = cut_back_facing(BshCone(a.xyz, a.w), d.xyz, sin_b,
                                  sqrt(max(1.0 - sin_b * sin_b, 0.0)));
    out_data[i] = (culled ? 1u : 0u) + 2u;
}
