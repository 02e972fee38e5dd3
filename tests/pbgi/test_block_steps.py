"""The block-step metric (tests/support/block_steps.py) on synthetic images whose
answer is known: Hybrid's far-field sharing is tested with it (tests/pbgi/test_pbgi_farfield.py)."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support.block_steps import block_steps


def _disc(n: int) -> np.ndarray:
    y, x = np.mgrid[0:n, 0:n]
    return (x - n / 2 + 0.5) ** 2 + (y - n / 2 + 0.5) ** 2 < (0.45 * n) ** 2


def test_a_blocky_image_has_steps_only_across_block_boundaries():
    """Constant per 8 x 8 block, a random level per block: every difference is across a
    boundary (inside = 0 exactly), and `across` is the mean |step| over the mask's mean."""
    rng = np.random.default_rng(1)
    n = 64
    levels = 1.0 + 0.1 * rng.standard_normal((n // 8, n // 8))
    img = np.repeat(np.repeat(levels, 8, 0), 8, 1)
    mask = np.ones((n, n), bool)
    r = block_steps(img, mask)
    assert r["inside"] == 0.0 and r["ratio"] > 1e6
    want = (np.abs(np.diff(levels, axis=0)).mean() * (n // 8 - 1) * n
            + np.abs(np.diff(levels, axis=1)).mean() * (n // 8 - 1) * n) / (2 * (n // 8 - 1) * n)
    assert r["across"] == pytest.approx(want / img.mean(), rel=1e-9)


def test_noise_has_a_ratio_near_one_and_blocks_on_noise_stand_out():
    """Independent per-pixel noise on a disc (RGB, luminance-weighted): ratio within 10% of 1 and
    `inside` the expected E|a - b| = 2 sigma / sqrt(pi). Block levels added on top of the same
    noise - steps as large as the noise - push the ratio above 1.5."""
    rng = np.random.default_rng(2)
    n, sigma = 96, 0.05
    mask = _disc(n)
    img = np.ones((n, n, 3)) + sigma * rng.standard_normal((n, n, 1))
    r = block_steps(img, mask)
    assert abs(r["ratio"] - 1) < 0.1
    assert r["inside"] == pytest.approx(2 * sigma / np.sqrt(np.pi), rel=0.05)
    levels = 0.07 * rng.standard_normal((n // 8, n // 8))
    blocky = img + np.repeat(np.repeat(levels, 8, 0), 8, 1)[..., None]
    assert block_steps(blocky, mask)["ratio"] > 1.5
    # the same blocks on a 4 x 4 grid are not 8 x 8 steps: only every other 4-boundary is one
    assert block_steps(blocky, mask, block=4)["ratio"] < block_steps(blocky, mask)["ratio"]


def test_a_smooth_gradient_has_ratio_one_and_an_empty_mask_is_refused():
    n = 64
    y, x = np.mgrid[0:n, 0:n].astype(np.float64)
    r = block_steps(1.0 + 0.01 * x + 0.02 * y, np.ones((n, n), bool))
    assert r["ratio"] == pytest.approx(1.0, abs=1e-9)
    with pytest.raises(ValueError):
        block_steps(np.ones((n, n)), np.zeros((n, n), bool))


def test_offset_moves_the_grid_the_metric_looks_for():
    """Blocks of a grid shifted by (3, 5): found at that offset (inside = 0), not at (0, 0)."""
    rng = np.random.default_rng(3)
    n, dx, dy = 64, 3, 5
    levels = 1.0 + 0.1 * rng.standard_normal((n // 8 + 1, n // 8 + 1))
    y, x = np.mgrid[0:n, 0:n]
    img = levels[(y + dy) // 8, (x + dx) // 8]
    mask = np.ones((n, n), bool)
    assert block_steps(img, mask, offset=(dx, dy))["inside"] == 0.0
    assert block_steps(img, mask)["ratio"] < 0.5
