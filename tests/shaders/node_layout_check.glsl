// Test shader for the generated BSH node layout (tests/bsh/test_bsh_glsl.py): the GLSL side of the
// "numpy and GLSL read the same records" check.
//   MODE 0: one invocation per node; writes the fields load_node() decodes, as raw 32-bit words,
//           plus a bit mask saying whether the single-field helpers agree with load_node().
//   MODE 1: one invocation per query sphere; a stackless walk (descend i + 1, skip node.skip)
//           that enters every node whose sphere meets the query and reports the leaves reached.
#include "gen/node_layout.glsl"

#ifndef MODE
#define MODE 0
#endif
#define DECODED_WORDS 17u

layout(local_size_x = 64) in;

layout(std430, binding = 1) writeonly buffer Decoded { uint decoded[]; };
layout(std430, binding = 2) readonly buffer Queries { vec4 queries[]; };
uniform uint u_count;      // nodes (MODE 0) or queries (MODE 1)
uniform uint u_max_steps;  // MODE 1: walk budget per query (llvmpipe cuts long loops silently)

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
#if MODE == 0
    Node n = load_node(i);
    uint o = i * DECODED_WORDS;
    decoded[o + 0u] = floatBitsToUint(n.center.x);
    decoded[o + 1u] = floatBitsToUint(n.center.y);
    decoded[o + 2u] = floatBitsToUint(n.center.z);
    decoded[o + 3u] = floatBitsToUint(n.radius);
    decoded[o + 4u] = floatBitsToUint(n.color.r);
    decoded[o + 5u] = floatBitsToUint(n.color.g);
    decoded[o + 6u] = floatBitsToUint(n.color.b);
    decoded[o + 7u] = floatBitsToUint(n.cone_axis.x);
    decoded[o + 8u] = floatBitsToUint(n.cone_axis.y);
    decoded[o + 9u] = floatBitsToUint(n.cone_axis.z);
    decoded[o + 10u] = floatBitsToUint(n.cone_cos);
    decoded[o + 11u] = floatBitsToUint(n.cone_angle);
    decoded[o + 12u] = n.skip;
    decoded[o + 13u] = n.count;
    decoded[o + 14u] = n.is_leaf ? 1u : 0u;
    decoded[o + 15u] = n.is_leaf ? 0xffffffffu : node_right(i);
    uint agree = 0u;
    if (node_sphere(i) == vec4(n.center, n.radius)) agree |= 1u;
    if (node_color(i) == n.color) agree |= 2u;
    if (node_cone(i) == vec4(n.cone_axis, n.cone_cos)) agree |= 4u;
    if (node_cone_angle(i) == n.cone_angle) agree |= 8u;
    if (node_skip(i) == n.skip) agree |= 16u;
    if (node_is_leaf(i) == n.is_leaf) agree |= 32u;
    if (node_point_count(i) == n.count) agree |= 64u;
    if (node_left(i) == i + 1u) agree |= 128u;
    if (node_count() == BSH_END) agree |= 256u;
    decoded[o + 16u] = agree;
#else
    vec4 q = queries[i];
    uint node = 0u, steps = 0u, leaves = 0u, points = 0u, visited = 0u;
    uint end = BSH_END;
    while (node != end && steps < u_max_steps) {
        steps++;
        vec4 s = node_sphere(node);
        visited++;
        if (distance(s.xyz, q.xyz) > s.w + q.w) {
            node = node_skip(node);          // cull the subtree
        } else if (node_is_leaf(node)) {
            leaves++;
            points += node_point_count(node);
            node = node_skip(node);
        } else {
            node = node + 1u;                // descend
        }
    }
    uint o = i * 4u;
    decoded[o + 0u] = leaves;
    decoded[o + 1u] = points;
    decoded[o + 2u] = visited;
    decoded[o + 3u] = (node == end) ? 1u : 0u;  // completed: the walk reached the end marker
#endif
}
