"""Hybrid PBGI (paper Section 5.2.2), in two variants behind one cut finder.

Default - far-field sharing (app/pbgi/farfield.py, ``parallax_tolerance`` = eps > 0): the walk
is shared where its *result* is the same for neighbouring receivers. Blocks of up to 8 x 8
receivers with normals within 0.1 rad walk and rasterise the far field (nodes farther than
D = block radius / (eps x 2 / M): they move by < eps micro-pixels across the block) once; each
receiver walks the near field into a copy. This is what makes Hybrid faster than Classic on
llvmpipe (README.md, Tests and benchmarks): 12-14x at 512 x 512 close-up, where the exact
variant below gets 1.1x.

``parallax_tolerance`` = 0 - the paper's exact Hybrid: refine (node, pixel) pairs in parallel
only while the node is large, Omega(A) > Omega_tr = omega_tr_factor * Omega (Omega = 2 pi / M^2,
eq. 5), and the pixel is not at the finest level; every other pair becomes an item of the second
stream, which a per-receiver depth-first walk with Classic's rules finishes (the engine is
app.pbgi.mipmapped.PairRefiner, the walk shaders/pbgi_finish.glsl with lib/pbgi_cut.glsl, the
same decision and rasteriser code as Classic).

Same cut as Classic (exact variant): the parallel phase only ever (a) culls a node that every
receiver below the pixel would cull, (b) replaces a node by its children where every receiver
below would descend (or cull it, and then its children too: their spheres and cones lie inside
its own), and (c) hands the rest to the finishing walk, which applies Classic's rules per
receiver. So the cut - and with the deterministic tie-break of the micro-buffer write, every
micro-buffer entry - is the one Classic finds, up to float rounding exactly at a cull threshold
(tests/test_pbgi_modes.py compares the micro-buffers entry by entry and finds them identical).

Transform feedback or compute: ``refine_backend_figures`` runs the same refinement step (read a
pair, test it, emit its children) once as a vertex + geometry shader writing transform feedback
(the paper's design) and once as a compute dispatch with an atomic append, on this machine.
The compute version is what the modes use; the note in the report has the figures.
"""

from __future__ import annotations

import time

import numpy as np

from app.pbgi.farfield import DEFAULT_TOLERANCE, FarFieldShare
from app.pbgi.mipmapped import AllocationError, PairRefiner  # noqa: F401 (the renderer's retry)

DEFAULT_OMEGA_TR_FACTOR = 32.0


class HybridCut:
    """Hybrid PBGI. ``parallax_tolerance`` > 0 (the default): far-field sharing
    (app/pbgi/farfield.py) - the far field walked once per block of receivers, the near field
    per receiver; 0: the paper's exact Hybrid (PairRefiner: parallel refinement above
    Omega_tr, per-receiver walks below; the same cut as Classic)."""

    name = "hybrid"
    needs_tile = True

    def __init__(self, ctx, omega_tr_factor: float = DEFAULT_OMEGA_TR_FACTOR,
                 parallax_tolerance: float = DEFAULT_TOLERANCE, **kw):
        if not omega_tr_factor > 0:
            raise ValueError(f"omega_tr_factor must be > 0, got {omega_tr_factor!r}")
        if not parallax_tolerance >= 0:
            raise ValueError(f"parallax_tolerance must be >= 0, got {parallax_tolerance!r}")
        self.omega_tr_factor = float(omega_tr_factor)
        self.parallax_tolerance = float(parallax_tolerance)
        if self.parallax_tolerance > 0:
            self.engine = FarFieldShare(ctx, tolerance=self.parallax_tolerance)
        else:
            self.engine = PairRefiner(ctx, omega_tr_factor=omega_tr_factor, **kw)

    @property
    def clears_microbuffers(self) -> bool:
        return getattr(self.engine, "clears_microbuffers", False)

    def bytes_per_receiver(self, m: int) -> int:
        return self.engine.bytes_per_receiver(m)

    def reserve_bytes(self, budget_bytes: float) -> int:
        return getattr(self.engine, "reserve_bytes", lambda b: 0)(budget_bytes)

    def fill(self, *args, **kw) -> dict:
        return self.engine.fill(*args, **kw)

    def release(self) -> None:
        self.engine.release()


_GS_VERT = """#version 430
in uvec2 in_pair;
out uvec2 v_pair;
void main() { v_pair = in_pair; }
"""

_GS_GEOM = """#version 430
layout(points) in;
layout(points, max_vertices = 2) out;
in uvec2 v_pair[];
out uvec2 out_pair;
uniform uint u_limit;
void main() {
    uvec2 p = v_pair[0];
    // the same arithmetic as the compute version: a cheap stand-in for the refinement test
    float f = sin(float(p.x) * 0.001) * cos(float(p.y) * 0.002);
    if (p.x < u_limit && f > -2.0) {
        out_pair = uvec2(2u * p.x + 1u, p.y); EmitVertex(); EndPrimitive();
        out_pair = uvec2(2u * p.x + 2u, p.y); EmitVertex(); EndPrimitive();
    }
}
"""

_CS = """#version 430
layout(local_size_x = 64) in;
layout(rg32ui, binding = 1) uniform readonly uimage2D in_pairs;
layout(rg32ui, binding = 2) uniform writeonly uimage2D out_pairs;
layout(std430, binding = 0) buffer Counter { uint count; };
uniform uint u_n;
uniform uint u_limit;
ivec2 texel(uint i) { return ivec2(int(i & 4095u), int(i >> 12u)); }
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= u_n) return;
    uvec2 p = imageLoad(in_pairs, texel(i)).xy;
    float f = sin(float(p.x) * 0.001) * cos(float(p.y) * 0.002);
    if (p.x < u_limit && f > -2.0) {
        uint slot = atomicAdd(count, 2u);
        imageStore(out_pairs, texel(slot), uvec4(2u * p.x + 1u, p.y, 0u, 0u));
        imageStore(out_pairs, texel(slot + 1u), uvec4(2u * p.x + 2u, p.y, 0u, 0u));
    }
}
"""


def refine_backend_figures(ctx, n_pairs: int = 1 << 18, repeat: int = 3) -> dict:
    """ns per input pair of one refinement step (every pair emits two) with a geometry shader
    + transform feedback vs a compute shader + atomic append, best of ``repeat``."""
    import moderngl
    n = int(n_pairs)
    pairs = np.stack([np.arange(n, dtype=np.uint32), np.arange(n, dtype=np.uint32) * 7], 1)
    limit = np.uint32(0xFFFFFFFF)
    # geometry shader + transform feedback
    prog = ctx.program(vertex_shader=_GS_VERT, geometry_shader=_GS_GEOM, varyings=["out_pair"])
    prog["u_limit"] = int(limit)
    vbo = ctx.buffer(pairs.tobytes())
    out = ctx.buffer(reserve=2 * n * 8)
    vao = ctx.vertex_array(prog, [(vbo, "2u4", "in_pair")])
    query = ctx.query(primitives=True)
    gs = []
    for _ in range(repeat + 1):
        ctx.finish()
        t0 = time.perf_counter()
        with query:
            vao.transform(out, mode=moderngl.POINTS, vertices=n)
        written = query.primitives
        ctx.finish()
        gs.append(time.perf_counter() - t0)
    ok_gs = written == 2 * n and np.array_equal(
        np.sort(np.frombuffer(out.read(), np.uint32).reshape(-1, 2)[:, 0])[:4], [1, 2, 3, 4])
    # compute + atomic append
    rows = (n + 4095) // 4096
    tin = ctx.texture((4096, rows), 2, dtype="u4")
    buf = np.zeros((rows * 4096, 2), np.uint32)
    buf[:n] = pairs
    tin.write(buf.tobytes())
    tout = ctx.texture((4096, 2 * rows), 2, dtype="u4")
    counter = ctx.buffer(reserve=4)
    cs = ctx.compute_shader(_CS)
    cs["u_n"] = n
    cs["u_limit"] = int(limit)
    tin.bind_to_image(1, read=True, write=False)
    tout.bind_to_image(2, read=False, write=True)
    counter.bind_to_storage_buffer(0)
    cp = []
    for _ in range(repeat + 1):
        counter.write(b"\0\0\0\0")
        ctx.finish()
        t0 = time.perf_counter()
        cs.run((n + 63) // 64)
        ctx.memory_barrier()
        got = int(np.frombuffer(counter.read(), np.uint32)[0])
        cp.append(time.perf_counter() - t0)
    for obj in (prog, vbo, out, vao, tin, tout, counter, cs):
        obj.release()
    return {"pairs": n, "ns_per_pair_geometry_tf": min(gs[1:]) / n * 1e9,
            "ns_per_pair_compute": min(cp[1:]) / n * 1e9,
            "geometry_tf_correct": bool(ok_gs), "compute_correct": got == 2 * n}
