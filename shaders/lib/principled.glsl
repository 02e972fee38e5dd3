// Disney Principled BRDF (Burley 2012, "Physically-Based Shading at Disney"), transcribed from
// Disney's BRDF explorer `disney.brdf`. Numpy twin: app/pbgi/brdf.py (keep the two in step;
// tests/test_brdf.py compares them).
//
// Conventions
// - All vectors are unit length, in one space (world or local). L = direction TO the light,
//   V = direction TO the viewer, N = shading normal, X/Y = tangent/bitangent forming an
//   orthonormal frame with N (anisotropy stretches the highlight along X). Without a tangent,
//   use orthonormal_basis(N, X, Y); with anisotropic = 0 the result does not depend on X/Y.
// - principled_brdf returns f(L, V) in 1/sr WITHOUT the cosine (n.L) factor, and 0 when L or V
//   is on or below the surface (n.L <= 0 or n.V <= 0).
// - base_color is LINEAR RGB (the explorer's mon2lin() is not applied). The tint hue uses the
//   explorer's luminance approximation 0.3 R + 0.6 G + 0.1 B, not Rec.709.
// - Parameters are clamped to their ranges (base_color and scalars to [0, 1]).
// - Robustness: both microfacet alphas are clamped to >= 1e-3 (roughness 0 is a very sharp
//   but finite GGX lobe, D <= 3.2e5), the clearcoat alpha is mix(0.1, 0.001, gloss) as in the
//   explorer; Schlick weights clamp 1 - cos to [0, 1]; the subsurface term's 1 / (n.L + n.V)
//   uses max(n.L + n.V, 1e-6). GTR1's 1 - (n.h)^2 is computed as |n x h|^2 (float32
//   cancellation at gloss 1 would otherwise cost ~6% of the clearcoat peak).
// - Feature variants (app/pbgi/gather.py: material_features): a program may define
//   PRINCIPLED_NO_SUBSURFACE, PRINCIPLED_NO_ANISOTROPY, PRINCIPLED_NO_SHEEN and
//   PRINCIPLED_NO_CLEARCOAT when every material it shades has that parameter at 0; the lobes
//   below then skip that term's code (llvmpipe pays for untaken branches), and the result is
//   the same up to rounding (the isotropic GGX is the anisotropic one with ax = ay).
// - Not energy conserving by construction (Burley's model): the diffuse retro-reflection can
//   exceed albedo 1 at high roughness, and sheen and clearcoat are added on top of the base
//   layer. Reciprocal: f(L, V) = f(V, L) for every term.
//
// Packing (13 floats, the order of app/material.py ALL_NAMES / SCALAR_PARAMS, brdf.pack_params):
//   v[0..2]  base_color.rgb
//   v[3..12] subsurface, metallic, specular, specular_tint, roughness, anisotropic,
//            sheen, sheen_tint, clearcoat, clearcoat_gloss
//   as vec4s: a = (base_color.rgb, subsurface), b = (metallic, specular, specular_tint,
//   roughness), c = (anisotropic, sheen, sheen_tint, clearcoat), d = clearcoat_gloss.
// (The renderer's material table is not this packing: gen/materials.glsl's receiver_principled
// builds the struct from a receiver and its material's row, app/pbgi/gpu_layout.py.)
#ifndef SCANLIGHT_PRINCIPLED_GLSL
#define SCANLIGHT_PRINCIPLED_GLSL
#include "lib/common.glsl"

#define PRINCIPLED_PARAM_COUNT 13
const float PRINCIPLED_MIN_ALPHA = 1e-3;

struct PrincipledParams {
    vec3 base_color;        // linear RGB
    float subsurface;
    float metallic;
    float specular;
    float specular_tint;
    float roughness;
    float anisotropic;
    float sheen;
    float sheen_tint;
    float clearcoat;
    float clearcoat_gloss;
};

PrincipledParams principled_from_vec4s(vec4 a, vec4 b, vec4 c, float d) {
    return PrincipledParams(a.rgb, a.w, b.x, b.y, b.z, b.w, c.x, c.y, c.z, c.w, d);
}

PrincipledParams principled_from_floats(float v[PRINCIPLED_PARAM_COUNT]) {
    return PrincipledParams(vec3(v[0], v[1], v[2]), v[3], v[4], v[5], v[6], v[7], v[8], v[9],
                            v[10], v[11], v[12]);
}

// Burley's explorer defaults (base colour as in app/material.py).
PrincipledParams principled_default() {
    return PrincipledParams(vec3(0.82, 0.67, 0.16), 0.0, 0.0, 0.5, 0.0, 0.5, 0.0, 0.0, 0.5,
                            0.0, 1.0);
}

// Branchless orthonormal basis (Duff et al. 2017, "Building an Orthonormal Basis, Revisited"):
// right-handed, cross(t, b) = n; for n = +z: t = +x, b = +y.
void orthonormal_basis(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;  // not sign(): sign(0) = 0
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

float principled_gtr1(float n_dot_h, float sin2_h, float a) {
    float a2 = a * a;  // a <= 0.1: the a >= 1 special case of the explorer never occurs
    return (a2 - 1.0) / (PI * log(a2) * (a2 * n_dot_h * n_dot_h + sin2_h));
}

float principled_gtr2_aniso(float n_dot_h, float h_dot_x, float h_dot_y, float ax, float ay) {
    float hx = h_dot_x / ax, hy = h_dot_y / ay;
    float t = hx * hx + hy * hy + n_dot_h * n_dot_h;
    return 1.0 / (PI * ax * ay * t * t);
}

// Smith G1 / (2 n.v) (the 1 / (4 n.l n.v) of the microfacet BRDF is folded in).
float principled_smith_ggx(float n_dot_v, float alpha) {
    float a = alpha * alpha, b = n_dot_v * n_dot_v;
    return 1.0 / (n_dot_v + sqrt(a + b - a * b));
}

float principled_smith_ggx_aniso(float n_dot_v, float v_dot_x, float v_dot_y, float ax, float ay) {
    float x = v_dot_x * ax, y = v_dot_y * ay;
    return 1.0 / (n_dot_v + sqrt(x * x + y * y + n_dot_v * n_dot_v));
}

// The BRDF in two parts, for loops over many L with one V (the final gather): everything that
// depends only on the material, N, X, Y and V is computed once by principled_prepare, the rest
// per direction by principled_brdf_prepared. principled_brdf is the two in one call.
struct PrincipledPrepared {
    vec3 N, V, X, Y;
    float n_dot_v, metallic, roughness, subsurface, clearcoat, fv, ax, ay, gs_v, gr_v, cc_alpha;
    vec3 base, spec0, sheen_w;   // sheen_w = sheen * sheen_color
};

PrincipledPrepared principled_prepare(PrincipledParams p, vec3 V, vec3 N, vec3 X, vec3 Y) {
    PrincipledPrepared q;
    q.N = N; q.V = V; q.X = X; q.Y = Y;
    q.n_dot_v = dot(N, V);
    q.base = clamp(p.base_color, 0.0, 1.0);
    q.subsurface = clamp(p.subsurface, 0.0, 1.0);
    q.metallic = clamp(p.metallic, 0.0, 1.0);
    float specular = clamp(p.specular, 0.0, 1.0);
    float specular_tint = clamp(p.specular_tint, 0.0, 1.0);
    q.roughness = clamp(p.roughness, 0.0, 1.0);
    float anisotropic = clamp(p.anisotropic, 0.0, 1.0);
    float sheen = clamp(p.sheen, 0.0, 1.0);
    float sheen_tint = clamp(p.sheen_tint, 0.0, 1.0);
    q.clearcoat = clamp(p.clearcoat, 0.0, 1.0);
    float clearcoat_gloss = clamp(p.clearcoat_gloss, 0.0, 1.0);
    vec3 base = q.base;
    float lum = 0.3 * base.r + 0.6 * base.g + 0.1 * base.b;
    vec3 tint = lum > 0.0 ? base / lum : vec3(1.0);
    q.spec0 = mix(specular * 0.08 * mix(vec3(1.0), tint, specular_tint), base, q.metallic);
    q.sheen_w = sheen * mix(vec3(1.0), tint, sheen_tint);
    q.fv = schlick_weight(q.n_dot_v);
    float aspect = sqrt(1.0 - 0.9 * anisotropic);
    float r2 = q.roughness * q.roughness;
    q.ax = max(PRINCIPLED_MIN_ALPHA, r2 / aspect);
    q.ay = max(PRINCIPLED_MIN_ALPHA, r2 * aspect);
    q.gs_v = principled_smith_ggx_aniso(q.n_dot_v, dot(V, X), dot(V, Y), q.ax, q.ay);
    q.gr_v = principled_smith_ggx(q.n_dot_v, 0.25);
    q.cc_alpha = mix(0.1, 0.001, clearcoat_gloss);
    return q;
}

// The BRDF's scalar factors for one direction, before the material's colours multiply them:
//   base = (diffuse base + fh sheen_w) (1 - metallic), spec = spec mix(spec0, 1, fh),
//   coat = clearcoat coat
// (principled_lobes_prepared). The gather's GATHER_PARTS variant sums L w times each factor
// apart, so that a new base colour, metallic, specular, sheen or clearcoat amount is a
// recombination of the sums (app/pbgi/gather_parts.py), not a new gather.
struct PrincipledParts {
    float diffuse;   // Burley's diffuse (subsurface blended in) / pi
    float fh;        // Schlick's weight at l.h: the sheen and the specular Fresnel
    float spec;      // GGX D G (the 1 / (4 n.l n.v) folded in), before the Fresnel
    float coat;      // the clearcoat lobe at clearcoat 1
};
PrincipledParts principled_parts_prepared(PrincipledPrepared q, vec3 L) {
    PrincipledParts r = PrincipledParts(0.0, 0.0, 0.0, 0.0);
    vec3 N = q.N, V = q.V;
    float n_dot_l = dot(N, L);
    float n_dot_v = q.n_dot_v;
    if (n_dot_l <= 0.0 || n_dot_v <= 0.0) return r;
    vec3 H = normalize(L + V);
    float n_dot_h = dot(N, H);
    float l_dot_h = dot(L, H);
    float fl = schlick_weight(n_dot_l), fv = q.fv;
    float fd90 = 0.5 + 2.0 * l_dot_h * l_dot_h * q.roughness;
    float fd = mix(1.0, fd90, fl) * mix(1.0, fd90, fv);
#ifdef PRINCIPLED_NO_SUBSURFACE
    float diffuse = fd;
#else
    float fss90 = l_dot_h * l_dot_h * q.roughness;
    float fss = mix(1.0, fss90, fl) * mix(1.0, fss90, fv);
    float ss = 1.25 * (fss * (1.0 / max(n_dot_l + n_dot_v, 1e-6) - 0.5) + 0.5);
    float diffuse = mix(fd, ss, q.subsurface);
#endif
#ifdef PRINCIPLED_NO_ANISOTROPY
    // GTR2 with ax = ay: a^2 / (pi (sin^2 + a^2 cos^2)^2), sin^2 = |n x h|^2 (no cancellation)
    vec3 nxh_s = cross(N, H);
    float a2 = q.ax * q.ax, t = dot(nxh_s, nxh_s) + a2 * n_dot_h * n_dot_h;
    float ds = a2 / (PI * t * t);
    float gs = principled_smith_ggx(n_dot_l, q.ax) * q.gs_v;
#else
    float ds = principled_gtr2_aniso(n_dot_h, dot(H, q.X), dot(H, q.Y), q.ax, q.ay);
    float gs = principled_smith_ggx_aniso(n_dot_l, dot(L, q.X), dot(L, q.Y), q.ax, q.ay) * q.gs_v;
#endif
    r.diffuse = INV_PI * diffuse;
    r.fh = schlick_weight(l_dot_h);
    r.spec = gs * ds;
#ifndef PRINCIPLED_NO_CLEARCOAT
    vec3 nxh = cross(N, H);
    float dr = principled_gtr1(n_dot_h, dot(nxh, nxh), q.cc_alpha);
    float fr = mix(0.04, 1.0, r.fh);
    float gr = principled_smith_ggx(n_dot_l, 0.25) * q.gr_v;
    r.coat = 0.25 * gr * fr * dr;
#endif
    return r;
}
// The BRDF's three lobes apart (the lobe micro-buffer gathers the specular ones through its own
// directions, app/pbgi/lobe.py): ``base`` = diffuse, subsurface and sheen (wide lobes), ``spec`` =
// the GGX specular lobe, ``coat`` = the clearcoat lobe; f = base + spec + coat.
void principled_lobes_prepared(PrincipledPrepared q, vec3 L, out vec3 base, out vec3 spec,
                               out vec3 coat) {
    PrincipledParts r = principled_parts_prepared(q, L);
#ifdef PRINCIPLED_NO_SHEEN
    base = r.diffuse * q.base * (1.0 - q.metallic);
#else
    base = (r.diffuse * q.base + r.fh * q.sheen_w) * (1.0 - q.metallic);
#endif
    spec = r.spec * mix(q.spec0, vec3(1.0), r.fh);
    coat = vec3(q.clearcoat * r.coat);
}
vec3 principled_brdf_prepared(PrincipledPrepared q, vec3 L) {
    vec3 base, spec, coat;
    principled_lobes_prepared(q, L, base, spec, coat);
    return base + spec + coat;
}

vec3 principled_brdf(PrincipledParams p, vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y) {
    return principled_brdf_prepared(principled_prepare(p, V, N, X, Y), L);
}

// Convenience for callers without a tangent (builds the frame on every call; hoist
// orthonormal_basis out of loops that share N).
vec3 principled_brdf_iso(PrincipledParams p, vec3 L, vec3 V, vec3 N) {
    vec3 X, Y;
    orthonormal_basis(N, X, Y);
    return principled_brdf(p, L, V, N, X, Y);
}
#endif
