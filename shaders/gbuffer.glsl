// G-buffer of the asset (MRT, RGBA32F): what every PBGI mode and the final gather read per pixel.
// Render target k is slot k of the receiver record (app/pbgi/gpu_layout.py RECEIVER, the
// locations below come from it), except that target 0's w is the coverage (1 on covered pixels),
// which the compaction replaces by the pixel index:
//   position relative to the hierarchy origin; shading normal (normal map applied, bent towards
//   the viewer), material id; tangent orthogonalised against the shading normal, roughness
//   (factor x texture); base colour (linear, factor x texture), metallic (factor x texture)
// The shading normal is bent so that n . v >= 0.01: interpolated and normal-mapped normals can
// face away from the camera at silhouettes, where the BRDF would be 0 (black rims).

// vertex inputs in_position, ... and the RECEIVER_SLOT_* output locations:
#include "gen/gbuffer.glsl"

#ifdef VERTEX_SHADER
uniform mat4 u_view;
uniform mat4 u_proj;
out vec3 v_position;
out vec3 v_normal;
out vec2 v_uv;
out vec4 v_tangent;
void main() {
    v_position = in_position;
    v_normal = in_normal;
    v_uv = in_uv;
    v_tangent = in_tangent;
    gl_Position = u_proj * u_view * vec4(in_position, 1.0);
}
#endif

#ifdef FRAGMENT_SHADER
in vec3 v_position;
in vec3 v_normal;
in vec2 v_uv;
in vec4 v_tangent;
uniform vec3 u_camera;          // relative to the hierarchy origin
uniform float u_material_id;
uniform vec3 u_base_color;
uniform float u_metallic;
uniform float u_roughness;
uniform bool u_has_base_tex;
uniform bool u_has_mr_tex;
uniform bool u_has_normal_tex;
uniform sampler2D u_base_tex;
uniform sampler2D u_mr_tex;
uniform sampler2D u_normal_tex;
layout(location = RECEIVER_SLOT_POSITION) out vec4 o_position;   // w: coverage
layout(location = RECEIVER_SLOT_NORMAL) out vec4 o_normal;       // w: material id
layout(location = RECEIVER_SLOT_TANGENT) out vec4 o_tangent;     // w: roughness
layout(location = RECEIVER_SLOT_BASE_COLOR) out vec4 o_base;     // w: metallic

void main() {
    vec3 V = normalize(u_camera - v_position);
    vec3 ng = normalize(v_normal);
    if (!gl_FrontFacing) ng = -ng;           // open meshes seen from behind
    vec3 t = v_tangent.xyz - ng * dot(ng, v_tangent.xyz);
    t = dot(t, t) > 1e-12 ? normalize(t) : normalize(abs(ng.x) < 0.9 ? cross(ng, vec3(1, 0, 0))
                                                                      : cross(ng, vec3(0, 0, 1)));
    vec3 b = (v_tangent.w < 0.0 ? -1.0 : 1.0) * cross(ng, t);
    vec3 n = ng;
    if (u_has_normal_tex) {
        vec3 ts = texture(u_normal_tex, v_uv).xyz * 2.0 - 1.0;
        vec3 m = t * ts.x + b * ts.y + ng * ts.z;
        if (dot(m, m) > 1e-12) n = normalize(m);
    }
    float nv = dot(n, V);
    if (nv < 0.01) n = normalize(n + (0.01 - nv) * V);
    t = t - n * dot(n, t);
    t = dot(t, t) > 1e-12 ? normalize(t) : normalize(cross(n, b));

    vec3 base = u_base_color;
    if (u_has_base_tex) base *= texture(u_base_tex, v_uv).rgb;
    float metallic = u_metallic, roughness = u_roughness;
    if (u_has_mr_tex) {
        vec4 mr = texture(u_mr_tex, v_uv);
        roughness *= mr.g;
        metallic *= mr.b;
    }
    o_position = vec4(v_position, 1.0);
    o_normal = vec4(n, u_material_id);
    o_tangent = vec4(t, clamp(roughness, 0.0, 1.0));
    o_base = vec4(clamp(base, 0.0, 1.0), clamp(metallic, 0.0, 1.0));
}
#endif
