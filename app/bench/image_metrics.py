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
* ``block_steps``: adjacent-pixel differences across the 8 x 8 block boundaries of the pixel
  grid against those inside the blocks (Hybrid's far-field sharing must not draw its blocks).
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


def block_steps(image, mask, block: int = 8, offset=(0, 0)) -> dict:
    """Block steps (Hybrid's far-field sharing, app/pbgi/farfield.py): the mean absolute
    luminance difference of horizontally and vertically adjacent pixels, both on ``mask``, whose
    pair crosses a ``block`` x ``block`` boundary of the pixel grid (``across``) or lies inside
    one block (``inside``), each relative to the mean luminance over the mask; ``ratio`` =
    across / inside. Why both: a structure that is the same over a block and jumps at its edge
    (a blocky image) gives a ratio well above 1, noise or a smooth image about 1. ``offset``
    (dx, dy): the blocks are those of pixel (x + dx, y + dy) (a shifted block grid, as
    app/pbgi/farfield.py's grid_offset shifts Hybrid's)."""
    y = np.asarray(image, np.float64)
    y = y[..., :3] @ LUMA if y.ndim == 3 else y
    m = np.asarray(mask, bool)
    if not m.any():
        raise ValueError("block_steps: empty mask")
    mean = max(float(y[m].mean()), 1e-30)
    sums = {True: [0.0, 0], False: [0.0, 0]}
    for axis in (0, 1):
        a, b = (y[:-1], y[1:]) if axis == 0 else (y[:, :-1], y[:, 1:])
        ok = (m[:-1] & m[1:]) if axis == 0 else (m[:, :-1] & m[:, 1:])
        n = y.shape[axis] - 1
        shift = int(offset[1 - axis])                     # axis 0 is y
        edge = (np.arange(n) + shift) % block == block - 1   # k and k + 1 in different blocks
        edge = edge[:, None] if axis == 0 else edge[None, :]
        d = np.abs(a - b)
        for cross in (True, False):
            sel = ok & (edge if cross else ~edge)
            sums[cross][0] += float(d[sel].sum())
            sums[cross][1] += int(sel.sum())
    if not sums[True][1] or not sums[False][1]:
        raise ValueError(f"block_steps: the mask holds no adjacent pair across and inside "
                         f"{block}x{block} blocks")
    across = sums[True][0] / sums[True][1] / mean
    inside = sums[False][0] / sums[False][1] / mean
    return {"across": across, "inside": inside, "ratio": across / max(inside, 1e-30)}
