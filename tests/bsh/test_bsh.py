"""BSH (paper Section 5.1): invariants on random and room-like clouds, pruning, degenerate input.

``check_invariants`` recomputes everything it asserts from the points and the raw records
(subtree ranges from the skip links, means from prefix sums), independently of the build code.
"""

from __future__ import annotations

import numpy as np
import pytest

from app.bench.bsh import local_room
from app.cloud import PointCloud
from app.errors import ScanlightError
from app.pbgi import layout
from app.pbgi.hierarchy import build_bsh, build_bsh_from_cloud
from tests.support.bsh import check_invariants, unit


def random_cloud(n, seed=0, offset=0.0):
    rng = np.random.default_rng(seed)
    p = rng.random((n, 3)) * [4.0, 2.8, 4.0] + offset
    nrm = unit(rng.normal(size=(n, 3))).astype(np.float32)
    return p, nrm, rng.random((n, 3)).astype(np.float32)


def spread_and_similarity(d, h, colors, normals):
    """Per node: RMS colour distance from the mean, and mean dot(normal, decoded axis)."""
    pn = h.point_node.astype(np.int64)
    m = len(h.nodes)
    order = np.argsort(pn, kind="stable")
    lo = np.searchsorted(pn[order], np.arange(m))
    hi = np.searchsorted(pn[order], d["skip"])
    col = np.asarray(colors, np.float64)[order]
    nrm = unit(normals)[order]
    cs = np.vstack([np.zeros(3), np.cumsum(col, axis=0)])
    cq = np.concatenate([[0.0], np.cumsum((col ** 2).sum(axis=1))])
    ns = np.vstack([np.zeros(3), np.cumsum(nrm, axis=0)])
    cnt = (hi - lo).astype(np.float64)
    mean = (cs[hi] - cs[lo]) / cnt[:, None]
    var = (cq[hi] - cq[lo]) / cnt - (mean ** 2).sum(axis=1)
    sim = np.einsum("ij,ij->i", ns[hi] - ns[lo], d["cone_axis"]) / cnt
    return np.sqrt(np.maximum(var, 0)), sim


# -- invariants on typical clouds ---------------------------------------------------------------

def test_random_cloud_invariants_unpruned():
    p, n, c = random_cloud(20000, seed=1)
    h = build_bsh(p, n, c, prune=False)
    check_invariants(h, p, n, c)
    assert h.stats["clusters"] == h.stats["nodes"] == 2 * h.stats["cells"] - 1
    assert h.stats["cluster_leaves"] == 0
    assert h.nodes.dtype.itemsize == 40 and h.stats["bytes_per_node"] == 40


def test_random_cloud_pruned_keeps_invariants():
    p, n, c = random_cloud(20000, seed=2)
    h = build_bsh(p, n, c)  # random colours and normals: nothing similar enough to merge
    check_invariants(h, p, n, c)
    assert h.stats["cluster_leaves"] == 0


def test_room_cloud_invariants_and_pruning():
    cloud = local_room(30000, seed=3)
    p, n, c = cloud.positions, cloud.normals, cloud.colors
    full = build_bsh(p, n, c, prune=False)
    h = build_bsh(p, n, c)
    d = check_invariants(h, p, n, c)
    check_invariants(full, p, n, c)
    assert h.stats["nodes"] == full.stats["nodes"] and h.stats["clusters"] < full.stats["nodes"]
    assert h.stats["clusters"] == len(h.nodes)

    # a pruned leaf whose points come from more than one cell is a cluster leaf
    pairs = np.unique(np.stack([h.point_node, full.point_node], axis=1), axis=0)
    cells_per_leaf = np.bincount(pairs[:, 0], minlength=len(h.nodes))
    cluster = d["is_leaf"] & (cells_per_leaf > 1)
    assert cluster.sum() == h.stats["cluster_leaves"] > 0
    rms, sim = spread_and_similarity(d, h, c, n)
    assert (rms[cluster] < 0.01 + 1e-9).all()          # tc
    assert (sim[cluster] > 0.98 - 2e-3).all()           # tn (decoded axis is quantised)
    inner = ~d["is_leaf"]
    assert not ((rms[inner] < 0.01 * (1 - 1e-6)) & (sim[inner] > 0.98 + 2e-3)).any()
    # count-weighted means make every cluster colour the mean of its points (checked above),
    # and the leaves of the pruned tree partition the same points as the cells
    assert d["count"][d["is_leaf"]].sum() == len(p)


def test_thresholds_are_parameters():
    cloud = local_room(20000, seed=4)
    args = (cloud.positions, cloud.normals, cloud.colors)
    strict = build_bsh(*args, tc=1e-9, tn=0.999999)
    loose = build_bsh(*args, tc=0.5, tn=0.5)
    default = build_bsh(*args)
    assert loose.stats["clusters"] < default.stats["clusters"] < strict.stats["clusters"]
    check_invariants(loose, *args)


def test_demo_room_invariants():
    room = pytest.importorskip("app.demo.room")
    cloud = room.room_cloud(20000, seed=5)
    h = build_bsh_from_cloud(cloud)
    check_invariants(h, cloud.positions, cloud.normals, cloud.colors)
    assert h.stats["cluster_leaves"] > 0


def test_deterministic_and_cloud_wrapper():
    p, n, c = random_cloud(10000, seed=6)
    before = [x.copy() for x in (p, n, c)]
    a = build_bsh(p, n, c)
    assert all(np.array_equal(x, y) for x, y in zip(before, (p, n, c)))  # inputs untouched
    one = np.array([[1.0, 2.0, 3.0]])
    build_bsh(one, np.array([[0.0, 0.0, 1.0]]), np.ones((1, 3)))
    assert one.tolist() == [[1.0, 2.0, 3.0]]
    b = build_bsh(p.copy(), n.copy(), c.copy())
    assert a.nodes.tobytes() == b.nodes.tobytes()
    assert np.array_equal(a.point_node, b.point_node)
    w = build_bsh_from_cloud(PointCloud(p, n, c))
    assert w.nodes.tobytes() == a.nodes.tobytes()


def test_cell_size_parameter_and_leaf_radius_floor():
    p, n, c = random_cloud(5000, seed=7)
    h = build_bsh(p, n, c, cell_size=0.5)
    d = check_invariants(h, p, n, c)
    assert h.cell_size == 0.5 and h.stats["cells"] <= 8 * 6 * 8
    leaf = d["is_leaf"]
    assert (d["radius"][leaf] >= 0.25).all()  # default floor: half a cell
    h2 = build_bsh(p, n, c, cell_size=0.5, min_leaf_radius=0.0)
    d2 = check_invariants(h2, p, n, c)
    assert d2["radius"][d2["is_leaf"]].min() < 0.25


def test_default_cell_size_is_the_median_spacing():
    g = np.stack(np.meshgrid(np.arange(40), np.arange(40), np.arange(3), indexing="ij"), -1)
    p = g.reshape(-1, 3) * 0.02
    n = np.tile([0.0, 0.0, 1.0], (len(p), 1))
    h = build_bsh(p, n, np.ones_like(p))
    assert h.cell_size == pytest.approx(0.02, rel=1e-9)
    assert h.stats["cells"] == len(p)  # one point per cell on a grid of that spacing


# -- degenerate input ---------------------------------------------------------------------------

def test_single_point():
    p = np.array([[1.0, 2.0, 3.0]])
    n = np.array([[0.0, 1.0, 0.0]], np.float32)
    c = np.array([[5.0, 6.0, 7.0]], np.float32)
    h = build_bsh(p, n, c)
    d = check_invariants(h, p, n, c)
    assert len(h) == 1 and d["is_leaf"][0] and d["skip"][0] == 1 and d["count"][0] == 1
    assert np.allclose(h.world_centers()[0], p[0])
    assert d["cone_angle"][0] < 0.01


def test_two_points_with_opposite_normals_give_aperture_pi():
    p = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    n = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]], np.float32)
    c = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], np.float32)
    h = build_bsh(p, n, c)
    d = check_invariants(h, p, n, c)
    assert len(h) == 3 and not d["is_leaf"][0]
    # minimum cone of two opposite vectors: half-angle pi/2 (aperture pi), axis perpendicular
    assert np.pi / 2 <= d["cone_angle"][0] <= np.pi / 2 + 2 * layout.ANGLE_STEP
    assert abs(d["cone_axis"][0, 2]) < 1e-2
    np.testing.assert_allclose(d["color"][0], [0.5, 0.0, 0.5], rtol=1e-6)
    np.testing.assert_allclose(d["center"][0], [0.0, 0.0, 0.0], atol=1e-6)
    assert d["radius"][0] >= 0.5


def test_two_points_cone_is_the_minimum_cone():
    a = np.deg2rad(50.0)
    p = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    n = np.array([[0.0, 0.0, 1.0], [np.sin(a), 0.0, np.cos(a)]], np.float32)
    h = build_bsh(p, n, np.ones((2, 3), np.float32))
    d = check_invariants(h, p, n, np.ones((2, 3)))
    assert a / 2 <= d["cone_angle"][0] <= a / 2 + 3 * layout.ANGLE_STEP  # bisector, half of 50
    bis = np.array([np.sin(a / 2), 0.0, np.cos(a / 2)])
    assert np.degrees(np.arccos(np.clip(d["cone_axis"][0] @ bis, -1, 1))) < 0.2


def test_coincident_points_make_one_leaf():
    rng = np.random.default_rng(8)
    p = np.tile([[3.0, -1.0, 2.0]], (1000, 1))
    n = unit(rng.normal(size=(1000, 3))).astype(np.float32)
    c = rng.random((1000, 3)).astype(np.float32)
    h = build_bsh(p, n, c)
    d = check_invariants(h, p, n, c)
    assert len(h) == 1 and d["count"][0] == 1000
    assert d["cone_angle"][0] > np.pi / 2  # random normals: (nearly) all directions


def test_planar_cloud_with_identical_normals():
    rng = np.random.default_rng(9)
    p = np.column_stack([rng.random((5000, 2)) * 3.0, np.full(5000, 1.25)])
    n = np.tile(np.array([[0.0, 0.6, 0.8]], np.float32), (5000, 1))
    c = rng.random((5000, 3)).astype(np.float32)
    h = build_bsh(p, n, c)
    d = check_invariants(h, p, n, c)
    assert h.stats["cells"] > 1000
    # identical normals: every cone is the quantisation margin only
    assert d["cone_angle"].max() <= 2 * layout.ANGLE_STEP
    assert np.allclose(d["cone_axis"], [0.0, 0.6, 0.8], atol=2e-3)


def test_far_offset_builds_like_the_origin():
    p, n, c = random_cloud(8000, seed=10)
    near = build_bsh(p, n, c)
    far = build_bsh(p + 1e6, n, c)
    check_invariants(far, p + 1e6, n, c)
    assert far.stats["cells"] == near.stats["cells"] and len(far) == len(near)
    np.testing.assert_allclose(far.nodes["center"], near.nodes["center"], atol=1e-6)
    np.testing.assert_allclose(far.nodes["radius"], near.nodes["radius"], rtol=1e-6)
    np.testing.assert_allclose(far.origin - near.origin, 1e6, rtol=0, atol=1e-6)


def test_zero_normals_get_a_full_cone():
    p, n, c = random_cloud(2000, seed=11)
    n[:10] = 0.0
    h = build_bsh(p, n, c)
    d = check_invariants(h, p, n, c)
    assert h.stats["zero_normals"] == 10
    assert (d["cone_angle"][h.point_node[:10]] == np.pi).all()
    assert d["cone_cos"][0] == pytest.approx(-1.0)


def test_hdr_colours_beyond_half_float_survive():
    p, n, c = random_cloud(3000, seed=12)
    c[0] = [2.0e5, 7.0e4, 1.0]
    h = build_bsh(p, n, c, prune=False)
    d = check_invariants(h, p, n, c)
    assert d["color"][h.point_node[0]][0] > 65504.0


@pytest.mark.parametrize("bad", ["nan_position", "inf_colour", "empty", "shape", "cell"])
def test_bad_input_is_one_scanlight_error(bad):
    p, n, c = random_cloud(100, seed=13)
    kwargs = {}
    if bad == "nan_position":
        p[5, 1] = np.nan
    elif bad == "inf_colour":
        c[3, 0] = np.inf
    elif bad == "empty":
        p, n, c = p[:0], n[:0], c[:0]
    elif bad == "shape":
        n = n[:50]
    else:
        kwargs["cell_size"] = -1.0
    with pytest.raises(ScanlightError):
        build_bsh(p, n, c, **kwargs)


def test_cloud_source_names_the_file_in_errors():
    p, n, c = random_cloud(10, seed=14)
    p[0, 0] = np.nan
    with pytest.raises(ScanlightError) as err:
        build_bsh_from_cloud(PointCloud(p, n, c, source="scan.ply"))
    assert "scan.ply" in str(err.value)


def test_pruning_needs_both_similar_colour_and_similar_normals():
    """A uniformly coloured corner: planes collapse into clusters, but never across the bend."""
    rng = np.random.default_rng(15)
    n = 6000
    a = rng.random((n, 2))
    floor = np.column_stack([a[:, 0], np.zeros(n), a[:, 1]])
    wall = np.column_stack([a[:, 0], a[:, 1], np.full(n, -0.05)])  # no cell holds both
    p = np.vstack([floor, wall])
    nrm = np.vstack([np.tile([0.0, 1.0, 0.0], (n, 1)), np.tile([0.0, 0.0, 1.0], (n, 1))])
    c = np.full((2 * n, 3), 0.5, np.float32)
    h = build_bsh(p, nrm, c)
    d = check_invariants(h, p, nrm, c)
    assert h.stats["cluster_leaves"] >= 2 and not d["is_leaf"][0]
    on_floor = np.zeros(len(h.nodes), bool)
    on_floor[h.point_node[:n]] = True
    on_wall = np.zeros(len(h.nodes), bool)
    on_wall[h.point_node[n:]] = True
    assert not (on_floor & on_wall).any()  # no cluster spans both planes
    assert len(build_bsh(p, nrm, c, tn=-1.0).nodes) == 1  # normals ignored: one cluster
    # colours that differ by more than tc keep the planes apart even with normals ignored
    c2 = c.copy()
    c2[n:] = 0.6
    h2 = build_bsh(p, nrm, c2, tn=-1.0)
    check_invariants(h2, p, nrm, c2)
    assert h2.stats["cluster_leaves"] >= 2
    assert not np.intersect1d(h2.point_node[:n], h2.point_node[n:]).size


def test_pruning_measures_each_normal_against_the_cone_axis():
    """A uniformly coloured plane whose points hold two normals 40 degrees apart (8% tilted).
    The prune test asks for a mean dot(normal, cone axis) above tn = 0.98 (Section 5.1); the
    merged cone of both normals has its axis at their bisector, 20 degrees from each, where the
    similarity is cos 20 = 0.94, so every cluster stays on one normal. The length of the mean
    normal, 0.983, would have merged the whole plane into one cluster of similarity 0.94."""
    rng = np.random.default_rng(16)
    n = 8000
    a = rng.random((n, 2))
    p = np.column_stack([a[:, 0], np.zeros(n), a[:, 1]])
    tilted = rng.random(n) < 0.08
    t = np.radians(40.0)
    nrm = np.where(tilted[:, None], [0.0, np.cos(t), np.sin(t)], [0.0, 1.0, 0.0])
    c = np.full((n, 3), 0.5, np.float32)
    h = build_bsh(p, nrm, c)
    d = check_invariants(h, p, nrm, c)
    full = build_bsh(p, nrm, c, prune=False)             # a cluster leaf spans several cells
    pairs = np.unique(np.stack([h.point_node, full.point_node], axis=1), axis=0)
    cluster = d["is_leaf"] & (np.bincount(pairs[:, 0], minlength=len(h.nodes)) > 1)
    assert cluster.sum() == h.stats["cluster_leaves"] > 100
    _, sim = spread_and_similarity(d, h, c, nrm)
    assert (sim[cluster] > 0.98 - 2e-3).all()
    both = np.intersect1d(h.point_node[tilted], h.point_node[~tilted])
    assert not cluster[both].any()
