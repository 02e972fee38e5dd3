"""The BSH building blocks against independent references: Morton codes, count-leading-zeros,
Karras's radix tree, sphere and cone merges, cone packing, the spacing estimate."""

from __future__ import annotations

import numpy as np
import pytest

from app.pbgi import hierarchy as H
from app.pbgi import layout


def test_msb64_matches_python_bit_length():
    rng = np.random.default_rng(0)
    vals = [1, 2, 3, 2**31 - 1, 2**31, 2**32 - 1, 2**32, 2**32 + 1, 2**53 - 1, 2**53 + 1,
            2**62, 2**63 - 1, 2**63, 2**64 - 1]
    vals += [int(v) for v in rng.integers(1, 2**63, 2000, dtype=np.uint64)]
    vals += [1 << int(b) for b in rng.integers(0, 64, 200)]
    x = np.array(vals, dtype=np.uint64)
    assert H.msb64(x).tolist() == [v.bit_length() - 1 for v in vals]


def test_morton_codes_interleave_bits():
    rng = np.random.default_rng(1)
    c = rng.integers(0, 2**21, (300, 3))
    c[0] = 2**21 - 1
    c[1] = 0

    def ref(x, y, z):
        code = 0
        for b in range(21):
            code |= ((x >> b) & 1) << (3 * b + 2) | ((y >> b) & 1) << (3 * b + 1)
            code |= ((z >> b) & 1) << (3 * b)
        return code

    got = H.morton_codes(c[:, 0], c[:, 1], c[:, 2])
    assert [int(v) for v in got] == [ref(*map(int, row)) for row in c]
    assert int(got[0]) == 2**63 - 1


def _reference_radix(keys):
    """Binary radix tree by recursive splitting at the first differing bit (nested tuples)."""
    def build(lo, hi):
        if lo == hi:
            return lo
        bit = (int(keys[lo]) ^ int(keys[hi])).bit_length() - 1
        split = lo
        while not (int(keys[split + 1]) >> bit) & 1:
            split += 1
        return (build(lo, split), build(split + 1, hi))
    return build(0, len(keys) - 1)


def _karras_tree(keys):
    left, right = H._karras(keys)
    n_int = len(keys) - 1

    def conv(node):
        if node >= n_int:
            return int(node - n_int)
        return (conv(left[node]), conv(right[node]))
    return conv(0)


@pytest.mark.parametrize("kind", ["random", "consecutive", "clustered", "two"])
def test_karras_builds_the_radix_tree(kind):
    rng = np.random.default_rng(2)
    if kind == "random":
        keys = np.unique(rng.integers(0, 2**63, 400, dtype=np.uint64))
    elif kind == "consecutive":
        keys = np.arange(5, 133, dtype=np.uint64)
    elif kind == "clustered":
        base = rng.integers(0, 2**60, 8, dtype=np.uint64)
        keys = np.unique((base[:, None] + rng.integers(0, 64, (8, 30), dtype=np.uint64)).ravel())
    else:
        keys = np.array([0, 2**63 - 1], dtype=np.uint64)
    assert _karras_tree(keys) == _reference_radix(keys)


def _sphere_contains(c, r, c2, r2):
    return np.linalg.norm(c2 - c, axis=0) + r2 <= r * (1 + 1e-12)


def test_merge_spheres_contains_and_is_smallest():
    rng = np.random.default_rng(3)
    k = 5000
    c1, c2 = rng.normal(size=(3, k)), rng.normal(size=(3, k))
    r1, r2 = rng.random(k) * 2, rng.random(k) * 2
    c1, r1 = H.round_spheres(c1, r1)
    c2, r2 = H.round_spheres(c2, r2)
    c, r = H.merge_spheres(c1, r1, c2, r2)
    assert _sphere_contains(c, r, c1, r1).all() and _sphere_contains(c, r, c2, r2).all()
    assert np.array_equal(c, c.astype(np.float32)) and np.array_equal(r, r.astype(np.float32))
    d = np.linalg.norm(c2 - c1, axis=0)
    best = np.maximum(np.maximum(r1, r2), 0.5 * (d + r1 + r2))  # exact smallest enclosing radius
    assert (r <= best * (1 + 1e-6) + 1e-12).all()
    nested = d + r2 <= r1
    assert np.array_equal(c[:, nested], c1[:, nested]) and np.array_equal(r[nested], r1[nested])


def _random_cones(rng, k):
    a = rng.normal(size=(3, k))
    a /= np.linalg.norm(a, axis=0)
    return a, rng.random(k) * np.pi * 0.6


def _cone_contains(a, t, b, s, samples=24):
    """Border directions of cone (b, s) are inside cone (a, t) (within 1e-9 rad)."""
    perp = np.cross(b.T, np.where(np.abs(b[0:1]) < 0.9, [[1.0], [0], [0]], [[0], [1.0], [0]]).T).T
    perp /= np.linalg.norm(perp, axis=0)
    perp2 = np.cross(b.T, perp.T).T
    ok = np.ones(b.shape[1], dtype=bool)
    for phi in np.linspace(0, 2 * np.pi, samples, endpoint=False):
        v = b * np.cos(s) + (perp * np.cos(phi) + perp2 * np.sin(phi)) * np.sin(s)
        ang = np.arccos(np.clip((v * a).sum(axis=0), -1, 1))
        ok &= ang <= t + 1e-7
    return ok


def test_merge_cones_contains_both_and_is_minimal():
    rng = np.random.default_rng(4)
    a1, t1 = _random_cones(rng, 3000)
    a2, t2 = _random_cones(rng, 3000)
    a, t = H.merge_cones(a1, t1, a2, t2)
    assert np.allclose(np.linalg.norm(a, axis=0), 1.0)
    assert _cone_contains(a, t, a1, t1).all() and _cone_contains(a, t, a2, t2).all()
    g = np.arccos(np.clip((a1 * a2).sum(axis=0), -1, 1))
    lower = np.maximum(np.maximum(t1, t2), np.minimum(0.5 * (t1 + t2 + g), np.pi))
    np.testing.assert_allclose(t, lower, atol=1e-9)  # the closed form is exact, not a bound


def test_merge_cones_parallel_and_opposite_axes():
    z = np.array([[0.0], [0.0], [1.0]])
    # opposite unit normals -> half-angle pi/2
    a, t = H.merge_cones(z, np.zeros(1), -z, np.zeros(1))
    assert t[0] == pytest.approx(np.pi / 2) and abs(a[2, 0]) < 1e-12
    # nearly opposite: still contains both
    eps = 1e-8
    b = np.array([[eps], [0.0], [-1.0]]) / np.sqrt(1 + eps**2)
    a, t = H.merge_cones(z, np.array([0.1]), b, np.array([0.2]))
    assert _cone_contains(a, t, z, np.array([0.1])).all()
    assert _cone_contains(a, t, b, np.array([0.2])).all()
    # nearly parallel with equal angles
    c = np.array([[1e-9], [0.0], [1.0]])
    c /= np.linalg.norm(c)
    a, t = H.merge_cones(z, np.array([0.3]), c, np.array([0.3]))
    assert _cone_contains(a, t, c, np.array([0.3])).all() and t[0] < 0.3 + 1e-6
    # wide cones saturate at pi
    a, t = H.merge_cones(z, np.array([2.5]), -z, np.array([2.5]))
    assert t[0] == np.pi


def test_pack_cone_is_conservative_and_round_trips_the_layout():
    rng = np.random.default_rng(5)
    a, t = _random_cones(rng, 4000)
    t[:10] = 0.0
    t[10:20] = np.pi
    words = layout.pack_cone(a.T, t)
    axis, angle = layout.decode_cone(words)
    assert _cone_contains(axis.T, angle, a, t).all()
    assert (angle - t <= 2.5 * layout.ANGLE_STEP).all()  # tight: quantisation only
    assert (angle[10:20] == np.pi).all()
    dec = layout.decode(np.zeros(3, dtype=layout.NODE_DTYPE))
    assert dec["cone_cos"].shape == (3,)


def test_layout_dtype_is_40_bytes_and_matches_fields():
    dt = layout.NODE_DTYPE
    assert dt.itemsize == 40 == layout.NODE_BYTES
    for name, base, comps, word in layout.FIELDS:
        assert dt.fields[name][1] == 4 * word
        assert dt.fields[name][0].base == np.dtype(base)
    text = layout.glsl_header()
    assert "#define NODE_BINDING 3" in text and "Node load_node(uint i)" in text
    assert f"#define BSH_NODE_WORDS {layout.NODE_WORDS}u" in text


def test_median_spacing_exact_and_extrapolated():
    rng = np.random.default_rng(6)
    # small: exact median nearest-neighbour distance of a jittered grid
    g = np.stack(np.meshgrid(np.arange(30), np.arange(30), indexing="ij"), -1).reshape(-1, 2)
    p = np.column_stack([g * 0.01, np.zeros(len(g))])
    assert H.median_spacing(p) == pytest.approx(0.01)
    # large surface cloud: the extrapolation lands near the exact value
    from scipy.spatial import cKDTree
    n = 200_000
    q = np.column_stack([rng.random((n, 2)) * [4.0, 3.0], np.zeros(n)])
    exact = np.median(cKDTree(q).query(q[:20000], k=2)[0][:, 1])
    assert H.median_spacing(q) == pytest.approx(exact, rel=0.1)
    assert H.median_spacing(np.zeros((50, 3))) == 0.0
