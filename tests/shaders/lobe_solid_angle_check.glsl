// lib/lobe.glsl's micro-pixel solid angle in half-vector space, for
// tests/pbgi/test_lobe_anisotropic.py: per case i (cases[i] = (aw, amax, rings, 0)) the frame
// of lobe_frame, and the sum of lobe_omega_h over its rings x 64 sectors, each cell's mean over
// 64 points of its ring (the positions its jittered ray takes). Output per
// case: (sum, tan^2 of the domain's edge, split ring, 1): the sum is the domain's solid angle
// 2 pi (1 - cos theta_max) when each cell's solid angle follows the warp's Jacobian.
#include "lib/common.glsl"
#include "lib/principled.glsl"
#include "lib/lobe.glsl"

layout(local_size_x = 16) in;

layout(std430, binding = 0) readonly buffer CaseBuf { vec4 cases[]; };
layout(std430, binding = 1) writeonly buffer OutBuf { vec4 out_data[]; };

uniform uint u_count;

void main() {
    uint c = gl_GlobalInvocationID.x;
    if (c >= u_count) return;
    vec4 k = cases[c];
    uint rings = uint(k.z), sectors = 64u;
    LobeFrame f = lobe_frame(vec3(0.0, 0.0, 1.0), vec3(0.0, 0.0, 1.0), k.x, k.y, 0.0, 0u, 0u, rings,
                             sectors);
    float dphi = TWO_PI / float(sectors), sum = 0.0;
    for (uint i = 0u; i < rings; ++i) {
        LobePiece p = lobe_piece(f, i >= f.split);
        for (uint s = 0u; s < 64u; ++s) {      // a cell's jittered ray lands anywhere in it
            float u = p.u0 + (float(i - p.r0) + (float(s) + 0.5) / 64.0) * p.du;
            float tan2 = p.a2 * u / (1.0 - u);
            sum += float(sectors) * lobe_omega_h(p, tan2, dphi) / 64.0;
        }
    }
    out_data[c] = vec4(sum, f.tan2_max, float(f.split), 1.0);
}
