// How many lobe micro-pixels one receiver uses (pbgi_lobe.glsl's walk and pbgi_gather.glsl's
// read agree through this one function). The buffer's rings x sectors (M / 2 a side,
// app/pbgi/lobe.py) are for a clearcoat, whose micro-pixels are split between two lobes (its
// GTR1 lobe and the base's specular): with fewer, single pixels of the white furnace were 22%
// off (clearcoat 1 over roughness 0.1, 8 x 8). One lobe alone takes 2/3 of each side, rounded
// up (at least LOBE_SINGLE_MIN): 8 x 8 of the 12 x 12 at M 24, against Mitsuba (apartment, Hybrid)
// metal 2.2 -> 3.2% pooled at roughness 0.3, 1.1 -> 1.4% at 0.2, the same below 0.1, for
// 55-60% of the lobe walk's time. A lobe that carries only a share s of what the receiver
// reflects (a dielectric's 4% specular over its diffuse) takes sqrt(s) of that again, at
// least LOBE_WEAK_SIDE a side: the lobe's quantisation is noise of relative size
// ~1 / sqrt(cells) in the lobe's part, so the receiver's error from it is ~ s / sqrt(cells),
// and sqrt(s) of the side keeps that at or below a metal's - while the walk's work (its visits
// and its ray tests both follow the micro-pixels' size and count) falls with it. s is estimated
// at the receiver's view angle: the lobe's specular (Schlick towards 1 at grazing, times
// lobe_spec_share) against the diffuse albedo (1 - metallic) x base; roughness's shadowing is
// left out (a larger s: safe).
// Needs lib/common.glsl, lib/principled.glsl, lib/lobe.glsl.
#ifndef SCANLIGHT_LOBE_SIZE_GLSL
#define SCANLIGHT_LOBE_SIZE_GLSL

#ifndef LOBE_WEAK_SIDE
#define LOBE_WEAK_SIDE 4u
#endif
#define LOBE_SINGLE_MIN 8u

float lobe_share(PrincipledPrepared q, bvec2 terms, float glossy_below) {
    float spec = terms.x ? luminance(mix(q.spec0, vec3(1.0), q.fv))
                           * lobe_spec_share(q, glossy_below) : 0.0;
    float diffuse = (1.0 - q.metallic) * luminance(q.base);
    return clamp(spec / max(spec + diffuse, 1e-6), 0.0, 1.0);
}

uvec2 lobe_size(PrincipledPrepared q, bvec2 terms, float glossy_below, uint rings,
                uint sectors) {
    uvec2 full = uvec2(rings, sectors);
    if (terms.y) return full;                                  // a clearcoat: two lobes
    uvec2 single = clamp((2u * full + 2u) / 3u, min(full, uvec2(LOBE_SINGLE_MIN)), full);
    float f = sqrt(lobe_share(q, terms, glossy_below));
    return clamp(uvec2(ceil(vec2(single) * f)), min(single, uvec2(LOBE_WEAK_SIDE)), single);
}
#endif
