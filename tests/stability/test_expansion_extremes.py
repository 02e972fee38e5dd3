"""The HDR expansion's solvers at their degenerate inputs, called directly: Poisson filling with
nothing, everything or an island to fill; the exposure search on an all-black and an all-white
photo; PatchMatch between constant images. Finite output, the exact answer where there is one,
and a one-line ScanlightError where the pipeline refuses the input."""

from __future__ import annotations

import numpy as np
import pytest

from app.errors import ScanlightError
from app.hdr.exposure import find_exposure
from app.hdr.patchmatch import patchmatch
from app.hdr.pipeline import validate_photo
from app.hdr.poisson import poisson_fill


def _grid(n=20):
    yy, xx = np.mgrid[0:n, 0:n].astype(float)
    return np.c_[xx.ravel(), yy.ravel(), np.zeros(n * n)]


def _ldr(n, seed=0):
    return np.random.default_rng(seed).uniform(0.2, 1.0, (n, 3))


def _omega(pos, case):
    n = len(pos)
    if case == "nothing":
        return np.zeros(n, bool)
    if case == "everything":
        return np.ones(n, bool)
    if case == "hole":
        return (np.abs(pos[:, 0] - 10) < 4) & (np.abs(pos[:, 1] - 10) < 4)
    raise ValueError(case)


POISSON_CASES = ("nothing", "everything", "hole", "island", "one-point", "duplicate-points")


@pytest.mark.parametrize("solver", ["direct", "cg"])
@pytest.mark.parametrize("case", POISSON_CASES)
def test_poisson_fill_degenerate(case, solver):
    """nothing: a no-op; everything and the island (a component with no boundary): no HDR
    information, the LDR colour kept and marked unresolved; a hole: solved from its boundary;
    one point (no neighbour at all) and a cloud of coincident points: finite, never NaN."""
    if case == "island":
        pos = np.r_[_grid(), _grid(5) + [500.0, 0.0, 0.0]]
        omega = np.zeros(len(pos), bool)
        omega[400:] = True
    elif case == "one-point":
        pos = np.zeros((1, 3))
        omega = np.ones(1, bool)
    elif case == "duplicate-points":
        pos = np.r_[np.zeros((30, 3)), np.ones((30, 3))]
        omega = np.zeros(60, bool)
        omega[::2] = True
    else:
        pos = _grid()
        omega = _omega(pos, case)
    ldr = _ldr(len(pos))
    values = np.full((len(pos), 3), 3.0)
    values[omega] = 0.0
    res = poisson_fill(pos, ldr, values, omega, k=8, solver=solver)
    assert np.isfinite(res.values).all(), case
    assert res.values.shape == values.shape and res.values.dtype == np.float32
    assert not (res.filled & res.unresolved).any()
    assert ((res.filled | res.unresolved) == omega).all(), case
    np.testing.assert_array_equal(res.values[~omega], values[~omega].astype(np.float32))
    if case in ("everything", "island", "one-point"):
        assert res.unresolved[omega].all(), case
        np.testing.assert_allclose(res.values[omega], ldr[omega], rtol=1e-6)
    if case == "nothing":
        assert res.components == 0 and not res.filled.any()
    if case in ("hole", "duplicate-points"):
        assert res.filled[omega].all(), case
        # a solved value is the boundary's plus LDR differences: within their range of 3
        assert np.abs(res.values[omega] - 3.0).max() <= 3 * np.ptp(ldr) + 1e-6, case


PHOTOS = {"all-black": 0.0, "all-white": 1.0, "all-white-hdr": 40.0}


@pytest.mark.parametrize("photo", list(PHOTOS))
def test_a_uniform_photo_is_refused_with_a_reason(photo):
    """The pipeline's gate (validate_photo) before the exposure search: an all-black photo holds
    no light, an all-white (or any uniform) one no dynamic range."""
    img = np.full((32, 48, 3), PHOTOS[photo], np.float32)
    with pytest.raises(ScanlightError) as err:
        validate_photo(img, {"photo": "p.exr"})
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("p.exr")
    assert ("photo is all black" in msg if photo == "all-black" else "photo is uniform" in msg)


def test_exposure_search_on_an_all_black_photo_raises():
    """Called directly (past the gate), the search has no positive pixel to scale."""
    cloud = np.random.default_rng(0).uniform(0, 1, (1000, 3))
    with pytest.raises(ValueError, match="photo has no positive pixel"):
        find_exposure(cloud, np.zeros((16, 16, 3), np.float32))


@pytest.mark.parametrize("cloud", ["spread", "all-clipped", "all-black"])
@pytest.mark.parametrize("photo", ["all-white", "all-white-hdr"])
def test_exposure_search_on_an_all_white_photo_is_finite(photo, cloud):
    """Called directly: a finite, positive alpha within the scanned stops, whatever the cloud
    (a distance of Inf is the pipeline's cue to retry with the clipped bin)."""
    colours = {"spread": np.random.default_rng(0).uniform(0, 1, (1000, 3)),
               "all-clipped": np.ones((1000, 3)), "all-black": np.zeros((1000, 3))}[cloud]
    level = PHOTOS[photo]
    res = find_exposure(colours, np.full((16, 16, 3), level, np.float32))
    base = 1.0 / level
    assert np.isfinite(res.alpha) and base * 2.0 ** -12.5 <= res.alpha <= base * 2.0 ** 12.5
    assert not np.isnan(res.distance)
    assert all(np.isfinite(a) for a, _ in res.scanned)
    if cloud == "spread":
        assert np.isfinite(res.distance)


IMAGES = {"black": 0.0, "grey": 0.5, "clipped-white": 1.0, "hdr": 50.0}


@pytest.mark.parametrize("level", list(IMAGES))
def test_patchmatch_between_constant_images(level):
    """Every patch matches every other: cost 0 everywhere, every transform inside B and inside
    the searched ranges, nothing NaN; a clipped image is flagged flat throughout."""
    v = IMAGES[level]
    a = np.full((40, 48, 3), v, np.float32)
    b = np.full((36, 30, 3), v, np.float32)
    nnf = patchmatch(a, b, patch_radius=2, iterations=2, levels=2, coarse_samples=4)
    for f in (nnf.x, nnf.y, nnf.angle, nnf.scale, nnf.cost):
        assert f.shape == (40, 48) and np.isfinite(f).all(), level
    assert (nnf.cost == 0).all(), level
    assert (nnf.x >= 0).all() and (nnf.x <= 29).all() and (nnf.y >= 0).all() and (nnf.y <= 35).all()
    assert (nnf.scale >= 0.33 - 1e-6).all() and (nnf.scale <= 3.0 + 1e-5).all()
    assert (np.abs(nnf.angle) <= np.pi + 1e-6).all()
    assert (nnf.flat == (v >= 0.99)).all(), level
