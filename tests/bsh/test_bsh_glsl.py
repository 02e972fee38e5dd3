"""numpy and GLSL read the same node records: shaders/node_layout_check.glsl decodes every node
through the generated ``gen/node_layout.glsl`` and walks the tree with the documented stackless
convention; the results must match layout.decode and a brute-force search."""

from __future__ import annotations

import numpy as np
import pytest

from app.bench.bsh import local_room
from app.errors import ScanlightError
from app.pbgi import layout
from app.pbgi.hierarchy import build_bsh
from tests.support import TEST_SHADERS

WORDS = 17


@pytest.fixture(scope="module")
def gl():
    try:
        from app.render.context import get_context
        return get_context()
    except ScanlightError as exc:
        pytest.skip(f"no OpenGL context: {exc}")


@pytest.fixture(scope="module")
def tree():
    cloud = local_room(4000, seed=21)
    h = build_bsh(cloud.positions, cloud.normals, cloud.colors)
    assert h.stats["cluster_leaves"] > 0  # the records include cluster leaves
    return h


def _decode_on_gpu(ctx, h, binding=None):
    from app.render.programs import load_compute

    defines = {"MODE": 0}
    if binding is not None:
        defines["NODE_BINDING"] = binding
    prog = load_compute(ctx, TEST_SHADERS / "node_layout_check.glsl", defines)
    m = len(h.nodes)
    nodes = ctx.buffer(h.nodes.tobytes())
    out = ctx.buffer(reserve=m * WORDS * 4)
    queries = ctx.buffer(reserve=16)
    nodes.bind_to_storage_buffer(layout.NODE_BINDING_DEFAULT if binding is None else binding)
    out.bind_to_storage_buffer(1)
    queries.bind_to_storage_buffer(2)
    prog["u_count"] = m
    prog.run((m + 63) // 64)
    words = np.frombuffer(out.read(), dtype=np.uint32).reshape(m, WORDS).copy()
    for b in (nodes, out, queries):
        b.release()
    prog.release()
    return words


def _assert_agrees(words, h):
    d = layout.decode(h.nodes)
    f = words.view(np.float32)
    m = len(h.nodes)
    assert (words[:, 16] == 511).all()  # node_sphere/node_color/... agree with load_node
    assert np.array_equal(f[:, 0:3], d["center"])  # bit-exact floats
    assert np.array_equal(f[:, 3], d["radius"])
    assert np.array_equal(f[:, 4:7], d["color"])
    np.testing.assert_allclose(f[:, 7:10], d["cone_axis"], atol=2e-6)
    np.testing.assert_allclose(f[:, 10], d["cone_cos"], atol=2e-6)
    np.testing.assert_allclose(f[:, 11], d["cone_angle"], rtol=1e-6)
    assert np.array_equal(words[:, 12], d["skip"])
    assert np.array_equal(words[:, 13], d["count"])
    assert np.array_equal(words[:, 14].astype(bool), d["is_leaf"])
    inner = np.flatnonzero(~d["is_leaf"])
    assert np.array_equal(words[inner, 15], d["skip"][inner + 1])  # node_right(i)
    assert d["skip"][0] == m


def test_glsl_decodes_what_numpy_decodes(gl, tree):
    _assert_agrees(_decode_on_gpu(gl, tree), tree)


def test_node_binding_define_moves_the_buffer(gl, tree):
    _assert_agrees(_decode_on_gpu(gl, tree, binding=6), tree)


def test_stackless_walk_matches_brute_force(gl, tree):
    from app.render.programs import load_compute

    h = tree
    d = layout.decode(h.nodes)
    rng = np.random.default_rng(22)
    q = np.zeros((64, 4), np.float32)
    q[:, :3] = rng.uniform(-2.2, 2.2, (64, 3)).astype(np.float32)
    q[:, 1] = rng.uniform(-1.4, 1.4, 64)
    q[:, 3] = rng.uniform(0.05, 0.8, 64)
    q[0] = (0.0, 0.0, 0.0, 100.0)  # everything: visits every node once
    prog = load_compute(gl, TEST_SHADERS / "node_layout_check.glsl", {"MODE": 1})
    nodes = gl.buffer(h.nodes.tobytes())
    out = gl.buffer(reserve=len(q) * 16)
    qb = gl.buffer(q.tobytes())
    nodes.bind_to_storage_buffer(layout.NODE_BINDING_DEFAULT)
    out.bind_to_storage_buffer(1)
    qb.bind_to_storage_buffer(2)
    prog["u_count"] = len(q)
    prog["u_max_steps"] = 60000
    prog.run(1)
    res = np.frombuffer(out.read(), dtype=np.uint32).reshape(-1, 4)
    assert (res[:, 3] == 1).all()  # every walk reached the end marker
    assert res[0, 1] == len(h.point_node) and res[0, 2] == len(h.nodes)
    # brute force: conservative spheres => a leaf meeting the query has every ancestor meeting it
    leaf = np.flatnonzero(d["is_leaf"])
    c = d["center"][leaf].astype(np.float64)
    r = d["radius"][leaf].astype(np.float64)
    for k in range(1, len(q)):
        gap = np.linalg.norm(c - q[k, :3], axis=1) - (r + q[k, 3])
        if np.abs(gap).min() < 1e-4:
            continue  # float32 vs float64 on the boundary: not a layout question
        hit = gap <= 0
        assert res[k, 0] == hit.sum()
        assert res[k, 1] == d["count"][leaf][hit].sum()
