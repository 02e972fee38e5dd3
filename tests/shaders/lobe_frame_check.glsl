// lib/lobe.glsl's frame rotation, for tests/pbgi/test_lobe_anisotropic.py: per invocation i
// (pixel i % u_pixels, pass i / u_pixels) the frame's azimuth phi0 of a fixed receiver, so a
// test can see that each pixel and each pass turns its lobe micro-buffer anew (seed 001's
// "rotate each receiver's frame": quantisation becomes noise, not a grid).
#include "lib/common.glsl"
#include "lib/principled.glsl"
#include "lib/lobe.glsl"

layout(local_size_x = 64) in;

layout(std430, binding = 0) writeonly buffer OutBuf { float out_data[]; };

uniform uint u_pixels;
uniform uint u_count;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    LobeFrame f = lobe_frame(vec3(0.0, 0.0, 1.0), normalize(vec3(0.3, 0.1, 1.0)), 0.2, 0.2, 0.0,
                             i % u_pixels, i / u_pixels, 8u, 8u);
    out_data[i] = f.phi0;
}
