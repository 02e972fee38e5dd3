"""Projection of expanded renderings back to the points (paper Section 4.1, last step).

Only overexposed points (LDR luminance > tl) that a face sees (depth test against its z-buffer)
receive samples. Samples are averaged over the views: plainly for the ITMOs, weighted by match
quality for PatchMatch (weight 1 / (SSD + eps): lower SSD, more weight), where samples with an SSD
above th are rejected. All values are on the LDR cloud's scale: the photo's radiance times alpha.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.color import luminance
from app.hdr.capture import Face
from app.hdr.itmo import rescale_luminance
from app.hdr.patchmatch import NNField

SSD_EPS = 1e-2


@dataclass
class PhotoMatch:
    """A face's NNF to the photo, with the work-resolution factors of both images."""

    field: NNField
    face_factor: float   # face pixels per work pixel
    photo_factor: float  # photo pixels per work pixel
    textured: np.ndarray | None = None  # work pixels whose patch has structure (scale evidence)


def bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Sample (H, W, C) at pixel-centre coordinates (x = column, pixel j centred at j), clamped."""
    h, w = img.shape[:2]
    x = np.clip(x, 0, w - 1)
    y = np.clip(y, 0, h - 1)
    x0 = np.minimum(np.floor(x).astype(np.int64), max(w - 2, 0))
    y0 = np.minimum(np.floor(y).astype(np.int64), max(h - 2, 0))
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    top = img[y0, x0] * (1 - fx) + img[y0, x1] * fx
    bot = img[y1, x0] * (1 - fx) + img[y1, x1] * fx
    return top * (1 - fy) + bot * fy


def match_samples(match: PhotoMatch, photo_hdr: np.ndarray, u: np.ndarray, v: np.ndarray):
    """(rgb, ssd) fetched from the HDR photo for face positions (u, v) (pixel i spans [i, i+1))."""
    ax = u / match.face_factor - 0.5
    ay = v / match.face_factor - 0.5
    bx, by = match.field.map(ax, ay)
    px = (bx + 0.5) * match.photo_factor - 0.5
    py = (by + 0.5) * match.photo_factor - 0.5
    h, w = match.field.cost.shape
    j = np.clip(np.rint(ax), 0, w - 1).astype(np.int64)
    i = np.clip(np.rint(ay), 0, h - 1).astype(np.int64)
    return bilinear(photo_hdr, px, py), match.field.cost[i, j]


@dataclass
class Projection:
    values: np.ndarray    # (N, 3) float32 averaged expanded colour (valid where has_value)
    has_value: np.ndarray  # (N,) bool: at least one accepted sample
    seen: np.ndarray      # (N,) bool: visible in at least one face
    samples: int          # accepted samples
    rejected: int         # samples with SSD > th
    ssd: np.ndarray       # SSD of all samples (accepted or not), for the report
    score: np.ndarray     # (N,) float32 best accepted SSD per point (NaN: none, or no SSD)


def project_to_points(points: np.ndarray, ldr: np.ndarray, targets: np.ndarray,
                      faces: list[Face], sampler, th: float | None, cancel=None) -> Projection:
    """Average the expanded samples of every face over the ``targets`` points (indices).

    ``sampler(face_index, u, v, target_ldr) -> (rgb, ssd or None)`` gives the expanded value of
    the face at the points' pixel positions (already multiplied by alpha).
    """
    n = len(points)
    acc = np.zeros((len(targets), 3))
    wsum = np.zeros(len(targets))
    seen = np.zeros(len(targets), dtype=bool)
    accepted = rejected = 0
    ssds = []
    best = np.full(len(targets), np.inf)
    tp = points[targets]
    for fi, face in enumerate(faces):
        if cancel is not None:
            cancel()
        vis, u, v = face.visible(tp)
        sel = np.flatnonzero(vis)
        if len(sel) == 0:
            continue
        seen[sel] = True
        rgb, ssd = sampler(fi, u[sel], v[sel], ldr[targets[sel]])
        if ssd is None:
            w = np.ones(len(sel))
        else:
            ssds.append(ssd)
            ok = ssd <= th
            rejected += int((~ok).sum())
            w = np.where(ok, 1.0 / (ssd + SSD_EPS), 0.0)
        good = w > 0
        if ssd is not None:
            idx = sel[good]
            best[idx] = np.minimum(best[idx], ssd[good])
        accepted += int(good.sum())
        acc[sel[good]] += w[good, None] * rgb[good]
        wsum[sel[good]] += w[good]
    values = np.zeros((n, 3), dtype=np.float32)
    has = np.zeros(n, dtype=bool)
    ok = wsum > 0
    values[targets[ok]] = (acc[ok] / wsum[ok, None]).astype(np.float32)
    has[targets[ok]] = True
    seen_all = np.zeros(n, dtype=bool)
    seen_all[targets[seen]] = True
    score = np.full(n, np.nan, dtype=np.float32)
    fin = np.isfinite(best)
    score[targets[fin]] = best[fin]
    return Projection(values, has, seen_all, accepted, rejected,
                      np.concatenate(ssds) if ssds else np.zeros(0), score)


def transfer(rgb: np.ndarray, ldr: np.ndarray, luminance_only: bool) -> np.ndarray:
    """The expanded colour of a point: the photo's colour, or its luminance on the LDR chroma."""
    if not luminance_only:
        return rgb
    return rescale_luminance(ldr, luminance(rgb).astype(np.float64))
