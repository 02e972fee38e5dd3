// A receiver's prepared BRDF as seen from the camera: the shading frame (the mesh's tangent,
// orthonormal_basis(N)'s t where it has none) and principled_prepare. The gather and the lobe
// walk (pbgi_lobe.glsl) both build it, and they must agree exactly: the walk chooses which lobes
// go to the lobe micro-buffer and how it is warped (lib/lobe.glsl) from it, the gather reads the
// buffer back with the same choice.
//
// Needs lib/principled.glsl, gen/receivers.glsl and gen/materials.glsl.
#ifndef SCANLIGHT_RECEIVER_SHADING_GLSL
#define SCANLIGHT_RECEIVER_SHADING_GLSL

PrincipledPrepared receiver_prepared(uint rid, vec3 p, vec3 N, vec3 camera) {
    vec3 V = normalize(camera - p);
    vec3 tangent = receiver_tangent(rid);
    vec3 X = tangent - N * dot(N, tangent);
    vec3 T, B;
    orthonormal_basis(N, T, B);
    X = dot(X, X) > 1e-12 ? normalize(X) : T;
    return principled_prepare(receiver_principled(rid), V, N, X, cross(N, X));
}
#endif
