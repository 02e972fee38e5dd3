"""Running a test's compute shader over SSBOs: the inputs bound at 0 .. k-1, the output at k,
the uniforms set, the output read back - the set-up every GLSL check in tests/ shares."""

from __future__ import annotations

import numpy as np


def run_ssbo(ctx, prog, inputs, out_bytes: int, groups: int, **uniforms) -> bytes:
    """Bind ``inputs`` (bytes each) to bindings 0.. and a new ``out_bytes`` buffer after them,
    set ``uniforms`` on ``prog``, dispatch ``groups`` work groups and return the output."""
    bufs = [ctx.buffer(np.ascontiguousarray(a).tobytes() if isinstance(a, np.ndarray) else a)
            for a in inputs] + [ctx.buffer(reserve=out_bytes)]
    try:
        for i, buf in enumerate(bufs):
            buf.bind_to_storage_buffer(i)
        for name, value in uniforms.items():
            prog[name].value = value
        prog.run(groups)
        return bufs[-1].read()
    finally:
        for buf in bufs:
            buf.release()
