"""Poisson colour editing on the k-NN graph (paper eqs. 2-3)."""

from __future__ import annotations

import numpy as np
import pytest

from app.hdr.poisson import poisson_fill


def _grid(n=40):
    """A flat grid: with k = 8 every interior point's neighbourhood is centrally symmetric, so
    the graph Laplacian of a linear function is exactly zero there."""
    yy, xx = np.mgrid[0:n, 0:n].astype(float)
    return np.c_[xx.ravel(), yy.ravel(), np.zeros(n * n)], xx.ravel(), yy.ravel()


@pytest.mark.parametrize("solver", ["cg", "direct"])
def test_guidance_plus_linear_boundary_is_reproduced(solver):
    """H = L + g with g linear on the boundary and L any guidance field: eq. 2 is solved by
    H = L + g inside (L's differences carried over, g harmonic)."""
    pos, x, y = _grid()
    rng = np.random.default_rng(0)
    L = rng.random((len(pos), 3))                     # arbitrary guidance colours
    g = np.stack([0.3 * x + 0.1 * y + 2, -0.2 * x + 0.5 * y, 0.05 * x], axis=1)
    truth = L + g
    omega = (x > 5) & (x < 34) & (y > 8) & (y < 30)
    values = np.where(omega[:, None], 0.0, truth)     # nothing known inside
    res = poisson_fill(pos, L, values, omega, k=8, solver=solver)
    assert res.filled.sum() == omega.sum() and not res.unresolved.any()
    np.testing.assert_allclose(res.values[omega], truth[omega], atol=2e-4)
    np.testing.assert_array_equal(res.values[~omega], values[~omega].astype(np.float32))


def test_constant_guidance_gives_harmonic_interpolation_between_boundaries():
    """With flat LDR (a clipped region: L = 1 everywhere) the fill is the harmonic interpolation
    of the boundary: on a strip between two walls of value 0 (x <= 2) and 10 (x >= 37), a
    linear ramp (exact away from the strip's open top and bottom edges)."""
    pos, x, y = _grid()
    L = np.ones((len(pos), 1))
    values = np.where(x[:, None] < 20, 0.0, 10.0)
    omega = (x >= 3) & (x <= 36)
    res = poisson_fill(pos, L, values, omega, k=8)
    ramp = 10.0 * (x - 2) / 35
    inner = omega & (y > 8) & (y < 31)
    np.testing.assert_allclose(res.values[inner, 0], ramp[inner], atol=0.01)


def test_component_without_boundary_falls_back_to_ldr_without_nan():
    """Omega points whose whole neighbourhood is Omega (a separate island) have no HDR data:
    they keep their LDR colour; the rest is solved; nothing is NaN, nothing raises."""
    pos, x, y = _grid(20)
    island = np.c_[np.random.default_rng(1).random((30, 2)) * 0.5 + 100, np.zeros(30)]
    pos = np.r_[pos, island]
    n = len(pos)
    L = np.full((n, 3), 0.9)
    L[-30:] = [0.95, 0.9, 0.8]
    values = np.full((n, 3), 2.0)
    omega = np.zeros(n, bool)
    omega[-30:] = True                                # the island: all unknown, far away
    omega[:400][(x > 5) & (x < 12) & (y > 5) & (y < 12)] = True  # a hole with a boundary
    res = poisson_fill(pos, L, values, omega, k=16)
    assert np.all(np.isfinite(res.values))
    assert res.unresolved[-30:].all() and not res.unresolved[:400].any()
    np.testing.assert_allclose(res.values[-30:], L[-30:], atol=1e-6)
    assert res.filled[:400].sum() == omega[:400].sum()
    np.testing.assert_allclose(res.values[:400][omega[:400]], 2.0, atol=1e-3)  # flat L: boundary value


def test_empty_omega_is_a_no_op():
    pos, _, _ = _grid(10)
    vals = np.random.default_rng(2).random((len(pos), 3))
    res = poisson_fill(pos, vals, vals, np.zeros(len(pos), bool))
    np.testing.assert_array_equal(res.values, vals.astype(np.float32))
    assert res.components == 0 and not res.filled.any()


def test_all_points_unknown_no_singular_matrix():
    pos, _, _ = _grid(10)
    L = np.full((len(pos), 1), 0.5)
    res = poisson_fill(pos, L, np.zeros((len(pos), 1)), np.ones(len(pos), bool))
    assert res.unresolved.all() and np.all(res.values == np.float32(0.5))


@pytest.mark.parametrize("solver", ["cg", "direct"])
def test_fill_solves_the_documented_system_on_an_irregular_cloud(solver):
    """On a random 3-D cloud (no grid symmetry to hide a one-sided neighbourhood) the fill is
    the solution of the module's equation, built here densely from its words: q is p's
    neighbour inside Omega when either is among the other's k nearest, a point outside Omega
    when it is among p's k nearest; |N_p| H(p) - sum over Omega neighbours of H(q) = sum over
    outside neighbours of H(q) + sum over all neighbours of (L(p) - L(q)). CG converges."""
    rng = np.random.default_rng(3)
    n, k = 400, 6
    pos = rng.random((n, 3))
    L = rng.random((n, 2))
    values = rng.random((n, 2)) * 4.0
    omega = rng.random(n) < 0.4
    res = poisson_fill(pos, L, values, omega, k=k, solver=solver, rtol=1e-12)
    assert not res.unresolved.any() and res.filled.sum() == omega.sum()
    if solver == "cg":
        assert 0 < res.iterations < 5000

    from scipy.spatial import cKDTree
    knn = cKDTree(pos).query(pos, k + 1)[1][:, 1:]
    near = np.zeros((n, n), dtype=bool)
    near[np.repeat(np.arange(n), k), knn.ravel()] = True
    inside = omega[:, None] & omega[None, :]
    nb = np.where(inside, near | near.T, near & ~omega[None, :])
    idx = np.flatnonzero(omega)
    a = np.zeros((len(idx), len(idx)))
    b = np.zeros((len(idx), 2))
    for row, p in enumerate(idx):
        qs = np.flatnonzero(nb[p])
        a[row, row] = len(qs)
        for q in qs:
            b[row] += L[p] - L[q]
            if omega[q]:
                a[row, np.searchsorted(idx, q)] -= 1.0
            else:
                b[row] += values[q]
    want = np.linalg.solve(a, b)
    np.testing.assert_allclose(res.values[idx], want, rtol=1e-5, atol=1e-5)
