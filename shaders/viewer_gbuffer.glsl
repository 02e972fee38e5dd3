// The viewer's asset G-buffer: shading normal and eye distance per pixel, rasterised at the
// full viewport resolution every frame (cheap). It guides the joint bilateral upsampling of the
// reduced-resolution GI (viewer_composite.glsl) and depth-tests the asset against the room.
// Target: GUIDE_TEXEL (RGBA32F: normal, eye depth along -z in metres); cleared to 0, so
// depth > 0 = covered.
// Positions arrive relative to an origin (float64 shift on the CPU), as in splat.glsl.
// Vertex inputs (VIEWER_VERTEX) and the output texel (GUIDE_TEXEL) are declared in
// app/render/gpu_layout.py; gen/viewer_gbuffer.glsl declares in_position, in_normal, out_guide.
#include "gen/viewer_gbuffer.glsl"

#ifdef VERTEX_SHADER
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
void main() {
    out_guide = guide_texel_pack(GuideTexel(normalize(v_normal), max(v_depth, 1e-6)));
}
#endif
