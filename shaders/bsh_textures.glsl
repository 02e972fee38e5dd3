// Builds the texture view of the BSH (lib/bsh_textures.glsl) from the canonical records, decoded
// by the generated layout header: the record format stays defined in one place.
#include "gen/node_layout.glsl"
#define BSH_TEX_WRITABLE 1
#include "gen/bsh_textures.glsl"

layout(local_size_x = WORKGROUP_SIZE) in;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= node_count()) return;
    Node n = load_node(i);
    ivec2 c = bsh_texel(i);
    imageStore(bsh_sphere_img, c, bsh_sphere_pack(BshSphere(n.center, n.radius)));
    imageStore(bsh_cone_img, c, bsh_cone_pack(BshCone(n.cone_axis, n.cone_cos)));
    imageStore(bsh_link_img, c,
               bsh_link_pack(BshLink(n.skip, n.count | (n.is_leaf ? BSH_TEX_LEAF_BIT : 0u))));
    imageStore(bsh_color_img, c, bsh_color_pack(BshColor(n.color)));
}
