// One refinement step as the modes run it: a compute dispatch appending the children of every
// pair with an atomic counter (the same stand-in test as refine_step_tf.glsl).
// tests/pbgi/test_refine_backends.py.

layout(local_size_x = 64) in;
layout(rg32ui, binding = 1) uniform readonly uimage2D in_pairs;
layout(rg32ui, binding = 2) uniform writeonly uimage2D out_pairs;
layout(std430, binding = 0) buffer Counter { uint count; };
uniform uint u_n;
uniform uint u_limit;

ivec2 texel(uint i) { return ivec2(int(i & 4095u), int(i >> 12u)); }

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_n) return;
    uvec2 p = imageLoad(in_pairs, texel(i)).xy;
    float f = sin(float(p.x) * 0.001) * cos(float(p.y) * 0.002);
    if (p.x < u_limit && f > -2.0) {
        uint slot = atomicAdd(count, 2u);
        imageStore(out_pairs, texel(slot), uvec4(2u * p.x + 1u, p.y, 0u, 0u));
        imageStore(out_pairs, texel(slot + 1u), uvec4(2u * p.x + 2u, p.y, 0u, 0u));
    }
}
