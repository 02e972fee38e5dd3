"""Numpy twin of shaders/viewer_composite.glsl: the linear composite of room and relit asset.

Slow and exact; tests compare it with the GPU pass, and it documents the maths in one readable
place (see the shader header for the rules). All images are in GL orientation here: row 0 at the
bottom, as the textures hold them. The images are (..., words) arrays of the texel records of
app/render/gpu_layout.py (ViewportRenderer.read_inputs); their columns are taken from there.
"""

from __future__ import annotations

import numpy as np

# the joint bilateral weights are app/pbgi/upsample.py's (shared with `render --render-scale`)
from app.pbgi.upsample import DEPTH_TOLERANCE, NORMAL_SHARPNESS, OFF_GUIDE_WEIGHT  # noqa: F401
from app.render.gpu_layout import COMPOSITE_TEXEL, GI_TEXEL, GUIDE_TEXEL, ROOM_TEXEL

_RGB = GI_TEXEL.columns("radiance")          # GI texel: radiance; status: 1 asset, < 0 pending
_STATUS = GI_TEXEL.index("status")
_NORMAL = GUIDE_TEXEL.columns("normal")      # G-buffer texel: normal, depth (0: no asset)
_DEPTH = GUIDE_TEXEL.index("depth")

ROOM_DEPTH_SLACK = (1.002, 1e-3)  # the asset wins ties with the room within 0.2% + 1 mm


def linear_depth(d, near: float, far: float):
    ndc = 2.0 * np.asarray(d, np.float64) - 1.0
    return 2.0 * near * far / (far + near - ndc * (far - near))


def upsample(lo_img: np.ndarray, gbuf: np.ndarray, size: tuple[int, int]):
    """(rgb_sum, weight, pending) per output pixel for one GI image, exactly as the shader."""
    H, W = size
    h, w = lo_img.shape[:2]
    py, px = np.mgrid[0:H, 0:W]
    qx = (px + 0.5) * w / W - 0.5
    qy = (py + 0.5) * h / H - 0.5
    ix, iy = np.floor(qx).astype(np.int64), np.floor(qy).astype(np.int64)
    fx, fy = qx - ix, qy - iy
    n_p, z_p = gbuf[..., _NORMAL], gbuf[..., _DEPTH]
    acc = np.zeros((H, W, 3))
    wsum = np.zeros((H, W))
    pending = np.zeros((H, W), bool)
    for dy in (0, 1):
        for dx in (0, 1):
            wb = (1 - fx if dx == 0 else fx) * (1 - fy if dy == 0 else fy)
            tx = np.clip(ix + dx, 0, w - 1)
            ty = np.clip(iy + dy, 0, h - 1)
            s = lo_img[ty, tx].astype(np.float64)
            use = wb > 0
            pending |= use & (s[..., _STATUS] < 0)
            use &= s[..., _STATUS] >= 0.5
            gx = np.clip(((tx + 0.5) * W / w).astype(np.int64), 0, W - 1)
            gy = np.clip(((ty + 0.5) * H / h).astype(np.int64), 0, H - 1)
            gq = gbuf[gy, gx].astype(np.float64)
            on = gq[..., _DEPTH] > 0
            cos = np.clip(np.sum(n_p * gq[..., _NORMAL], axis=-1), -1, 1)
            wg = np.exp(-NORMAL_SHARPNESS * (1 - cos)) * np.exp(
                -np.abs(gq[..., _DEPTH] - z_p) / (DEPTH_TOLERANCE * z_p + 1e-4))
            wt = wb * np.where(on, wg, OFF_GUIDE_WEIGHT)
            wt = np.maximum(wt, 1e-6 * wb) * use
            acc += wt[..., None] * s[..., _RGB]
            wsum += wt
    # Fallback: no usable tap and nothing pending -> mean of the asset taps among the four
    # (lib/joint_bilateral.glsl), whatever their bilinear weight.
    fb = (wsum <= 0) & ~pending
    if fb.any():
        facc = np.zeros((H, W, 3))
        fcnt = np.zeros((H, W))
        for dy in (0, 1):
            for dx in (0, 1):
                s = lo_img[np.clip(iy + dy, 0, h - 1), np.clip(ix + dx, 0, w - 1)]
                s = s.astype(np.float64)
                ok = s[..., _STATUS] >= 0.5
                facc += ok[..., None] * s[..., _RGB]
                fcnt += ok
        acc = np.where(fb[..., None], facc, acc)
        wsum = np.where(fb, fcnt, wsum)
    return acc, wsum, pending


def composite(room: np.ndarray, room_depth: np.ndarray, gbuf: np.ndarray, preview: np.ndarray,
              full: np.ndarray, near: float, far: float, background=(0.0, 0.0, 0.0),
              has_asset: bool = True) -> np.ndarray:
    """(H, W, 4) linear composite (COMPOSITE_TEXEL): radiance, asset = 1 where it is shown."""
    H, W = room.shape[:2]
    covered = room[..., ROOM_TEXEL.columns("coverage")] > 0
    room_rgb = np.where(covered, room[..., ROOM_TEXEL.columns("radiance")],
                        np.asarray(background, np.float64))
    out = room_rgb.astype(np.float64).copy()
    asset = np.zeros((H, W), bool)
    if has_asset:
        g = gbuf.astype(np.float64)
        room_z = np.where(covered[..., 0], linear_depth(room_depth, near, far), 1e30)
        vis = (g[..., _DEPTH] > 0) & (g[..., _DEPTH] <= room_z * ROOM_DEPTH_SLACK[0]
                                      + ROOM_DEPTH_SLACK[1])
        acc_f, w_f, pend_f = upsample(full, g, (H, W))
        acc_p, w_p, _ = upsample(preview, g, (H, W))
        use_p = pend_f | (w_f <= 0)
        acc = np.where(use_p[..., None], acc_p, acc_f)
        wsum = np.where(use_p, w_p, w_f)
        asset = vis & (wsum > 0)
        out = np.where(asset[..., None], acc / np.maximum(wsum, 1e-300)[..., None], out)
    res = COMPOSITE_TEXEL.zeros(H * W)
    res["radiance"] = out.reshape(-1, 3)
    res["asset"] = asset.reshape(-1)
    return COMPOSITE_TEXEL.flat(res).reshape(H, W, COMPOSITE_TEXEL.words)
