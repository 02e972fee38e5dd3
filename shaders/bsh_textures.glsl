// Builds the texture view of the BSH (lib/bsh_textures.glsl) from the canonical records, decoded
// by the generated layout header: the record format stays defined in one place.
#include "gen/node_layout.glsl"
#include "lib/bsh_textures.glsl"

layout(local_size_x = 64) in;
layout(rgba32f, binding = 1) uniform writeonly image2D out_sphere;
layout(rgba32f, binding = 2) uniform writeonly image2D out_cone;
layout(rgba32ui, binding = 3) uniform writeonly uimage2D out_link;
layout(rgba32f, binding = 4) uniform writeonly image2D out_color;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= node_count()) return;
    Node n = load_node(i);
    ivec2 c = bsh_texel(i);
    imageStore(out_sphere, c, vec4(n.center, n.radius));
    imageStore(out_cone, c, vec4(n.cone_axis, n.cone_cos));
    imageStore(out_link, c, uvec4(n.skip, n.count | (n.is_leaf ? BSH_TEX_LEAF_BIT : 0u), 0u, 0u));
    imageStore(out_color, c, vec4(n.color, 0.0));
}
