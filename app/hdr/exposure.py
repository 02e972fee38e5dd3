"""Exposure search (paper eq. 1): the alpha that makes clamp(alpha * I_HDR) look like the LDR cloud.

Distance: Wasserstein (earth mover's) distance between 128-bin CIE Y histograms on [0, 1] of the
whole LDR cloud and of the clamped photo. Search: a coarse scan over whole stops (the fixed
exposures of the paper's exposure-fusion step), then a bracketing search in log-exposure between
the scanned neighbours of the best stop: each iteration compares the distance at the bracket's
quarter points and keeps the part that holds the minimum (the distance is unimodal in alpha),
until the best distance stops decreasing (5 iterations without a decrease once the bracket is
below 1/20 stop), the bracket is below a thousandth of a stop, or after ``max_iters`` (50).

Deviation from the paper (parameter ``include_clipped``, default False): the top bin, where every
clipped value piles up, is left out of both histograms. Its mass says how much of the *frame* the
light sources fill, which depends on where the photo was pointed, not on the exposure; with it the
W1 optimum on the demo scene is 13% off the scan's exposure, without it 5%.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import wasserstein_distance

from app.color import luminance


@dataclass(frozen=True)
class ExposureResult:
    alpha: float
    distance: float
    iterations: int
    scanned: tuple  # ((alpha, distance), ...) of the coarse scan


def histogram(y: np.ndarray, bins: int = 128) -> np.ndarray:
    h, _ = np.histogram(np.clip(y, 0.0, 1.0), bins=bins, range=(0.0, 1.0))
    return h.astype(np.float64)


class _PhotoHistogram:
    """Histograms of clamp(alpha * photo) luminance for any alpha, from sorted photo samples.

    Clamping is per channel before the luminance (eq. 1), so the luminance of the clamped photo
    is not a function of the photo luminance alone: we keep the RGB samples and recompute.
    """

    def __init__(self, photo: np.ndarray, bins: int, max_samples: int = 262_144, seed: int = 0):
        rgb = np.asarray(photo, dtype=np.float32).reshape(-1, 3)
        if len(rgb) > max_samples:  # a regular subsample: histograms need no more
            rgb = rgb[np.random.default_rng(seed).choice(len(rgb), max_samples, replace=False)]
        self.rgb = rgb
        self.bins = bins

    def __call__(self, alpha: float) -> np.ndarray:
        return histogram(luminance(np.clip(alpha * self.rgb, 0.0, 1.0)), self.bins)


def find_exposure(cloud_colors: np.ndarray, photo: np.ndarray, bins: int = 128,
                  max_iters: int = 50, stops: tuple[int, int] = (-12, 12),
                  include_clipped: bool = False, cancel=None) -> ExposureResult:
    """alpha minimising W1(hist(Y(cloud)), hist(Y(clamp(alpha * photo)))) (eq. 1)."""
    keep = bins if include_clipped else bins - 1
    centres = ((np.arange(bins) + 0.5) / bins)[:keep]
    h_cloud = histogram(luminance(cloud_colors), bins)[:keep]
    photo_h = _PhotoHistogram(photo, bins)

    def dist(alpha: float) -> float:
        h = photo_h(alpha)[:keep]
        if h.sum() == 0 or h_cloud.sum() == 0:
            return np.inf
        return float(wasserstein_distance(centres, centres, h_cloud, h))

    y = luminance(photo_h.rgb)
    pos = y[y > 0]
    if len(pos) == 0:
        raise ValueError("photo has no positive pixel")
    base = 1.0 / float(np.percentile(pos, 99))  # 0 stops: the photo's 99th percentile -> 1
    ks = np.arange(stops[0], stops[1] + 1)
    scan = [(base * 2.0 ** k, dist(base * 2.0 ** k)) for k in ks]
    ds = np.array([d for _, d in scan])
    i = int(np.argmin(ds))
    lo = np.log2(scan[max(i - 1, 0)][0])
    hi = np.log2(scan[min(i + 1, len(scan) - 1)][0])
    best_x, best_d = np.log2(scan[i][0]), ds[i]
    iters = 0
    stalls = 0
    while iters < max_iters and hi - lo > 1e-3:
        if cancel is not None:
            cancel()
        iters += 1
        q1, q3 = lo + 0.25 * (hi - lo), lo + 0.75 * (hi - lo)
        d1, d3 = dist(2.0 ** q1), dist(2.0 ** q3)
        if d1 <= d3:          # unimodal: the minimum is not beyond q3
            hi = q3
        else:
            lo = q1
        d, x = (d1, q1) if d1 <= d3 else (d3, q3)
        if d < best_d:
            best_x, best_d = x, d
            stalls = 0
        else:
            stalls += 1
            # "until the error stops decreasing": once the bracket is down to a few percent
            # (before, the quarter points are simply still far from the minimum)
            if stalls >= 5 and hi - lo < 0.05:
                break
    return ExposureResult(float(2.0 ** best_x), float(best_d), iters,
                          tuple((float(a), float(d)) for a, d in scan))
