"""Numpy twin of shaders/gi_upsample.glsl (with lib/joint_bilateral.glsl): per pixel, plain
loops, float64, written from the shaders' header comments rather than from their code.
Images in GL orientation (row 0 at the bottom), as the pass reads them."""

from __future__ import annotations

import math

import numpy as np

from app.pbgi import upsample as U


def _weight(wb, n_p, z_p, gq):
    w = wb
    if gq[3] > 0.0:
        w *= math.exp(-U.NORMAL_SHARPNESS * (1.0 - min(max(float(np.dot(n_p, gq[:3])), -1.0),
                                                         1.0)))
        w *= math.exp(-abs(gq[3] - z_p) / (U.DEPTH_TOLERANCE * z_p + 1e-4))
    else:
        w *= U.OFF_GUIDE_WEIGHT
    return max(w, 1e-6 * wb)


def upsample(gi: np.ndarray, guide: np.ndarray) -> tuple[np.ndarray, int]:
    """(out (H, W, 4): rgb and alpha 1 on the guide, 0 off it; unfilled pixels)."""
    gi = np.asarray(gi, np.float64)
    guide = np.asarray(guide, np.float64)
    h, w = gi.shape[:2]
    H, W = guide.shape[:2]
    out = np.zeros((H, W, 4))
    unfilled = 0

    def asset(t):
        return gi[t[1], t[0], 3] >= 0.5

    for py in range(H):
        for px in range(W):
            g = guide[py, px]
            if g[3] <= 0.0:
                continue
            qx, qy = (px + 0.5) * w / W - 0.5, (py + 0.5) * h / H - 0.5
            ix, iy = math.floor(qx), math.floor(qy)
            fx, fy = qx - ix, qy - iy
            acc, ws = np.zeros(3), 0.0
            for dy in (0, 1):
                for dx in (0, 1):
                    wb = (1 - fx if dx == 0 else fx) * (1 - fy if dy == 0 else fy)
                    if wb <= 0:
                        continue
                    t = (min(max(ix + dx, 0), w - 1), min(max(iy + dy, 0), h - 1))
                    if not asset(t):
                        continue
                    gx = min(max(int((t[0] + 0.5) * W / w), 0), W - 1)
                    gy = min(max(int((t[1] + 0.5) * H / h), 0), H - 1)
                    wt = _weight(wb, g[:3], g[3], guide[gy, gx])
                    acc += wt * gi[t[1], t[0], :3]
                    ws += wt
            if ws <= 0:     # the four taps whatever their bilinear weight
                for k in range(4):
                    t = (min(max(ix + (k & 1), 0), w - 1), min(max(iy + (k >> 1), 0), h - 1))
                    if asset(t):
                        acc += gi[t[1], t[0], :3]
                        ws += 1.0
            r = 1
            while ws <= 0 and r <= U.FALLBACK_RINGS:   # then rings further out
                for ty in range(iy - r, iy + 2 + r):
                    for tx in range(ix - r, ix + 2 + r):
                        ring = tx in (ix - r, ix + 1 + r) or ty in (iy - r, iy + 1 + r)
                        if ring and 0 <= tx < w and 0 <= ty < h and asset((tx, ty)):
                            acc += gi[ty, tx, :3]
                            ws += 1.0
                r += 1
            if ws > 0:
                out[py, px] = (*(acc / ws), 1.0)
            else:
                out[py, px] = (0.0, 0.0, 0.0, 1.0)
                unfilled += 1
    return out, unfilled
