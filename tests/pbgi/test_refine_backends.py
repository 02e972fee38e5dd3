"""The measurement behind the pair engine's compute passes (app/pbgi/mipmapped.py): the same
refinement step (read a pair, test it, emit its two children) as a vertex + geometry shader
writing transform feedback - the paper's design - and as a compute dispatch with an atomic
append. The test checks that both emit every pair; for the timings run

    xvfb-run -a .venv/bin/python -m tests.pbgi.test_refine_backends
"""

from __future__ import annotations

import time

import numpy as np

from tests.support import TEST_SHADERS
from app.render.programs import load_compute, load_program


def refine_backend_figures(ctx, n_pairs: int = 1 << 18, repeat: int = 3) -> dict:
    """ns per input pair of one refinement step (every pair emits two) with a geometry shader
    + transform feedback vs a compute shader + atomic append, best of ``repeat``."""
    import moderngl
    n = int(n_pairs)
    pairs = np.stack([np.arange(n, dtype=np.uint32), np.arange(n, dtype=np.uint32) * 7], 1)
    limit = 0xFFFFFFFF
    # geometry shader + transform feedback
    prog = load_program(ctx, TEST_SHADERS / "refine_step_tf.glsl",
                        stages=("VERTEX_SHADER", "GEOMETRY_SHADER"), varyings=["out_pair"])
    prog["u_limit"] = limit
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
    cs = load_compute(ctx, TEST_SHADERS / "refine_step_compute.glsl")
    cs["u_n"] = n
    cs["u_limit"] = limit
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


def test_transform_feedback_and_compute_backends_agree(ctx):
    """Both back-ends emit every pair (the timings are for a person to read, see above)."""
    f = refine_backend_figures(ctx, 1 << 12, repeat=1)
    assert f["geometry_tf_correct"] and f["compute_correct"]
    assert f["ns_per_pair_compute"] > 0 and f["ns_per_pair_geometry_tf"] > 0


if __name__ == "__main__":
    from app.render.context import get_context
    for size in (1 << 14, 1 << 18, 1 << 20):
        print(refine_backend_figures(get_context(), size))
