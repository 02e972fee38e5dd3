"""Exposure search (eq. 1): Wasserstein distance of 128-bin luminance histograms."""

from __future__ import annotations

import numpy as np
import pytest

from app.hdr.exposure import find_exposure


@pytest.fixture(scope="module")
def demo50k():
    from app.demo.cache import load_demo
    return load_demo(50_000)


def _hdr_samples(n, seed):
    rng = np.random.default_rng(seed)
    y = np.exp(rng.normal(-1.0, 1.2, n))                  # log-normal radiance, long bright tail
    tint = rng.uniform(0.8, 1.2, (n, 3))
    return (y[:, None] * tint).astype(np.float32)


@pytest.mark.parametrize("alpha", [0.05, 0.7, 3.0])
def test_recovers_the_exposure_of_a_clipped_copy(alpha):
    """The cloud is clamp(alpha * X) of one sample of a distribution, the photo another sample
    of the same distribution: the search must find alpha (0.05: nothing clips; 3: half clips)."""
    cloud = np.clip(alpha * _hdr_samples(60_000, 1), 0, 1)
    photo = _hdr_samples(200 * 300, 2).reshape(200, 300, 3)
    res = find_exposure(cloud, photo)
    assert res.alpha == pytest.approx(alpha, rel=0.03)
    assert 0 < res.iterations <= 50
    # the refinement improved on the best whole stop of the coarse scan
    assert res.distance <= min(d for _, d in res.scanned) + 1e-12


def test_mostly_clipped_scan_within_ten_percent():
    """With 80% of the cloud clipped only the shape of the dim fifth is left to compare (the
    clipped bin is left out, see app.hdr.exposure): a weaker signal, still within 10%."""
    cloud = np.clip(8.0 * _hdr_samples(60_000, 1), 0, 1)
    photo = _hdr_samples(200 * 300, 2).reshape(200, 300, 3)
    assert find_exposure(cloud, photo).alpha == pytest.approx(8.0, rel=0.10)


def test_including_the_clipped_bin_is_available():
    cloud = np.clip(0.7 * _hdr_samples(60_000, 1), 0, 1)
    photo = _hdr_samples(200 * 300, 2).reshape(200, 300, 3)
    res = find_exposure(cloud, photo, include_clipped=True)
    assert res.alpha == pytest.approx(0.7, rel=0.03)


def test_iteration_limit_is_respected():
    cloud = np.clip(0.7 * _hdr_samples(20_000, 1), 0, 1)
    photo = _hdr_samples(100 * 100, 2).reshape(100, 100, 3)
    assert find_exposure(cloud, photo, max_iters=3).iterations <= 3


def test_demo_scene_exposure_within_ten_percent(demo50k):
    res = find_exposure(demo50k.ldr.colors, demo50k.photo)
    assert res.alpha == pytest.approx(demo50k.alpha, rel=0.10)
