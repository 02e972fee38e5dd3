"""Bounding sphere hierarchy (BSH) over the HDR point cloud: the paper's Section 5.1, in numpy.

Stages (each timed in ``Hierarchy.stats``). No Python loop over points or nodes: loops run over
the <= 64 tree levels and over fixed-size chunks of nodes (chunks keep numpy's temporaries in
cache, which whole-array steps over millions of nodes do not).

1. ``spacing``  - default cell size = median nearest-neighbour spacing (exact below 64k points,
   extrapolated from two random subsets above, see :func:`median_spacing`).
2. ``morton``   - voxelise in *box-relative* coordinates (a scan 1e6 m from the origin quantises
   like one at the origin) into 21 bits per axis, interleaved into 63-bit Morton codes.
3. ``sort``     - argsort of the codes; one leaf per non-empty cell.
4. ``leaves``   - per-cell sums (segmented reductions over the sorted points): bounding sphere
   around the mean position (radius at least ``min_leaf_radius``, default half a cell, so a leaf
   stands for its surface patch), normal cone around the mean normal, colour sums.
5. ``karras``   - internal nodes with Karras 2012 ("Maximizing parallelism in the construction of
   BVHs"): internal node i covers a key range with one end at i; direction, range end and split
   come from common-prefix lengths (highest differing bit of XORed keys). Karras's per-thread
   binary searches become numpy ``searchsorted`` calls over the sorted keys (keys are unique, one
   per cell, so no tie-breaking is needed).
6. ``propagate`` - bottom-up, one vectorised step per tree level (deepest first):

   * colour = point-count-weighted mean. The paper averages the two children equally; that lets
     a child holding 1 point weigh as much as a sibling holding 10,000. Weighting by point count
     makes every node's colour exactly the mean radiance of the points below it (for a uniform
     scan: the area-weighted mean), which is what a cluster stands for when it is splatted.
   * sphere = exact smallest sphere enclosing the two child spheres (the [FGK03] approximation is
     not needed for two spheres), then rounded conservatively to the float32 record: the centre
     is rounded, the radius grows by that rounding error and by >= one float32 ulp. Parents are
     merged from the *stored* (rounded) children, so a stored parent contains its stored
     children exactly and, transitively, every point below.
   * normal cone = **exact closed-form minimum cone containing the two child cones** (not the
     paper's four-border-vector construction): if one contains the other it is the result, else
     half-angle (t1 + t2 + g) / 2 (g = angle between axes, pi caps at "all directions") with the
     axis rotated from a1 towards a2. For two single-point leaves this is exactly the [BE05]
     minimum cone of their two normals. (Nearly) parallel or opposite axes, where the rotation
     plane is undefined, are widened explicitly; angle round-off is covered by the 1e-5 rad
     margin of the packed cone. Leaves holding several points use the cone around their mean
     normal that reaches the farthest point normal (conservative, not minimal).

7. ``prune``    - every maximal subtree with colour spread below ``tc`` and normal similarity
   above ``tn`` becomes one cluster leaf (Table 1: N.Nodes -> N.Cluster). Colour spread is the
   RMS vector distance of the point colours from the node colour, sqrt(E|c - mean|^2), exact from
   per-node sums; it bounds the paper's "average vector distance" E|c - mean| from above (Jensen),
   so a subtree we collapse would be collapsed by the paper's test as well. Normal similarity is
   the mean dot product of the point normals with the node's cone axis, also exact from sums.
8. ``linearise`` - depth-first order with escape (skip) indices, packed into the 40-byte records
   of :mod:`app.pbgi.layout` (see there for the traversal convention and the GLSL API).

Node centres are stored relative to ``Hierarchy.origin`` (float64, the bounding-box centre) so
float32 keeps millimetres for a scan far from the origin; world = origin + center.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from app.errors import ScanlightError
from app.pbgi import layout

MORTON_BITS = 21
MAX_CELL = (1 << MORTON_BITS) - 1
STAGES = ("spacing", "morton", "sort", "leaves", "karras", "propagate", "prune", "linearise")
_U64 = np.uint64
_GROW = 1.0 + 2.0 ** -22
# nodes per vectorised step: small enough that its temporaries stay in cache
_LEAF_CHUNK = 65536
_MERGE_CHUNK = 16384

# Per-node values during the build, structure-of-arrays: one row per scalar, one column per node
# (numpy gathers and arithmetic on contiguous rows are several times faster than on (M, 3)).
CEN, RAD, AXS, ANG, CNT, SUMC, SUMQ, SUMN = (slice(0, 3), 3, slice(4, 7), 7, 8, slice(9, 12),
                                             12, slice(13, 16))
NROWS = 16
OUT_ROWS = 12  # rows a record needs: centre, radius, axis, angle, count, colour sum


# -- small vectorised helpers (vectors are (3, M) arrays) -----------------------------------------

def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _norm(a: np.ndarray) -> np.ndarray:
    return np.sqrt(_dot(a, a))


def _spread_bits(v: np.ndarray) -> np.ndarray:
    """21-bit integers -> every third bit of a uint64 (the Morton interleave)."""
    v = v.astype(_U64) & _U64(0x1FFFFF)
    v = (v | (v << _U64(32))) & _U64(0x1F00000000FFFF)
    v = (v | (v << _U64(16))) & _U64(0x1F0000FF0000FF)
    v = (v | (v << _U64(8))) & _U64(0x100F00F00F00F00F)
    v = (v | (v << _U64(4))) & _U64(0x10C30C30C30C30C3)
    v = (v | (v << _U64(2))) & _U64(0x1249249249249249)
    return v


def morton_codes(cx: np.ndarray, cy: np.ndarray, cz: np.ndarray) -> np.ndarray:
    """Non-negative cell coordinates (< 2**21) -> uint64 Morton codes (x in the highest bit)."""
    return (_spread_bits(cx) << _U64(2)) | (_spread_bits(cy) << _U64(1)) | _spread_bits(cz)


def msb64(x: np.ndarray) -> np.ndarray:
    """Index of the highest set bit of non-zero uint64 values (63 - count-leading-zeros).

    frexp of each exact 32-bit half gives its bit length: no float64 rounding of 64-bit values.
    """
    hi = (x >> _U64(32)).astype(np.float64)
    lo = (x & _U64(0xFFFFFFFF)).astype(np.float64)
    return np.where(hi > 0, np.frexp(hi)[1] + 31, np.frexp(lo)[1] - 1).astype(np.int64)


def _any_perpendicular(a: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each unit column of ``a`` (3, k): a x X, or a x Y."""
    use_x = np.abs(a[0]) < 0.9
    zero = np.zeros(a.shape[1])
    p = np.where(use_x, np.stack([zero, a[2], -a[1]]), np.stack([-a[2], zero, a[0]]))
    return p / _norm(p)


def round_spheres(c: np.ndarray, r: np.ndarray, exact: np.ndarray | None = None):
    """Round spheres to float32 storage so that the stored sphere contains the float64 one.

    The centre is rounded and the radius grows by the centre's rounding error; the radius is then
    scaled by 1 + 2^-22 before rounding to nearest, so the float32 radius exceeds the float64 one
    by at least ~2^-23 relative (about one ulp: room for the float64 error of the merge).
    ``exact`` marks spheres that are stored children copied unchanged: they stay bit-identical.
    Returns float64 arrays holding float32 values.
    """
    cb = c.astype(np.float32).astype(np.float64)
    rr = r + _norm(cb - c)
    r32 = (rr * _GROW).astype(np.float32).astype(np.float64)
    if exact is not None:
        r32 = np.where(exact, r, r32)
    return cb, r32


def merge_spheres(c1, r1, c2, r2):
    """Smallest sphere enclosing two spheres ((3, k) centres), rounded to float32 storage."""
    v = c2 - c1
    d = _norm(v)
    in1 = d + r2 <= r1
    in2 = (d + r1 <= r2) & ~in1
    r = 0.5 * (d + r1 + r2)
    t = (r - r1) / np.where(d > 0, d, 1.0)  # d == 0 always falls in in1 or in2
    c = c1 + t * v
    exact = in1 | in2
    if exact.any():
        c = np.where(in1, c1, np.where(in2, c2, c))
        r = np.where(in1, r1, np.where(in2, r2, r))
    return round_spheres(c, r, exact)


def merge_cones(a1, t1, a2, t2):
    """Exact minimum cone containing two cones: unit axes (3, k), half-angles in [0, pi].

    Angles come from arccos (error ~1e-8 rad per level); layout.pack_cone adds a 1e-5 rad margin
    that covers their accumulation over the <= 64 levels.
    """
    cg = np.clip(_dot(a1, a2), -1.0, 1.0)
    g = np.arccos(cg)
    in1 = g + t2 <= t1
    in2 = (g + t1 <= t2) & ~in1
    u = a2 - a1 * cg
    un = _norm(u)
    near = un < 1e-6  # (nearly) parallel axes: the rotation plane is undefined
    same = opp = None
    if near.any():
        opp = near & (cg < 0)   # rotate in any plane, widen by the angle between a2 and -a1
        same = near & ~opp      # keep a1, widen by the angle between a1 and a2
        if opp.any():
            u[:, opp] = _any_perpendicular(a1[:, opp])
            un[opp] = 1.0
            g_opp = np.where(opp, 2.0 * np.pi - g, g)
        else:
            g_opp = g
        un[same] = 1.0
    else:
        g_opp = g
    t = 0.5 * (t1 + t2 + g_opp)
    phi = t - t1
    if same is not None:
        t = np.where(same, np.maximum(t1, t2 + g), t)
        phi = np.where(same, 0.0, phi)
    u /= un
    a = a1 * np.cos(phi) + u * np.sin(phi)
    a = np.where(in1, a1, np.where(in2, a2, a))
    t = np.where(in1, t1, np.where(in2, t2, np.minimum(t, np.pi)))
    return a, t


def median_spacing(p: np.ndarray, exact_below: int = 65536, queries: int = 4096,
                   seed: int = 0) -> float:
    """About the median nearest-neighbour distance of (N, 3) points (0.0 if all coincide).

    Exact (KD-tree over all points, a random sample of queries) up to ``exact_below`` points.
    Above, the median spacings d(m), d(m/4) of two nested random subsets give the local
    dimension D = log 4 / log(d(m/4) / d(m)) (2 for a surface scan), and d(N) = d(m) (m/N)^(1/D):
    a KD-tree over 3M points alone would cost a third of the build budget.
    """
    n = len(p)
    if n < 2:
        return 0.0
    rng = np.random.default_rng(seed)

    def med(sub: np.ndarray) -> float:
        k = min(len(sub), 8)
        tree = cKDTree(sub, balanced_tree=False, compact_nodes=False)
        q = sub[rng.choice(len(sub), min(queries, len(sub)), replace=False)]
        dist = tree.query(q, k=k)[0][:, 1:]
        first = np.where(dist > 0, dist, np.inf).min(axis=1)  # nearest *distinct* point
        first = first[np.isfinite(first)]
        return float(np.median(first)) if len(first) else 0.0

    if n <= exact_below:
        return med(p)
    idx = np.sort(rng.choice(n, exact_below, replace=False))
    d_m = med(p[idx])
    d_q = med(p[idx[rng.choice(exact_below, exact_below // 4, replace=False)]])
    if d_m <= 0:
        return 0.0
    dim = np.log(4.0) / np.log(d_q / d_m) if d_q > d_m else 3.0
    return d_m * (exact_below / n) ** (1.0 / float(np.clip(dim, 1.0, 3.0)))


# -- result ------------------------------------------------------------------------------------

@dataclass
class Hierarchy:
    """A built BSH: depth-first records (``layout.NODE_DTYPE``) plus what the CPU side needs.

    ``point_node[k]`` is the index of the leaf or cluster leaf holding input point k (the pruned
    tree's leaves partition the points). ``stats``: points, cells (leaves before pruning), nodes
    (before pruning, Table 1's N.Nodes), clusters (nodes after pruning, Table 1's N.Cluster),
    leaves and cluster_leaves (after pruning), depth, cell_size, zero_normals, bytes_per_node,
    seconds_<stage>, seconds_total.
    """

    nodes: np.ndarray
    origin: np.ndarray
    cell_size: float
    point_node: np.ndarray
    params: dict = field(default_factory=dict)
    stats: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.nodes)

    @property
    def nbytes(self) -> int:
        return self.nodes.nbytes

    def decoded(self) -> dict:
        """The fields as GLSL's load_node sees them (see layout.decode)."""
        return layout.decode(self.nodes)

    def parents(self) -> np.ndarray:
        """Parent index per node (-1 for the root), from the traversal links alone."""
        skip = self.nodes["skip"].astype(np.int64)
        m = len(skip)
        par = np.full(m, -1, dtype=np.int64)
        inner = np.flatnonzero(skip != np.arange(1, m + 1))
        par[inner + 1] = inner
        par[skip[inner + 1]] = inner
        return par

    def world_centers(self) -> np.ndarray:
        return self.origin + self.nodes["center"].astype(np.float64)


class _Timer:
    def __init__(self):
        self.t0 = self.t = time.perf_counter()
        self.seconds = {f"seconds_{s}": 0.0 for s in STAGES}

    def lap(self, stage: str) -> None:
        now = time.perf_counter()
        self.seconds[f"seconds_{stage}"] += now - self.t
        self.t = now

    def total(self) -> float:
        return time.perf_counter() - self.t0


def _validate(positions, normals, colors):
    p = np.asarray(positions, dtype=np.float64)
    n = np.asarray(normals)
    c = np.asarray(colors)
    if p.ndim != 2 or p.shape[1] != 3 or n.shape != p.shape or c.shape != p.shape:
        raise ScanlightError(None, f"BSH build needs (N, 3) positions, normals and colours; got "
                                   f"{p.shape}, {n.shape}, {c.shape}")
    if len(p) == 0:
        raise ScanlightError(None, "BSH build: the point cloud is empty")
    if len(p) > int(layout.COUNT_MASK):
        raise ScanlightError(None, f"BSH build: {len(p)} points exceed the record's 31-bit count")
    for name, a in (("positions", p), ("normals", n), ("colours", c)):
        if not np.isfinite(a).all():
            raise ScanlightError(None, f"BSH build: non-finite values in the point {name}")
    return p, n, c


def _leaves(V, rel, nrm, col, order, starts, npts, leaf_floor):
    """Fill V (NROWS, L) with per-cell leaf values from the Morton-sorted points.

    Works in chunks of whole cells so the per-point temporaries stay in cache. Returns the
    number of zero-length normals (their leaves get an all-directions cone)."""
    n_leaves = len(starts)
    nrm_t, col_t = np.ascontiguousarray(nrm.T), np.ascontiguousarray(col.T)  # rows gather fast
    n_unknown = 0
    for l0 in range(0, n_leaves, _LEAF_CHUNK):
        l1 = min(l0 + _LEAF_CHUNK, n_leaves)
        p0, p1 = starts[l0], (starts[l1] if l1 < n_leaves else npts)
        o = order[p0:p1]
        n_unknown += _leaf_chunk(V[:, l0:l1], [r[o] for r in rel], np.take(nrm_t, o, axis=1),
                                 np.take(col_t, o, axis=1), starts[l0:l1] - p0, leaf_floor)
    return n_unknown


def _leaf_chunk(V, ps, nrm, col, st, leaf_floor):
    """Leaf values of consecutive cells; ps, nrm, col: (3, n) sorted rows, st: cell starts."""
    cnt = np.diff(np.append(st, len(ps[0])))
    fc = cnt.astype(np.float64)
    lid = np.repeat(np.arange(len(st)), cnt)

    def sums(x):  # per-cell sums (bincount: one pass, no sorted segments needed)
        return np.bincount(lid, weights=x, minlength=len(st))

    V[CNT] = fc
    mean = np.stack([sums(x) for x in ps]) / fc
    d2 = sum((x - np.repeat(m, cnt)) ** 2 for x, m in zip(ps, mean))
    r = np.maximum(np.sqrt(np.maximum.reduceat(d2, st)), leaf_floor)
    V[CEN], V[RAD] = round_spheres(mean, r)

    ns = nrm.astype(np.float64)
    nlen = _norm(ns)
    unknown = nlen < 1e-12
    ns /= np.where(unknown, 1.0, nlen)
    sn = np.stack([sums(x) for x in ns])
    V[SUMN] = sn
    sl = _norm(sn)
    weak = sl <= 1e-9 * fc  # normals cancel out: use the cell's first normal
    axis = sn / np.where(weak, 1.0, sl)
    if weak.any():
        axis[:, weak] = ns[:, st[weak]]
        lost = _norm(axis) < 0.5
        axis[:, lost] = np.array([[0.0], [0.0], [1.0]])
    mind = np.minimum.reduceat(_dot(ns, np.repeat(axis, cnt, axis=1)), st)
    V[AXS] = axis
    ang = np.arccos(np.clip(mind, -1.0, 1.0))
    n_unknown = int(unknown.sum())
    if n_unknown:
        ang[np.maximum.reduceat(unknown.astype(np.int8), st) > 0] = np.pi
    V[ANG] = ang

    cs = col.astype(np.float64)
    V[SUMC] = np.stack([sums(x) for x in cs])
    V[SUMQ] = sums(_dot(cs, cs))
    return n_unknown


def _karras(keys: np.ndarray):
    """Children of the L-1 internal nodes of Karras's radix tree over sorted unique keys.

    Combined numbering: internal node i -> i, leaf j -> L-1+j (so the root is 0 either way).
    """
    n_int = len(keys) - 1
    x = keys[:-1] ^ keys[1:]             # x[i] = k_i ^ k_{i+1} (never 0: keys are unique)
    mx = msb64(x)                        # lower msb = longer common prefix (delta)
    m_prev = np.empty(n_int, dtype=np.int64)
    m_prev[0] = 64                       # delta(0, -1) = -1
    m_prev[1:] = mx[:-1]
    d_right = mx < m_prev                # d = sign(delta(i, i+1) - delta(i, i-1))
    m_min = np.where(d_right, m_prev, mx)  # highest bit where k_i and k_{i-d} differ
    # range: every key sharing the bits above m_min with k_i; its far end by binary search
    shift = np.minimum(m_min, 63).astype(_U64)
    prefix = keys[:-1] >> shift
    j = np.searchsorted(keys, np.where(d_right, (prefix + _U64(1)) << shift, prefix << shift))
    other = np.where(d_right, j - 1, j)
    other[0] = n_int                     # the root covers every key
    i = np.arange(n_int, dtype=np.int64)
    first = np.minimum(i, other)
    last = np.maximum(i, other)
    # split: the last key whose first differing bit (within the range) is 0
    b = msb64(keys[first] ^ keys[last]).astype(_U64)
    gamma = np.searchsorted(keys, ((keys[first] >> b) + _U64(1)) << b) - 1
    left = np.where(first == gamma, n_int + gamma, gamma)
    right = np.where(last == gamma + 1, n_int + gamma + 1, gamma + 1)
    return left, right


def _levels(left, right, n_int):
    """Karras ids of the internal nodes per depth. Level d+1 lists the internal children of
    level d's nodes in (left, right) order, so every level stays in Morton order and the
    children gathered at each level are read with increasing, cache-friendly indices."""
    levels = [np.zeros(1, dtype=np.int64)]
    while True:
        ch = np.stack([left[levels[-1]], right[levels[-1]]], axis=1).ravel()
        ch = ch[ch < n_int]
        if not ch.size:
            return levels
        if len(levels) > 200:  # radix tree over 63-bit codes: <= 64 levels
            raise ScanlightError(None, "BSH build: radix tree deeper than 200 (internal error)")
        levels.append(ch)


def _merge_children(A, B, tc, tn, do_prune, M):
    """Write parent values of children columns A, B into M; return the prune test per parent."""
    M[CEN], M[RAD] = merge_spheres(A[CEN], A[RAD], B[CEN], B[RAD])
    M[AXS], M[ANG] = merge_cones(A[AXS], A[ANG], B[AXS], B[ANG])
    M[CNT:] = A[CNT:] + B[CNT:]
    if not do_prune:
        return np.zeros(M.shape[1], dtype=bool)
    fc = M[CNT]
    mean = M[SUMC] / fc
    var = M[SUMQ] / fc - _dot(mean, mean)        # E|c|^2 - |E c|^2
    sim = _dot(M[SUMN], M[AXS]) / fc             # mean dot(point normal, cone axis)
    return (var < tc * tc) & (sim > tn)


def build_bsh(positions, normals, colors, cell_size: float | None = None, tc: float = 0.01,
              tn: float = 0.98, min_leaf_radius: float | None = None,
              prune: bool = True) -> Hierarchy:
    """Build the BSH of a point cloud (see the module docstring for the stages).

    positions (N, 3) float64 metres; normals (N, 3) unit (zero-length ones are allowed and give
    their leaf an "all directions" cone); colors (N, 3) linear radiance. ``cell_size`` defaults
    to the median point spacing. ``min_leaf_radius`` (default half the cell size) keeps each
    leaf the size of the surface patch it stands for instead of a zero-radius single point.
    ``prune=False`` keeps every node (tc, tn unused).
    """
    timer = _Timer()
    p, nrm, col = _validate(positions, normals, colors)
    npts = len(p)
    lo = np.array([p[:, k].min() for k in range(3)])
    hi = np.array([p[:, k].max() for k in range(3)])
    origin = 0.5 * (lo + hi)
    rel = [p[:, k] - origin[k] for k in range(3)]  # box-relative float64 rows (new arrays)
    extent = float((hi - lo).max())
    if cell_size is None:
        h = median_spacing(p)  # distances do not depend on the offset
    else:
        h = float(cell_size)
        if not np.isfinite(h) or h <= 0:
            raise ScanlightError(None, f"BSH build: cell size must be > 0, got {cell_size}")
    if not np.isfinite(h) or h <= 0:  # all points coincide
        h = extent / 1024.0 if extent > 0 else 1.0
    h = max(h, extent / (MAX_CELL - 1))  # 21 bits per axis
    leaf_floor = 0.5 * h if min_leaf_radius is None else float(min_leaf_radius)
    timer.lap("spacing")

    cells = [np.clip(np.floor((r - (lo[k] - origin[k])) / h), 0, MAX_CELL)
             for k, r in enumerate(rel)]
    codes = morton_codes(*cells)
    del cells
    timer.lap("morton")

    order = np.argsort(codes)
    sorted_codes = codes[order]
    new = np.empty(npts, dtype=bool)
    new[0] = True
    np.not_equal(sorted_codes[1:], sorted_codes[:-1], out=new[1:])
    starts = np.flatnonzero(new)
    keys = sorted_codes[starts]
    n_leaves = len(starts)
    point_leaf = np.empty(npts, dtype=np.int64)
    point_leaf[order] = np.cumsum(new) - 1
    del codes, sorted_codes, new
    timer.lap("sort")

    # Global node values, one column per node: internal nodes numbered breadth-first (each level
    # a contiguous slice), leaves after them in Morton order (column n_int + leaf).
    n_int = n_leaves - 1
    total_before = 2 * n_leaves - 1
    G = np.empty((NROWS, total_before))
    n_unknown = _leaves(G[:, n_int:], rel, nrm, col, order, starts, npts, leaf_floor)
    del rel, order
    timer.lap("leaves")

    if n_int > 0:
        left, right = _karras(keys)
        levels = _levels(left, right, n_int)
        bfs = np.concatenate(levels)
        if len(bfs) != n_int:
            raise ScanlightError(None, "BSH build: inconsistent radix tree (internal error)")
        slot = np.empty(n_int, dtype=np.int64)
        slot[bfs] = np.arange(n_int)
        remap = lambda c: np.where(c < n_int, slot[np.minimum(c, n_int - 1)], c)  # noqa: E731
        lc, rc = remap(left[bfs]), remap(right[bfs])  # children columns, by parent column
        offsets = np.cumsum([0] + [len(lv) for lv in levels])
        del left, right, slot, bfs
    else:
        levels, offsets = [], [0]
        lc = rc = np.zeros(0, dtype=np.int64)
    timer.lap("karras")

    # bottom-up, deepest level first; chunks keep the merge temporaries in cache
    do_prune = bool(prune) and tc is not None and tn is not None
    passes = np.zeros(total_before, dtype=bool)
    size = np.ones(total_before, dtype=np.int64)  # node count of the pruned subtree
    for d in range(len(levels) - 1, -1, -1):
        for s0 in range(offsets[d], offsets[d + 1], _MERGE_CHUNK):
            cols = slice(s0, min(s0 + _MERGE_CHUNK, offsets[d + 1]))
            a, b = lc[cols], rc[cols]
            ok = _merge_children(np.take(G, a, axis=1), np.take(G, b, axis=1), tc, tn,
                                 do_prune, G[:, cols])
            passes[cols] = ok
            size[cols] = np.where(ok, 1, 1 + size[a] + size[b])
    timer.lap("propagate")

    # top-down: kept nodes (not below a cluster leaf), depth-first index, nearest kept ancestor
    kept = np.zeros(total_before, dtype=bool)
    kept[0] = True
    pre = np.zeros(total_before, dtype=np.int64)
    owner = np.arange(total_before, dtype=np.int64)  # nearest kept node at or above each node
    for d in range(len(levels)):
        cols = slice(offsets[d], offsets[d + 1])
        a, b = lc[cols], rc[cols]
        open_ = kept[cols] & ~passes[cols]
        kept[a] = open_
        kept[b] = open_
        pre[a] = pre[cols] + 1
        pre[b] = pre[cols] + 1 + size[a]
        owner[a] = np.where(open_, a, owner[cols])
        owner[b] = np.where(open_, b, owner[cols])
    sel = np.flatnonzero(kept)
    total = int(size[0])
    if len(sel) != total:
        raise ScanlightError(None, "BSH build: pruned tree size mismatch (internal error)")
    timer.lap("prune")

    rec = np.empty(total, dtype=layout.NODE_DTYPE)  # records in column order, then permuted
    for s0 in range(0, total, _LEAF_CHUNK):
        part = sel[s0:s0 + _LEAF_CHUNK]
        V = np.take(G[:OUT_ROWS], part, axis=1)
        out = rec[s0:s0 + len(part)]
        out["center"] = V[CEN].T
        out["radius"] = V[RAD]
        out["color"] = (V[SUMC] / V[CNT]).T
        out["cone"] = layout.pack_cone(V[AXS].T, V[ANG])
        out["skip"] = pre[part] + size[part]
        leaf = (part >= n_int) | passes[part]
        out["count_flags"] = V[CNT].astype(np.uint32) | np.where(leaf, layout.LEAF_BIT,
                                                                 np.uint32(0))
    del G
    inverse = np.empty(total, dtype=np.int64)
    inverse[pre[sel]] = np.arange(total)
    nodes = rec.take(inverse)  # depth-first order (a gather: sequential writes, unlike the scatter)
    is_leaf = (nodes["count_flags"] & layout.LEAF_BIT) != 0
    point_node = pre[owner[n_int + point_leaf]].astype(np.int32)
    n_cluster_leaves = int(passes[sel].sum())
    timer.lap("linearise")

    stats = {
        "points": npts, "cells": n_leaves, "nodes": 2 * n_leaves - 1, "clusters": total,
        "leaves": int(is_leaf.sum()), "cluster_leaves": n_cluster_leaves,
        "depth": len(levels) + 1, "cell_size": h, "zero_normals": n_unknown,
        "bytes_per_node": layout.NODE_BYTES, **timer.seconds, "seconds_total": timer.total(),
    }
    params = {"cell_size": cell_size, "tc": tc, "tn": tn, "min_leaf_radius": min_leaf_radius,
              "prune": bool(prune)}
    return Hierarchy(nodes=nodes, origin=origin, cell_size=h, point_node=point_node,
                     params=params, stats=stats)


def recolor(hierarchy, colors: np.ndarray) -> np.ndarray:
    """Node records with colours recomputed from new point colours on the same tree.

    Every node's colour is the mean of the points below it (app.pbgi.hierarchy); in depth-first
    order a subtree is the index range [i, skip(i)), so prefix sums of per-leaf colour sums give
    every subtree sum at once.
    """
    nodes = hierarchy.nodes.copy()
    m = len(nodes)
    leaf_sum = np.zeros((m, 3))
    np.add.at(leaf_sum, hierarchy.point_node, np.asarray(colors, dtype=np.float64))
    prefix = np.zeros((m + 1, 3))
    np.cumsum(leaf_sum, axis=0, out=prefix[1:])
    skip = nodes["skip"].astype(np.int64)
    sums = prefix[skip] - prefix[np.arange(m)]
    count = (nodes["count_flags"] & layout.COUNT_MASK).astype(np.float64)
    nodes["color"] = (sums / np.maximum(count, 1.0)[:, None]).astype(np.float32)
    return nodes


def build_bsh_from_cloud(cloud, **params) -> Hierarchy:
    """build_bsh on an app.cloud.PointCloud (same keyword parameters); errors name its source."""
    try:
        return build_bsh(cloud.positions, cloud.normals, cloud.colors, **params)
    except ScanlightError as exc:
        if cloud.source and exc.path is None:
            raise ScanlightError(cloud.source, exc.reason) from None
        raise
