"""Equirectangular (latitude-longitude) panoramas: the direction of each pixel and a bilinear
lookup. One convention for every panorama Scanlight reads - the test rooms made from the
panoramas of ../shared/data (app/bench/panorama_rooms.py) and the HDRI that lights an asset
(app/pbgi/hdri.py):

* +y is up; the panorama's top row looks up, its bottom row down;
* its centre column looks along -z (the default camera's view), longitude grows towards +x, so
  the column at 3/4 of the width looks along +x;
* pixel centres at half-integer coordinates; the columns wrap around.

A rotation of a panorama by ``deg`` about +y (counter-clockwise seen from above) moves the light
that came from direction d to R(deg) d, so the lookup of direction d reads R(-deg) d.
"""

from __future__ import annotations

import numpy as np


def direction_to_uv(d: np.ndarray, w: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """Equirectangular pixel coordinates (pixel-centre convention) of (N, 3) unit directions."""
    lon = np.arctan2(d[:, 0], -d[:, 2])
    lat = np.arcsin(np.clip(d[:, 1], -1, 1))
    return (lon / (2 * np.pi) + 0.5) * w - 0.5, (0.5 - lat / np.pi) * h - 0.5


def rotate_about_y(d: np.ndarray, deg: float) -> np.ndarray:
    """(N, 3) directions rotated by ``deg`` about +y (counter-clockwise seen from above)."""
    if deg == 0:
        return d
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    out = np.array(d, dtype=np.float64, copy=True)
    out[:, 0] = c * d[:, 0] + s * d[:, 2]
    out[:, 2] = -s * d[:, 0] + c * d[:, 2]
    return out


def sample_panorama(pano: np.ndarray, d: np.ndarray, rotation_deg: float = 0.0) -> np.ndarray:
    """Bilinear lookup of (N, 3) directions (any length) with horizontal wrap-around, in the
    panorama rotated by ``rotation_deg`` about +y."""
    h, w = pano.shape[:2]
    d = np.asarray(d, dtype=np.float64)
    d = rotate_about_y(d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300),
                       -float(rotation_deg))
    x, y = direction_to_uv(d, w, h)
    y = np.clip(y, 0, h - 1)
    x0 = np.floor(x).astype(np.int64)
    y0 = np.minimum(np.floor(y).astype(np.int64), max(h - 2, 0))
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, x1 = x0 % w, (x0 + 1) % w
    y1 = np.minimum(y0 + 1, h - 1)
    top = pano[y0, x0] * (1 - fx) + pano[y0, x1] * fx
    bot = pano[y1, x0] * (1 - fx) + pano[y1, x1] * fx
    return (top * (1 - fy) + bot * fy).astype(np.float32)


__all__ = ["direction_to_uv", "rotate_about_y", "sample_panorama"]
