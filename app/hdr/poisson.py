"""Poisson colour editing on the point cloud (paper Section 4.2, eqs. 2-3).

For every point p of Omega (overexposed, no valid HDR value):

    |N_p| H(p) - sum_{q in N_p, Omega} H(q) = sum_{q in N_p, dOmega} H(q) + sum_{q in N_p} (L(p) - L(q))

with N_p the k-nearest-neighbour graph. The k-NN relation is not symmetric; we symmetrise it
inside Omega (q in N_p iff q in kNN(p) or p in kNN(q)), which makes the matrix a graph Laplacian
with Dirichlet rows: symmetric positive definite on every connected component of Omega that
touches a point with a value, so conjugate gradients apply. Components with no boundary (no
neighbour outside Omega) have no HDR information at all and a singular matrix: they are left out
of the solve and keep their LDR colour (``unresolved``), never NaN.

Solvers (compared by ``scanlight bench expand --poisson-stress``): "cg", Jacobi-preconditioned
conjugate gradients on all channels at once, written here with einsum reductions because scipy's
cg spends most of its time in BLAS dot products, which a multi-threaded BLAS slows down on a
shared machine with few cores; and "direct" (sparse LU, scipy.sparse.linalg.splu, one
factorisation for the three channels). On the 1M-point room (k = 16) LU was the faster at every
size tried, but a factorisation cannot be interrupted, so "auto" (the default) uses LU up to
DIRECT_MAX unknowns, where a cancel still answers promptly, and CG, which checks the cancel flag
every 16 iterations, above.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import splu
from scipy.spatial import cKDTree


DIRECT_MAX = 100_000


@dataclass
class PoissonResult:
    values: np.ndarray      # (N, C) float32: input values with Omega filled
    filled: np.ndarray      # (N,) bool: points of Omega that got a solved value
    unresolved: np.ndarray  # (N,) bool: points of Omega in components without a boundary
    components: int
    iterations: int         # CG iterations (max over channels); 0 for the direct solver


def poisson_fill(positions: np.ndarray, ldr: np.ndarray, values: np.ndarray, omega: np.ndarray,
                 k: int = 16, tree: cKDTree | None = None, solver: str = "auto",
                 rtol: float = 1e-6, max_iter: int = 5000, cancel=None) -> PoissonResult:
    """Solve eq. 2 for the points ``omega`` (bool (N,)); ``values`` (N, C) holds H outside Omega,
    ``ldr`` (N, C) the guidance colours L (the same channels as ``values``)."""
    values = np.array(values, dtype=np.float64, copy=True)
    ldr = np.asarray(ldr, dtype=np.float64)
    if values.ndim == 1:
        values = values[:, None]
        ldr = ldr[:, None]
    n = len(positions)
    om_idx = np.flatnonzero(omega)
    filled = np.zeros(n, dtype=bool)
    unresolved = np.zeros(n, dtype=bool)
    if len(om_idx) == 0:
        return PoissonResult(values.astype(np.float32), filled, unresolved, 0, 0)
    kk = min(k, n - 1)
    if kk < 1:
        unresolved[om_idx] = True
        values[om_idx] = ldr[om_idx]
        return PoissonResult(values.astype(np.float32), filled, unresolved, len(om_idx), 0)
    if tree is None:
        tree = cKDTree(positions)
    _, nb = tree.query(positions[om_idx], kk + 1, workers=-1)
    nb = nb.reshape(len(om_idx), kk + 1)
    rows = np.repeat(np.arange(len(om_idx)), kk + 1)
    cols = nb.ravel()
    keep = (cols != om_idx[rows]) & (cols < n)  # drop self (and missing neighbours)
    rows, cols = rows[keep], cols[keep]
    local = np.full(n, -1, dtype=np.int64)
    local[om_idx] = np.arange(len(om_idx))
    lc = local[cols]
    inner = lc >= 0
    m = len(om_idx)
    # Omega-Omega edges, symmetrised and deduplicated
    w = sp.coo_matrix((np.ones(inner.sum()), (rows[inner], lc[inner])), shape=(m, m)).tocsr()
    w = ((w + w.T) > 0).astype(np.float64)
    b_rows, b_cols = rows[~inner], cols[~inner]  # boundary edges p -> q (q has a value)
    n_bound = np.bincount(b_rows, minlength=m)
    deg = np.asarray(w.sum(axis=1)).ravel() + n_bound
    # guidance: sum_q (L(p) - L(q)) over all of N_p
    lp = ldr[om_idx]
    guid = deg[:, None] * lp - w @ lp
    guid -= np.stack([np.bincount(b_rows, ldr[b_cols, c], minlength=m)
                      for c in range(ldr.shape[1])], axis=1)
    rhs = guid + np.stack([np.bincount(b_rows, values[b_cols, c], minlength=m)
                           for c in range(values.shape[1])], axis=1)
    n_comp, comp = connected_components(w, directed=False)
    has_boundary = np.bincount(comp, n_bound, minlength=n_comp) > 0
    solvable = has_boundary[comp]
    unresolved[om_idx[~solvable]] = True
    values[om_idx[~solvable]] = ldr[om_idx[~solvable]]
    iters = 0
    if solvable.any():
        s_idx = np.flatnonzero(solvable)
        a = (sp.diags(deg[s_idx]) - w[s_idx][:, s_idx]).tocsc()
        b = rhs[s_idx]
        if solver == "auto":
            solver = "direct" if len(s_idx) <= DIRECT_MAX else "cg"
        if solver == "direct":
            lu = splu(a)
            x = lu.solve(b)
        elif solver == "cg":
            x, iters, ok = _pcg(a.tocsr(), b, lp[s_idx].copy(), 1.0 / deg[s_idx], rtol,
                                max_iter, cancel)
            if not ok:  # not converged: the exact solve
                x = splu(a).solve(b)
        else:
            raise ValueError(f"unknown Poisson solver {solver!r}")
        values[om_idx[s_idx]] = x
        filled[om_idx[s_idx]] = True
    return PoissonResult(values.astype(np.float32), filled, unresolved, int(n_comp), iters)


def _pcg(a, b: np.ndarray, x0: np.ndarray, inv_diag: np.ndarray, rtol: float, max_iter: int,
         cancel=None) -> tuple[np.ndarray, int, bool]:
    """Jacobi-preconditioned CG for SPD ``a`` and the columns of ``b`` together.

    Returns (x, iterations, converged): each column stops improving once its residual is below
    ``rtol`` times its right-hand side's norm."""
    def dots(u, v):
        return np.einsum("ij,ij->j", u, v)

    x = x0.astype(np.float64, copy=True)
    r = b - a @ x
    z = r * inv_diag[:, None]
    p = z.copy()
    rz = dots(r, z)
    target = rtol * np.maximum(np.sqrt(dots(b, b)), 1e-300)
    for it in range(max_iter):
        if np.all(np.sqrt(dots(r, r)) <= target):
            return x, it, True
        if cancel is not None and it % 16 == 0:
            cancel()
        ap = a @ p
        pap = dots(p, ap)
        step = np.where(pap > 0, rz / np.where(pap > 0, pap, 1.0), 0.0)
        x += step * p
        r -= step * ap
        z = r * inv_diag[:, None]
        rz_new = dots(r, z)
        beta = np.where(rz > 0, rz_new / np.where(rz > 0, rz, 1.0), 0.0)
        p = z + beta * p
        rz = rz_new
    return x, max_iter, bool(np.all(np.sqrt(dots(r, r)) <= target))
