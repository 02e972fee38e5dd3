// G-buffer pyramid geometry (app/pbgi/gmip.py holds the why; the records are gen/mip.glsl): one
// dispatch per level, finest first. Level 0 copies each receiver's position (radius 0) and
// shading normal (half-angle 0); a coarser pixel merges its 1-4 children as (c0 + c1) + (c2 + c3)
// with the BSH's operators: smallest sphere enclosing two spheres and the exact minimum cone
// containing two cones (app/pbgi/hierarchy.py merge_spheres / merge_cones).
// Conservative in float32: angles come from atan2 (accurate for nearly parallel axes, where
// acos loses ~1e-4 rad), unit vectors from sqrt (llvmpipe's normalize is approximate), the
// result is re-checked against both inputs, and grows by a margin.
#include "lib/common.glsl"
#include "gen/receivers.glsl"
#define MIP_WRITABLE 1
#include "gen/mip.glsl"

layout(local_size_x = WORKGROUP_SIZE) in;

uniform uint u_first;      // first receiver of the batch
uniform uint u_offset;     // first pyramid pixel of this level
uniform uint u_count;      // pixels in this level

float angle_between(vec3 a, vec3 b) { return atan(length(cross(a, b)), dot(a, b)); }

// llvmpipe's normalize() uses an approximate reciprocal square root (errors ~3e-4); sqrt is exact.
vec3 unit(vec3 v) { return v / sqrt(dot(v, v)); }

vec3 any_perpendicular(vec3 a) {
    vec3 p = abs(a.x) < 0.9 ? vec3(0.0, a.z, -a.y) : vec3(-a.z, 0.0, a.x);
    return unit(p);
}

void merge_cone(inout vec3 a1, inout float t1, vec3 a2, float t2) {
    float g = angle_between(a1, a2);
    if (g + t2 <= t1) return;
    if (g + t1 <= t2) { a1 = a2; t1 = t2; return; }
    float t = 0.5 * (t1 + t2 + g);
    if (t >= PI) { t1 = PI; return; }            // all directions: the axis does not matter
    vec3 u = a2 - a1 * dot(a1, a2);
    float un = length(u);
    if (un < 1e-6) {
        if (dot(a1, a2) > 0.0) { t1 = min(max(t1, t2 + g), PI); return; }
        u = any_perpendicular(a1);
        un = 1.0;
    }
    float phi = t - t1;
    vec3 a = unit(a1 * cos(phi) + (u / un) * sin(phi));
    t = max(t, max(angle_between(a, a1) + t1, angle_between(a, a2) + t2));
    a1 = a;
    t1 = min(t, PI);
}

void merge_sphere(inout vec3 c1, inout float r1, vec3 c2, float r2) {
    vec3 v = c2 - c1;
    float d = length(v);
    if (d + r2 <= r1) return;
    if (d + r1 <= r2) { c1 = c2; r1 = r2; return; }
    float r = 0.5 * (d + r1 + r2);
    vec3 c = c1 + v * ((r - r1) / d);
    r = max(r, max(distance(c, c1) + r1, distance(c, c2) + r2));
    c1 = c;
    r1 = r;
}

void main() {
    uint j = gl_GlobalInvocationID.x;
    if (j >= u_count) return;
    uint g = u_offset + j;
    MipLink L = mip_link(g);
    if (L.count == 0u) {
        uint rid = u_first + L.first;
        mip_store(g, MipSphere(receiver_position(rid), 0.0), MipCone(unit(receiver_normal(rid)), 0.0));
        return;
    }
    uint last = L.count - 1u;
    vec3 c[4];
    float r[4];
    vec3 a[4];
    float t[4];
    for (uint k = 0u; k < 4u; ++k) {
        uint ch = L.first + min(k, last);
        MipSphere s = mip_sphere(ch);
        MipCone n = mip_cone(ch);
        c[k] = s.center; r[k] = s.radius; a[k] = n.axis; t[k] = n.angle;
    }
    merge_sphere(c[0], r[0], c[1], r[1]);
    merge_sphere(c[2], r[2], c[3], r[3]);
    merge_sphere(c[0], r[0], c[2], r[2]);
    merge_cone(a[0], t[0], a[1], t[1]);
    merge_cone(a[2], t[2], a[3], t[3]);
    merge_cone(a[0], t[0], a[2], t[2]);
    // growth margin: float32 rounding of the merges above (relative 1e-6 of the extent)
    float grow = 1e-6 * (length(c[0]) + r[0]) + 1e-7;
    mip_store(g, MipSphere(c[0], r[0] + grow), MipCone(a[0], min(t[0] + 2e-6, PI)));
}
