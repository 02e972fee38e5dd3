"""The inverse tone mapping baselines (Landis 2002, Banterle 2006)."""

from __future__ import annotations

import numpy as np
import pytest

from app.hdr import itmo


def test_landis_is_identity_below_threshold_continuous_and_reaches_lmax():
    ld = np.linspace(0, 1, 1001)
    lw = itmo.landis(ld, l_max=50.0, threshold=0.9, exponent=2.0)
    np.testing.assert_array_equal(lw[ld < 0.9], ld[ld < 0.9])
    assert lw[-1] == pytest.approx(50.0)
    assert np.all(np.diff(lw) >= 0)                       # monotone
    i = np.searchsorted(ld, 0.9)
    assert abs(lw[i] - lw[i - 1]) < 0.01                  # no jump at the threshold


def test_landis_interior_values_follow_the_published_curve():
    """Inside the expanded range, Lw = (1 - k) Ld + k Lmax Ld with k = ((Ld - R) / (1 - R))^a
    (Landis 2002, as Banterle et al. give it): at Ld 0.95, R 0.9, Lmax 50, k = 0.5^a, so
    a = 2 gives 0.25 and Lw = 12.5875, a = 3 gives 0.125 and Lw = 6.76875."""
    assert float(itmo.landis(np.array([0.95]), 50.0, 0.9, 2.0)[0]) == pytest.approx(12.5875,
                                                                                   rel=1e-12)
    assert float(itmo.landis(np.array([0.95]), 50.0, 0.9, 3.0)[0]) == pytest.approx(6.76875,
                                                                                   rel=1e-12)


def test_inverse_reinhard_inverts_reinhard():
    """Reinhard: Ld = Lw (1 + Lw / Lwhite^2) / (1 + Lw); with Lwhite = Lmax the inverse maps 1 to
    Lmax and small values to themselves."""
    l_max = 40.0
    lw = np.array([0.01, 0.3, 2.0, 10.0, 40.0])
    ld = lw * (1 + lw / l_max ** 2) / (1 + lw)
    np.testing.assert_allclose(itmo.inverse_reinhard(ld, l_max), lw, rtol=1e-6)


def test_banterle_blends_with_the_expand_map():
    ld = np.zeros((40, 40))
    ld[15:25, 15:25] = 1.0                                # a clipped square
    ld[2, 2] = 0.5
    e = itmo.expand_map_image(ld, threshold=0.9, sigma=2.0)
    assert e.max() == pytest.approx(1.0) and e[2, 2] < 1e-3
    out = itmo.banterle(ld, 30.0, e)
    assert out[20, 20] > 25.0                             # centre of the light: expanded
    assert out[2, 2] == pytest.approx(0.5, abs=1e-3)       # far from it: unchanged


def test_expand_map_on_points_spreads_over_the_graph():
    ld = np.array([1.0, 0.2, 0.2, 0.2, 0.2])
    nb = np.array([[1, 1], [0, 2], [1, 3], [2, 4], [3, 3]])  # a chain 0-1-2-3-4
    e = itmo.expand_map_points(ld, nb, threshold=0.9, iterations=3)
    assert e[0] == pytest.approx(1.0) and e[0] > e[1] > e[2] > e[3] > e[4] == 0
    dark = itmo.expand_map_points(ld, np.array([[1, -1], [0, 2], [1, 3], [2, 4], [3, -1]]), 0.9, 3)
    assert np.all(dark <= 1.0) and dark[4] == 0           # -1: a dark neighbour outside the set


def test_rescale_luminance_keeps_chromaticity():
    rgb = np.array([[0.9, 0.6, 0.3], [0.0, 0.0, 0.0]], np.float32)
    out = itmo.rescale_luminance(rgb, np.array([5.0, 2.0]))
    from app.color import luminance
    np.testing.assert_allclose(luminance(out), [5.0, 2.0], rtol=1e-5)
    np.testing.assert_allclose(out[0] / out[0, 0], rgb[0] / rgb[0, 0], rtol=1e-5)
    np.testing.assert_allclose(out[1], 2.0)               # black becomes grey of that luminance
