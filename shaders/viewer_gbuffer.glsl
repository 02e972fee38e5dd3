// The viewer's asset G-buffer: shading normal and eye distance per pixel, rasterised at the
// full viewport resolution every frame (cheap). It guides the joint bilateral upsampling of the
// reduced-resolution GI (viewer_composite.glsl) and depth-tests the asset against the room.
// Target: RGBA32F (normal.xyz, eye depth along -z in metres); cleared to 0, so w > 0 = covered.
// Positions arrive relative to an origin (float64 shift on the CPU), as in splat.glsl.

#ifdef VERTEX_SHADER
layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
uniform mat4 u_view;
uniform mat4 u_proj;
out vec3 v_normal;
out float v_depth;
void main() {
    vec4 eye = u_view * vec4(in_position, 1.0);
    gl_Position = u_proj * eye;
    v_normal = in_normal;  // world space: the composite only compares normals with each other
    v_depth = -eye.z;
}
#endif

#ifdef FRAGMENT_SHADER
in vec3 v_normal;
in float v_depth;
layout(location = 0) out vec4 out_gbuf;
void main() {
    out_gbuf = vec4(normalize(v_normal), max(v_depth, 1e-6));
}
#endif
