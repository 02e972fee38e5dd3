// Test shader for the generated GPU records (tests/pbgi/test_gpu_records.py): every record of
// app/pbgi/gpu_layout.py decoded (and, where the GPU writes it, encoded) through the generated
// gen/*.glsl code the renderer uses. One invocation per record i; a decoding MODE writes the
// record's fields in declaration order, every component as one 32-bit word (floats as their
// bits, a float-value id as the integer), WORDS words per record, into out_words; a writing
// MODE stores records the test then reads back through the numpy dtypes.
//   MODE 0  receivers: receiver_*(i)                     MODE 7  pyramid: mip_link / mip_sphere /
//   MODE 1  receiver_principled(i) (the material rule)          mip_cone, then mip_store (swapped)
//   MODE 2  ClassicState: read, write back reversed      MODE 8  micro-buffer texels and tables
//   MODE 3  FinishState: read, write back reversed       MODE 9  share rows   MODE 10 block_of
//   MODE 4  refinement counters by their C_* words       MODE 11 frames       MODE 12 gather output
//   MODE 5  pair stream: pair_load, pair_store, item_store     MODE 13 node textures (tnode_*)
//   MODE 6  pair stream, read-only: item_load, head_load
#ifndef MODE
#define MODE 0
#endif
#include "gen/bindings.glsl"

layout(local_size_x = WORKGROUP_SIZE) in;
layout(std430, binding = 10) buffer Out { uint out_words[]; };   // 10: no renderer binding
uniform uint u_count;
uniform uint u_words;          // words written per record

uint o_;
void put(uint v) { out_words[o_++] = v; }
void put(float v) { put(floatBitsToUint(v)); }
void put(vec3 v) { put(v.x); put(v.y); put(v.z); }
void put(uvec3 v) { put(v.x); put(v.y); put(v.z); }

#if MODE == 0
#include "gen/receivers.glsl"
#elif MODE == 1
#include "gen/materials.glsl"
#elif MODE == 2 || MODE == 3
#include "gen/walk_state.glsl"
#if MODE == 2
layout(std430, binding = SSBO_WALK_STATE) buffer State { ClassicState state[]; };
#else
layout(std430, binding = SSBO_WALK_STATE) buffer State { FinishState state[]; };
#endif
#elif MODE == 4
#include "gen/pair_streams.glsl"
layout(std430, binding = SSBO_COUNTERS) buffer Counters { uint counters[]; };
#elif MODE == 5 || MODE == 6
#include "gen/mip.glsl"
#if MODE == 6
#define PAIR_STREAMS_READONLY 1
#endif
#include "gen/pair_streams.glsl"
#elif MODE == 7
#define MIP_WRITABLE 1
#include "gen/mip.glsl"
#elif MODE == 8
#include "lib/microbuffer.glsl"
uniform uint u_side;           // M + 1: the index texture's side
#elif MODE == 9
#include "gen/share_rows.glsl"
#elif MODE == 10
#include "gen/block_of.glsl"
#elif MODE == 11
#include "gen/frames.glsl"
#elif MODE == 12
#include "gen/gather_output.glsl"
#elif MODE == 13
#include "lib/bsh_textures.glsl"
#elif MODE == 14
#define GATHER_PARTS 1
#include "gen/gather_output.glsl"
#endif

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    o_ = i * u_words;
#if MODE == 0
    put(receiver_position(i));
    put(receiver_pixel(i));
    put(receiver_normal(i));
    put(receiver_material(i));
    put(receiver_tangent(i));
    put(receiver_roughness(i));
    put(receiver_base_color(i));
    put(receiver_metallic(i));
#elif MODE == 1
    PrincipledParams p = receiver_principled(i);
    put(p.base_color);
    put(p.subsurface);
    put(p.metallic);
    put(p.specular);
    put(p.specular_tint);
    put(p.roughness);
    put(p.anisotropic);
    put(p.sheen);
    put(p.sheen_tint);
    put(p.clearcoat);
    put(p.clearcoat_gloss);
#elif MODE == 2
    ClassicState s = state[i];
    put(s.next);
    put(s.visited);
    put(s.flags);
    put(s.tests);
    state[i] = ClassicState(s.tests, s.flags, s.visited, s.next);
#elif MODE == 3
    FinishState s = state[i];
    put(s.node);
    put(s.end);
    put(s.next_item);
    put(s.pixel);
    put(s.visited);
    put(s.flags);
    put(s.tests);
    put(s.pixel0);
    state[i] = FinishState(s.pixel0, s.tests, s.flags, s.visited, s.pixel, s.next_item, s.end,
                           s.node);
#elif MODE == 4
    put(counters[C_STACK]);
    put(counters[C_S2]);
    put(counters[C_BASE]);
    put(counters[C_K]);
    put(uvec3(counters[C_REFINE_ARGS], counters[C_REFINE_ARGS + 1], counters[C_REFINE_ARGS + 2]));
    put(uvec3(counters[C_MOVE_ARGS], counters[C_MOVE_ARGS + 1], counters[C_MOVE_ARGS + 2]));
    put(counters[C_MOVE_SRC]);
    put(counters[C_MOVE_N]);
    put(counters[C_ALLOWED]);
    put(counters[C_PUSHED_BACK]);
    put(counters[C_PROCESSED]);
    put(counters[C_NODE_REFINES]);
    put(counters[C_PIXEL_SPLITS]);
    put(counters[C_CULLED]);
    put(counters[C_TO_S2]);
    put(counters[C_PEAK_STACK]);
    put(counters[C_PASSES]);
    put(counters[C_ACCEPTED]);
    put(counters[C_KMAX]);
    put(counters[C_CAP]);
    put(counters[C_S2_CAP]);
    put(counters[C_DISABLED_PASSES]);
#elif MODE == 5
    Pair p = pair_load(i);
    put(p.node);
    put(p.pixel);
    pair_store(u_count + i, p.pixel, p.node);
    item_store(i, Item(p.pixel, p.node, i, ~i));
#elif MODE == 6
    Item it = item_load(i);
    put(it.node);
    put(it.next);
    put(it.pixel);
    put(it.skip);
    put(head_load(i));
#elif MODE == 7
    MipLink l = mip_link(i);
    put(l.first);
    put(l.count);
    put(l.parent);
    put(l.level);
    MipSphere s = mip_sphere(i);
    put(s.center);
    put(s.radius);
    MipCone c = mip_cone(i);
    put(c.axis);
    put(c.angle);
    mip_store(i, MipSphere(c.axis, c.angle), MipCone(s.center, s.radius));
#elif MODE == 8
    // entry i of the tables and of micro-buffer row 0; index texel (i % side, i / side)
    if (i < mb_entries()) {
        MbDirection d = mb_table(i);
        put(d.dir);
        put(d.weight);
        MbFlux f = mb_flux(i);
        put(f.flux);
        put(f.solid_angle);
        MbEntry e = mb_load(0u, i);
        put(e.key);
        put(e.node);
        mb_entry_store(ivec2(int(i), 1), MbEntry(e.node, e.key));
    }
    o_ = i * u_words + 10u;
    if (i < u_side * u_side) {
        MbBands b = mb_bands(i % u_side, i / u_side);
        put(b.first);
        put(b.count);
        put(b.prefix);
    }
#elif MODE == 9
    put(share_center(i));
    put(share_ball(i));
    put(share_frame(i));
    put(share_seed(i));
#elif MODE == 10
    put(share_block(i));
#elif MODE == 11
    put(frame_normal(i));
    put(frame_seed(i));
    put(frame_level(i));
#elif MODE == 12
    gather_output_store(i, GatherOutput(vec3(float(i), float(i) + 0.5, -float(i)),
                                        (i & 1u) == 0u ? 1.0 : -1.0));
#elif MODE == 14
    float f = float(i);
    gather_parts_store(i, GatherParts(vec3(f, f + 0.25, -f), i % 7u, vec3(2.0 * f), vec3(3.0),
                                      vec3(-1.0, f, 0.5), vec3(f * f)));
#elif MODE == 13
    BshSphere s = tnode_sphere(i);
    put(s.center);
    put(s.radius);
    BshCone c = tnode_cone(i);
    put(c.axis);
    put(c.cos_angle);
    BshLink l = tnode_link(i);
    put(l.skip);
    put(l.count_flags);
    put(tnode_color(i));
#endif
}
