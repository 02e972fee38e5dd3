// Test shader for the viewer's generated records (tests/render/test_viewer_records.py): each
// record of app/render/gpu_layout.py decoded (and, where the GPU writes it, encoded) through the
// generated gen/*.glsl code the viewer's passes use.
//   MODE 0  compute, one invocation per texel p = (i % u_width, i / u_width): room_at, guide_at,
//           gi_at(u_preview), gi_at(u_full) on the viewer's own samplers and units, each field
//           one 32-bit word (16 per texel) into out_words; then composite_store(p, ...) with
//           the guide's normal and the room's coverage, read back through COMPOSITE_TEXEL.
//   MODE 1  vertex stage, transform feedback: SPLAT_VERTEX's inputs copied to o_* varyings
//   MODE 2  vertex stage, transform feedback: VIEWER_VERTEX's inputs copied to o_* varyings
#ifndef MODE
#define MODE 0
#endif

#if MODE == 0
#ifdef COMPUTE_SHADER
#include "gen/viewer_composite.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 0) buffer Out { uint out_words[]; };   // no viewer program has SSBOs
uniform uint u_count;
uniform uint u_width;

uint o_;
void put(float v) { out_words[o_++] = floatBitsToUint(v); }
void put(vec3 v) { put(v.x); put(v.y); put(v.z); }

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    ivec2 p = ivec2(int(i % u_width), int(i / u_width));
    o_ = 16u * i;
    RoomTexel r = room_at(p);
    put(r.radiance);
    put(r.coverage);
    GuideTexel g = guide_at(p);
    put(g.normal);
    put(g.depth);
    GiTexel a = gi_at(u_preview, p);
    put(a.radiance);
    put(a.status);
    GiTexel b = gi_at(u_full, p);
    put(b.radiance);
    put(b.status);
    composite_store(p, CompositeTexel(g.normal, r.coverage));
}
#endif

#else
#ifdef VERTEX_SHADER
#if MODE == 1
#include "gen/splat.glsl"
out vec3 o_position;
out vec3 o_color;
out vec3 o_normal;
out float o_radius;
void main() { o_position = in_position; o_color = in_color; o_normal = in_normal;
              o_radius = in_radius; }
#else
#include "gen/viewer_gbuffer.glsl"
out vec3 o_position;
out vec3 o_normal;
void main() { o_position = in_position; o_normal = in_normal; }
#endif
#endif
#endif
