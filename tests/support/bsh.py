"""Structural and geometric invariants of a built bounding sphere hierarchy (asserted by the
BSH tests on every tree they build)."""

from __future__ import annotations

import numpy as np

from app.pbgi import layout


def check_invariants(h, positions, normals, colors):
    """Assert every structural and geometric guarantee of a built hierarchy."""
    nodes = h.nodes
    m = len(nodes)
    d = layout.decode(nodes)
    idx = np.arange(m)
    skip = d["skip"]
    for key in ("center", "radius", "color", "cone_axis", "cone_cos"):
        assert np.isfinite(d[key]).all(), key
    assert (d["radius"] >= 0).all()
    assert ((d["cone_angle"] >= 0) & (d["cone_angle"] <= np.pi + 1e-12)).all()

    # depth-first layout: subtree of i = [i, skip[i]); children i+1 and skip[i+1]
    assert skip[0] == m
    assert ((skip > idx) & (skip <= m)).all()
    leaf = skip == idx + 1
    assert np.array_equal(leaf, d["is_leaf"])
    inner = np.flatnonzero(~leaf)
    left = inner + 1
    right = skip[left]
    assert (right < skip[inner]).all()
    assert np.array_equal(skip[right], skip[inner])  # left + right subtrees fill the parent's
    children = np.concatenate([left, right])
    assert np.array_equal(np.sort(children), idx[1:])  # every non-root node: exactly one parent
    parent = np.full(m, -1)
    parent[left] = inner
    parent[right] = inner
    assert np.array_equal(parent, h.parents())
    assert np.array_equal(d["count"][inner], d["count"][left] + d["count"][right])

    # the leaves partition the points; node i holds the points whose leaf is in [i, skip[i])
    pn = h.point_node.astype(np.int64)
    assert len(pn) == len(positions) and leaf[pn].all()
    order = np.argsort(pn, kind="stable")
    pn_sorted = pn[order]
    lo = np.searchsorted(pn_sorted, idx)
    hi = np.searchsorted(pn_sorted, skip)
    assert np.array_equal(hi - lo, d["count"])
    assert d["count"][0] == len(positions)

    # colour = mean of the points below (point-count weighted)
    cum = np.vstack([np.zeros(3), np.cumsum(np.asarray(colors, np.float64)[order], axis=0)])
    mean = (cum[hi] - cum[lo]) / d["count"][:, None]
    scale = max(1.0, float(np.abs(colors).max()))
    np.testing.assert_allclose(d["color"], mean, rtol=2e-6, atol=1e-9 * scale * len(positions))

    # child spheres inside parent spheres, with the stored float32 values
    c = d["center"].astype(np.float64)
    r = d["radius"].astype(np.float64)
    for ch in (left, right):
        gap = np.linalg.norm(c[ch] - c[inner], axis=1) + r[ch] - r[inner]
        assert (gap <= 1e-12 * r[inner]).all(), gap.max()

    # every point inside the sphere and the normal cone of its leaf and of each ancestor
    rel = np.stack([positions[:, k] - h.origin[k] for k in range(3)], axis=1)
    nrm = unit(normals)
    known = np.linalg.norm(nrm, axis=1) > 0.5
    node = pn.copy()
    pts = np.arange(len(pn))
    for _ in range(200):
        if not len(pts):
            break
        dist = np.linalg.norm(rel[pts] - c[node], axis=1)
        assert (dist <= r[node]).all(), (dist - r[node]).max()
        k = known[pts]
        dots = np.einsum("ij,ij->i", nrm[pts][k], d["cone_axis"][node[k]])
        assert (dots >= d["cone_cos"][node[k]] - 1e-6).all()
        up = parent[node]
        keep = up >= 0
        pts, node = pts[keep], up[keep]
    else:
        raise AssertionError("parent chain does not end at the root")
    return d


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)
