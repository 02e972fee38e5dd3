"""The error metrics of the reference protocol (app/bench/mitsuba_scene.py), used by the
benchmarks and the accuracy tests alike.

* ``relative_rmse``: RMSE over the object's pixels divided by the reference's mean luminance
  there - per pixel (``pool`` 1), or after averaging ``pool`` x ``pool`` blocks ("4x4-pooled":
  what the eye sees of noise at a normal viewing distance, and what a converged progressive
  render shows). Blocks count only where every pixel is on the object.
* ``flip``: NVIDIA's FLIP (``flip-evaluator``), HDR-FLIP on linear images, mean over the mask.
* ``periodic_peak``: the artefact detector - the strongest non-zero-frequency peak of the power
  spectrum of (candidate - reference) over the object, relative to the median power: a regular
  grid of dots or blocks is a few sharp peaks, noise is flat.
* ``peak_ratio``: the largest candidate pixel over the largest reference pixel (a fireflies /
  20x-too-bright-dot check).
"""

from __future__ import annotations

import numpy as np

LUMA = np.array([0.2126, 0.7152, 0.0722])


def _pooled(img: np.ndarray, mask: np.ndarray, pool: int):
    if pool <= 1:
        return img, mask
    h, w = (img.shape[0] // pool) * pool, (img.shape[1] // pool) * pool
    im = img[:h, :w].reshape(h // pool, pool, w // pool, pool, -1).mean(axis=(1, 3))
    mk = mask[:h, :w].reshape(h // pool, pool, w // pool, pool).all(axis=(1, 3))
    return im, mk


def relative_rmse(candidate, reference, mask=None, pool: int = 1, reference_image=None) -> float:
    """RMSE over ``mask`` (all RGB channels) / mean luminance of the reference there.
    ``reference_image``: the image whose mean luminance normalises (default ``reference``)."""
    a = np.asarray(candidate, np.float64)[..., :3]
    b = np.asarray(reference, np.float64)[..., :3]
    norm_img = b if reference_image is None else np.asarray(reference_image, np.float64)[..., :3]
    m = np.ones(a.shape[:2], bool) if mask is None else np.asarray(mask, bool)
    if not m.any():
        raise ValueError("relative_rmse: empty mask")
    mean = float((norm_img[m] @ LUMA).mean())
    pa, pm = _pooled(a, m, pool)
    pb, _ = _pooled(b, m, pool)
    if not pm.any():
        raise ValueError(f"relative_rmse: no {pool}x{pool} block lies wholly on the mask")
    d = pa[pm] - pb[pm]
    return float(np.sqrt((d * d).mean()) / max(mean, 1e-30))


def flip(candidate, reference, mask=None) -> float | None:
    """Mean HDR-FLIP over ``mask`` (None when flip-evaluator is not installed)."""
    try:
        import flip_evaluator as fe
    except ImportError:
        return None
    a = np.ascontiguousarray(np.maximum(np.nan_to_num(candidate[..., :3]), 0), np.float32)
    b = np.ascontiguousarray(np.maximum(np.nan_to_num(reference[..., :3]), 0), np.float32)
    err = fe.evaluate(b, a, "HDR")[0]
    m = np.ones(a.shape[:2], bool) if mask is None else np.asarray(mask, bool)
    return float(np.asarray(err)[m].mean())


def periodic_peak(candidate, reference, mask, min_freq: int = 3) -> float:
    """Strongest power-spectrum peak of the luminance difference over the mask's bounding box,
    at frequencies >= ``min_freq`` cycles per box (the object's own shape lives below), divided
    by the median power there. Flat noise gives ~10-20; a dot grid gives hundreds."""
    m = np.asarray(mask, bool)
    ys, xs = np.nonzero(m)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    d = (np.asarray(candidate, np.float64)[..., :3] - np.asarray(reference, np.float64)[..., :3]) @ LUMA
    d = np.where(m, d, 0.0)[y0:y1, x0:x1]
    d = d - d[m[y0:y1, x0:x1]].mean() * m[y0:y1, x0:x1]
    win = np.outer(np.hanning(d.shape[0]), np.hanning(d.shape[1]))
    p = np.abs(np.fft.fft2(d * win)) ** 2
    fy = np.abs(np.fft.fftfreq(d.shape[0]) * d.shape[0])
    fx = np.abs(np.fft.fftfreq(d.shape[1]) * d.shape[1])
    far = np.maximum(fy[:, None], fx[None, :]) >= min_freq
    vals = p[far]
    return float(vals.max() / max(np.median(vals), 1e-30))


def peak_ratio(candidate, reference, mask) -> float:
    m = np.asarray(mask, bool)
    a = np.asarray(candidate, np.float64)[..., :3][m] @ LUMA
    b = np.asarray(reference, np.float64)[..., :3][m] @ LUMA
    return float(a.max() / max(b.max(), 1e-30))


def erode(mask, steps: int = 1) -> np.ndarray:
    """The mask without its outer ``steps`` pixels (the silhouette, whose anti-aliasing is the
    look-dev issue's: compared apart)."""
    m = np.asarray(mask, bool).copy()
    for _ in range(steps):
        e = m.copy()
        e[1:] &= m[:-1]
        e[:-1] &= m[1:]
        e[:, 1:] &= m[:, :-1]
        e[:, :-1] &= m[:, 1:]
        m = e
    return m
