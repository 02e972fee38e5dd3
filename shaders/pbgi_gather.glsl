// Final gather (paper eq. 9), shared by every mode: per receiver,
//   L_out(w_o) = sum_k f(w_k, w_o) L_k Omega_k (n . w_k)
// with the Disney Principled BRDF (lib/principled.glsl). Omega_k (n . w_k) is the micro-pixel's
// cosine-weighted solid angle from the table (its own solid angle, clipped at the horizon).
// With FRAME_NORMALS the micro-buffer is in the frame of another normal A (frames[i]: Hybrid's
// far-field sharing gives a block of receivers one frame); the weight becomes the cosine-weighted
// solid angle about the receiver's own normal, max(n . F_k, 0) with F_k the integral of w over the
// entry's region (app/pbgi/microbuffer.py's flux table; = Omega_ij (n . w_ij) for A = n). Only
// entries the receiver's horizon cuts are approximate, and directions above n's horizon but
// below A's are missing: a sliver as wide as the angle between n and A. The entries copied from the
// block (MB_FAR_BIT: the shared far field) are scaled by the frame's level (its block's,
// app/pbgi/block_levels.py: the far field's quantisation error traded for its neighbours' mean);
// the receiver's own near field and the lobe buffers are not shared and keep theirs.
// L_k comes from the micro-buffer (the node's float32 colour) or, with RADIANCE_CUBEMAP, from the
// environment cube map in the same direction (the look-dev baseline): the two differ only in
// where the incoming radiance is read, never in how it is integrated.
// The BRDF's parameters: receiver_principled (gen/materials.glsl) - base colour, metallic and
// roughness from the receiver (factor x texture), the rest from the material table.
// With LOBE_BUFFER the receivers whose specular or clearcoat lobe is too narrow for the cosine
// micro-buffer (lib/lobe.glsl: lobe_terms) gather those lobes from their lobe micro-buffer instead,
// each micro-pixel weighted by f cos(theta) times its own solid angle; the cosine loop then
// leaves them out inside the lobe's domain (lobe_inside), so the two loops split the directions -
// except the specular lobe near glossy_below, which the two share (lobe_spec_share).
// The micro-buffer is in the frame its cut drew it in (lib/microbuffer.glsl: mb_frame): the
// receiver's own, turned about N per receiver and pass or not, or with FRAME_NORMALS its
// block's, turned per block and pass (frames[i].seed).
// With IRRADIANCE the BRDF is a white Lambertian one, f = 1 / pi, whatever the material: the output
// is E / pi, the diffuse outgoing radiance per unit albedo (the asset's surfel bounce and the
// differential rendering of the scan, app/pbgi/renderer.py's gather_points).
// With IRRADIANCE and COVERAGE every held entry has radiance 1: the output is the cosine-weighted
// share of the hemisphere the micro-buffer holds (Hybrid's block levels, app/pbgi/farfield.py).
// With GATHER_PARTS the same sums are kept apart per BRDF factor (lib/principled.glsl:
// PrincipledParts) and stored per tile pixel as GatherParts (gen/gather_output.glsl); L_out is
// their recombination with the receiver's own factors - the one app/pbgi/gather_parts.py repeats
// in numpy for another base colour, metallic, specular, sheen or clearcoat amount.
// Output per tile pixel: GatherOutput (L_out, status 1; -1 marks a gather loop the driver cut
// short).
#include "lib/common.glsl"
#include "lib/principled.glsl"
#include "gen/receivers.glsl"
#include "gen/materials.glsl"
#include "gen/gather_output.glsl"
#include "lib/receiver_shading.glsl"
#include "lib/bsh_textures.glsl"
#include "lib/microbuffer.glsl"
#ifdef LOBE_BUFFER
#include "lib/lobe.glsl"
#include "lib/lobe_size.glsl"
uniform uint u_rings;
uniform uint u_sectors;
uniform uint u_pass;
uniform float u_glossy_below;
#endif

layout(local_size_x = WORKGROUP_SIZE) in;

uniform uint u_first;
uniform uint u_count;
uniform int u_m;               // micro-buffer size M (the entry table is bound per M)
uniform vec3 u_camera;         // camera position relative to the hierarchy origin
#ifdef FRAME_NORMALS
#include "gen/frames.glsl"
#endif
#ifdef RADIANCE_CUBEMAP
layout(binding = TEX_ENV) uniform samplerCube u_env;
uniform float u_env_texel_omega;   // solid angle of one cube-map texel at a face centre
#else
// The asset's glossy bounce (app/pbgi/asset_scene.py, app/pbgi/nodetex.py: set_directional):
// the asset's nodes from `first` on send L(d) = colour + G d towards unit direction d (here -w,
// from the node to the receiver), G's columns at texels 1 + 4 j + c of asset node j; texel 0
// holds (first / 65536, first % 65536, count) - a first no node reaches when the bounce is
// diffuse or there is none.
// Compiled in only when the tree has such nodes (ASSET_DIRECTIONAL, app/pbgi/gather.py): the
// untaken test and its look-ups cost llvmpipe's gather 2.8x otherwise (demo close-up, 19 -> 55
// ms for a room without them).
layout(binding = TEX_ASSET_DIR) uniform sampler2D u_asset_dir;
#ifdef ASSET_MIRROR
// The mirror bounce of a smooth metal (asset_scene.py: mirror_params), where a plane in d cannot
// hold the sharp reflection: the room's light from the mirror direction about the node's normal
// (its cone axis), seen from the asset's centre (u_asset_env: distant light, as the
// environment-map baseline) and prefiltered to the lobe's solid angle 4 pi alpha^2 by the cube
// map's mip level, times the metal's directional albedo F0 S + B (u_metal_albedo: the split sum).
// Mixed into the plane by the node's weight (texel 1 + 4 j + 3's alpha) times its cone's
// tightness: a node whose normals spread wide (a cube's edge, both faces of a thin plate) has
// no one mirror direction and keeps the plane (mirrored about its axis anyway, a hot pixel 2x
// the path tracer's brightest came up on the blocks in the city). The roughness is the alpha
// of texel 1 + 4 j, F0 the rgb of texel 1 + 4 j + 3.
layout(binding = TEX_ASSET_ENV) uniform samplerCube u_asset_env;
layout(binding = TEX_METAL_ALBEDO) uniform sampler2D u_metal_albedo;
uniform float u_asset_env_texel_omega;   // solid angle of one cube-map texel at a face centre
#define MIRROR_CONE_COS vec2(0.7, 0.95)  // cone cosines: the plane alone .. the mirror alone

vec3 asset_mirror(vec3 n, vec3 o, vec3 f0, float rough) {
    float mu = dot(n, o);
    if (mu <= 0.0) return vec3(0.0);
    vec3 r = 2.0 * mu * n - o;
    float alpha = max(rough * rough, 1e-3);
    float lod = 0.5 * log2(max(4.0 * PI * alpha * alpha / u_asset_env_texel_omega, 1.0));
    vec2 sb = texture(u_metal_albedo, vec2(min(mu, 1.0), rough)).rg;
    return textureLod(u_asset_env, r, lod).rgb * (f0 * sb.x + sb.y);
}
#endif
vec3 node_radiance(uint node, vec3 w, uint first, int width) {
    vec3 L = tnode_color(node);
#ifndef ASSET_DIRECTIONAL
    return L;
#endif
    if (node < first) return L;
    int t = 1 + 4 * int(node - first);
    vec4 gx = texelFetch(u_asset_dir, ivec2(t % width, t / width), 0);
    vec3 gy = texelFetch(u_asset_dir, ivec2((t + 1) % width, (t + 1) / width), 0).rgb;
    vec3 gz = texelFetch(u_asset_dir, ivec2((t + 2) % width, (t + 2) / width), 0).rgb;
    L = max(L - (gx.rgb * w.x + gy * w.y + gz * w.z), vec3(0.0));
#ifdef ASSET_MIRROR
    vec4 f0w = texelFetch(u_asset_dir, ivec2((t + 3) % width, (t + 3) / width), 0);
    BshCone cone = tnode_cone(node);
    float weight = f0w.a * clamp((cone.cos_angle - MIRROR_CONE_COS.x)
                                 / (MIRROR_CONE_COS.y - MIRROR_CONE_COS.x), 0.0, 1.0);
    if (weight > 0.0) L = mix(L, asset_mirror(cone.axis, -w, f0w.rgb, gx.a), weight);
#endif
    return L;
}
#endif

#ifdef GATHER_PARTS
// One direction's radiance L w (w: its weight) into the parts, every lobe / the narrow ones.
void gather_parts_add_lobes(inout GatherParts P, PrincipledParts r, vec3 Lw) {
    P.spec_f0 += (r.spec * (1.0 - r.fh)) * Lw;
    P.spec_one += (r.spec * r.fh) * Lw;
    P.coat += r.coat * Lw;
}
void gather_parts_add(inout GatherParts P, PrincipledParts r, vec3 Lw) {
    P.diffuse += r.diffuse * Lw;
    P.sheen += r.fh * Lw;
    gather_parts_add_lobes(P, r, Lw);
}

// The receiver's own factors on the parts: what principled_lobes_prepared multiplies in.
vec3 gather_parts_radiance(PrincipledPrepared q, GatherParts P) {
#ifdef PRINCIPLED_NO_SHEEN
    vec3 base = q.base * P.diffuse;
#else
    vec3 base = q.base * P.diffuse + q.sheen_w * P.sheen;
#endif
    return base * (1.0 - q.metallic) + q.spec0 * P.spec_f0 + P.spec_one + q.clearcoat * P.coat;
}
#endif

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_count) return;
    uint rid = u_first + i;
    vec3 p = receiver_position(rid);
    vec3 N = receiver_normal(rid);
    PrincipledPrepared Q = receiver_prepared(rid, p, N, u_camera);
    vec3 T, B;                           // the micro-buffer frame
#ifdef FRAME_NORMALS
    vec3 A = frame_normal(i);
    mb_frame_shared(A, frame_seed(i), receiver_pixel(rid), T, B);   // as its walks drew it
    vec3 n_local = vec3(dot(N, T), dot(N, B), dot(N, A));   // the receiver's normal, A's frame
    vec3 level = frame_level(i);                              // on the block's far entries
#elif defined(RADIANCE_CUBEMAP)
    vec3 A = N;
    orthonormal_basis(N, T, B);          // directions into a cube map: no cut to agree with
#else
    vec3 A = N;
    mb_frame(N, receiver_pixel(rid), T, B);   // the frame the receiver's cut was drawn in
#endif

    uint mm = mb_entries();
    vec3 sum = vec3(0.0);
#ifdef GATHER_PARTS
    GatherParts P = GatherParts(vec3(0.0), receiver_material(rid), vec3(0.0), vec3(0.0),
                                vec3(0.0), vec3(0.0));
#endif
#if !defined(RADIANCE_CUBEMAP) && defined(ASSET_DIRECTIONAL)
    vec2 first_halves = texelFetch(u_asset_dir, ivec2(0), 0).xy;
    uint asset_dir_first = (uint(first_halves.x) << 16) | uint(first_halves.y);
    int asset_dir_width = textureSize(u_asset_dir, 0).x;
#else
    uint asset_dir_first = 0xFFFFFFFFu;
    int asset_dir_width = 1;
#endif
#ifdef LOBE_BUFFER
    bvec2 terms = lobe_terms(Q, u_glossy_below);
    bool lobed = any(terms) && Q.n_dot_v > 0.0;
    uvec2 size = lobe_size(Q, terms, u_glossy_below, u_rings, u_sectors);
    LobeFrame F = lobe_frame_for(Q, terms, lobe_seed_pixel(receiver_pixel(rid)), u_pass, size.x,
                                  size.y);
    float spec_share = lobe_spec_share(Q, u_glossy_below);
#endif
    uint k;
    for (k = 0u; k < mm; ++k) {
        MbDirection e = mb_table(k);
        if (e.weight <= 0.0) continue;
        vec3 w = T * e.dir.x + B * e.dir.y + A * e.dir.z;
#ifdef FRAME_NORMALS
        float weight = max(dot(n_local, mb_flux(k).flux), 0.0);
        if (weight <= 0.0) continue;
#else
        float weight = e.weight;
#endif
#ifdef RADIANCE_CUBEMAP
        float lod = 0.5 * log2(max(e.weight / max(e.dir.z, 1e-3) / u_env_texel_omega, 1.0));
        vec3 L = textureLod(u_env, w, lod).rgb;
#else
        uint node = mb_load(i, k).node;
        if (node == MB_EMPTY) continue;
#ifdef FRAME_NORMALS
        bool far = node >= MB_FAR_BIT;
        node &= ~MB_FAR_BIT;
#endif
#ifdef COVERAGE
        vec3 L = vec3(1.0);                      // every direction the buffer holds, as white
#else
        vec3 L = node_radiance(node, w, asset_dir_first, asset_dir_width);
#endif
#ifdef FRAME_NORMALS
        if (far) L *= level;
#endif
#endif
#if defined(GATHER_PARTS)
        PrincipledParts r = principled_parts_prepared(Q, w);
#ifdef LOBE_BUFFER
        if (lobed && lobe_inside(F, w)) {       // those lobes come from the lobe buffer
            if (terms.x) r.spec *= 1.0 - spec_share;
            if (terms.y) r.coat = 0.0;
        }
#endif
        gather_parts_add(P, r, L * weight);
#elif defined(LOBE_BUFFER)
        vec3 fb, fs, fc;
        principled_lobes_prepared(Q, w, fb, fs, fc);
        if (lobed && lobe_inside(F, w)) {       // those lobes come from the lobe buffer
            if (terms.x) fs *= 1.0 - spec_share;
            if (terms.y) fc = vec3(0.0);
        }
        sum += (fb + fs + fc) * L * weight;
#else
#ifdef IRRADIANCE
        sum += L * (weight * INV_PI);
#else
        sum += principled_brdf_prepared(Q, w) * L * weight;
#endif
#endif
    }
    bool complete = k == mm;
#ifdef LOBE_BUFFER
    if (lobed) {
        uint cells = F.rings * F.sectors;
        for (k = 0u; k < cells; ++k) {
            vec3 w;
            float omega;
            lobe_cell(F, k, w, omega);
            if (omega <= 0.0) continue;
#ifdef RADIANCE_CUBEMAP
            float lod = 0.5 * log2(max(omega / u_env_texel_omega, 1.0));
            vec3 L = textureLod(u_env, w, lod).rgb;
#else
            uint node = lobe_entry_at(ivec2(int(k), int(i))).node;
            if (node == MB_EMPTY) continue;
            vec3 L = node_radiance(node, w, asset_dir_first, asset_dir_width);
#endif
#ifdef GATHER_PARTS
            PrincipledParts r = principled_parts_prepared(Q, w);
            r.spec *= terms.x ? spec_share : 0.0;
            if (!terms.y) r.coat = 0.0;
            gather_parts_add_lobes(P, r, L * (omega * dot(N, w)));   // no wide lobes here
#else
            vec3 fb, fs, fc;
            principled_lobes_prepared(Q, w, fb, fs, fc);
            vec3 f = (terms.x ? spec_share * fs : vec3(0.0)) + (terms.y ? fc : vec3(0.0));
            sum += f * L * (omega * dot(N, w));
#endif
        }
        complete = complete && k == cells;
    }
#endif
#ifdef GATHER_PARTS
    sum = gather_parts_radiance(Q, P);
    gather_parts_store(receiver_pixel(rid), P);
#endif
    gather_output_store(receiver_pixel(rid), GatherOutput(sum, complete ? 1.0 : -1.0));
}
