"""The inverse tone mapping baselines of Table 2: Landis 2002 and Banterle 2006 (luminance only).

Both need the maximum luminance of the expanded range, which an LDR input cannot tell; we take it
from the HDR photo (its 99.9th percentile luminance times the exposure alpha), the only fair
choice when the photo is at hand. They run on the renderings (``landis``, ``banterle``: the
per-pixel operator, then projection to the points) or directly on the points (``-pc``).

- Landis 2002 (as given in Banterle et al., Advanced High Dynamic Range Imaging):
  Lw = (1 - k) Ld + k Lmax Ld for Ld >= R, with k = ((Ld - R) / (1 - R))^a, else Lw = Ld.
  R defaults to tl so the operator is continuous at the threshold that decides which points
  are expanded at all.
- Banterle 2006: the inverse of Reinhard's photographic operator (white point = Lmax, so dark
  values map to themselves and 1 maps to Lmax), blended with the LDR luminance through an
  "expand map": a smooth [0, 1] density of the bright pixels. The paper estimates that density
  from median-cut light samples; a Gaussian-filtered bright-luminance map is the same density
  estimate without the sampling step. On points the Gaussian becomes repeated averaging over the
  k-nearest-neighbour graph.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter

from app.color import luminance


def landis(ld: np.ndarray, l_max: float, threshold: float = 0.9, exponent: float = 2.0) -> np.ndarray:
    ld = np.asarray(ld, dtype=np.float64)
    k = (np.clip(ld - threshold, 0.0, None) / max(1.0 - threshold, 1e-6)) ** exponent
    lw = (1.0 - k) * ld + k * l_max * ld
    return np.where(ld >= threshold, lw, ld)


def inverse_reinhard(ld: np.ndarray, l_max: float, l_white: float | None = None) -> np.ndarray:
    ld = np.clip(np.asarray(ld, dtype=np.float64), 0.0, 1.0)
    lw2 = (l_max if l_white is None else l_white)
    return 0.5 * l_max * lw2 * (ld - 1.0 + np.sqrt((1.0 - ld) ** 2 + 4.0 * ld / lw2 ** 2))


def _normalise(e: np.ndarray) -> np.ndarray:
    m = float(e.max()) if e.size else 0.0
    return e / m if m > 0 else np.zeros_like(e)


def expand_map_image(ld: np.ndarray, threshold: float, sigma: float) -> np.ndarray:
    """[0, 1] smooth density of the bright pixels of a (H, W) luminance image."""
    bright = np.where(ld >= threshold, ld, 0.0)
    return np.clip(_normalise(gaussian_filter(bright, sigma, mode="nearest")), 0.0, 1.0)


def expand_map_points(ld: np.ndarray, neighbours: np.ndarray, threshold: float,
                      iterations: int = 8) -> np.ndarray:
    """The same density on points: bright luminance averaged over the k-NN graph.

    ``neighbours`` (m, k) indexes ``ld``; -1 marks a neighbour outside the set (a dark point:
    it adds 0), so the graph can be built for the bright points and their surroundings only.
    """
    e = np.where(ld >= threshold, ld, 0.0)
    valid = neighbours >= 0
    nb = np.where(valid, neighbours, 0)
    for _ in range(iterations):
        e = 0.5 * e + 0.5 * np.where(valid, e[nb], 0.0).mean(axis=1)
    return np.clip(_normalise(e), 0.0, 1.0)


def banterle(ld: np.ndarray, l_max: float, expand_map: np.ndarray) -> np.ndarray:
    ld = np.asarray(ld, dtype=np.float64)
    return ld + expand_map * (inverse_reinhard(ld, l_max) - ld)


def rescale_luminance(rgb: np.ndarray, y_new: np.ndarray) -> np.ndarray:
    """Colours with their luminance replaced (chromaticity kept): luminance-only transfer."""
    y_old = luminance(rgb).astype(np.float64)
    ratio = np.where(y_old > 1e-8, y_new / np.maximum(y_old, 1e-8), 0.0)
    out = rgb * ratio[..., None]
    grey = y_old <= 1e-8  # black pixel, bright target: grey of the target luminance
    if np.any(grey):
        out[grey] = np.asarray(y_new)[grey, None]
    return out.astype(np.float32)


def expand_face(rgb: np.ndarray, method: str, l_max: float, threshold: float,
                exponent: float = 2.0, sigma_frac: float = 0.02) -> np.ndarray:
    """An expanded (H, W, 3) rendering, ``method`` 'landis' or 'banterle'."""
    ld = luminance(rgb).astype(np.float64)
    if method == "landis":
        y = landis(ld, l_max, threshold, exponent)
    elif method == "banterle":
        sigma = max(1.0, sigma_frac * max(ld.shape))
        y = banterle(ld, l_max, expand_map_image(ld, threshold, sigma))
    else:
        raise ValueError(f"unknown ITMO {method!r}")
    return rescale_luminance(rgb, y)


def expand_points(rgb: np.ndarray, method: str, l_max: float, threshold: float,
                  neighbours: np.ndarray | None = None, exponent: float = 2.0,
                  map_iterations: int = 8) -> np.ndarray:
    """Per-point ITMO ('landis-pc', 'banterle-pc'): expanded colours for all given points."""
    ld = luminance(rgb).astype(np.float64)
    if method == "landis-pc":
        y = landis(ld, l_max, threshold, exponent)
    elif method == "banterle-pc":
        if neighbours is None:
            raise ValueError("banterle-pc needs the k-NN graph")
        y = banterle(ld, l_max, expand_map_points(ld, neighbours, threshold, map_iterations))
    else:
        raise ValueError(f"unknown ITMO {method!r}")
    return rescale_luminance(rgb, y)
