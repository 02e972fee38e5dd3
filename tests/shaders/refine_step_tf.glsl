// One refinement step as the paper's design runs it: a vertex + geometry shader writing transform
// feedback. Every pair (node, pixel) emits its two children; the arithmetic stands in for the
// refinement test (the same in refine_step_compute.glsl). tests/pbgi/test_refine_backends.py.

#ifdef VERTEX_SHADER
in uvec2 in_pair;
out uvec2 v_pair;
void main() { v_pair = in_pair; }
#endif

#ifdef GEOMETRY_SHADER
layout(points) in;
layout(points, max_vertices = 2) out;
in uvec2 v_pair[];
out uvec2 out_pair;
uniform uint u_limit;
void main() {
    uvec2 p = v_pair[0];
    float f = sin(float(p.x) * 0.001) * cos(float(p.y) * 0.002);
    if (p.x < u_limit && f > -2.0) {
        out_pair = uvec2(2u * p.x + 1u, p.y); EmitVertex(); EndPrimitive();
        out_pair = uvec2(2u * p.x + 2u, p.y); EmitVertex(); EndPrimitive();
    }
}
#endif
