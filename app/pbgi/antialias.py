"""Which pixels a silhouette crosses: the only ones whose box-filtered value needs more than one
sample (``Relighter.render_passes`` with ``edge_samples``).

A pixel's footprint is its square; one sample at its centre gives its exact box-filtered value
only where the asset covers all of the square or none of it and the surface under it is one
continuous piece. Both fail where coverage changes between the pixel and a neighbour (the
asset's outline) or the distance to the surface jumps (one part of the asset in front of
another: the inner silhouettes of a non-convex asset). Against the path tracer (issue 18) the
2% of object pixels on the outline carried almost half of a whole-object view's per-pixel
error, so those pixels get ``edge_samples`` samples (gbuffer.pass_jitter's points of that many
passes, centred on the pixel: a box filter over the footprint) and their alpha becomes the
covered fraction - true coverage; all others keep the passes they had.
"""

from __future__ import annotations

import numpy as np

DEPTH_JUMP = 0.04   # relative change of the distance to a neighbour that makes an inner edge


def _neighbours(a: np.ndarray, fill):
    """The 8 neighbours of every pixel (edge pixels see ``fill`` outside)."""
    p = np.pad(a, 1, constant_values=fill)
    h, w = a.shape
    return [p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
            for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]


def silhouette_pixels(alpha: np.ndarray, depth: np.ndarray,
                      depth_jump: float = DEPTH_JUMP) -> np.ndarray:
    """(h, w) bool: pixels whose 3x3 neighbourhood mixes covered and uncovered pixels (or
    partly covered ones), or covered pixels whose distance differs from a covered
    neighbour's by more than ``depth_jump`` of it. ``depth``: inf where nothing is covered."""
    alpha = np.asarray(alpha, np.float64)
    covered = alpha > 0.5
    edge = (alpha > 0.0) & (alpha < 1.0)
    for n in _neighbours(covered, False):
        edge |= n != covered
    d = np.where(covered & np.isfinite(depth), depth, np.nan)
    for n in _neighbours(d, np.nan):
        with np.errstate(invalid="ignore"):
            edge |= np.abs(n - d) > depth_jump * np.fmin(d, n)
    return edge


__all__ = ["silhouette_pixels", "DEPTH_JUMP"]
