"""Hybrid's block steps as a number, for the tests of its far-field sharing
(app/pbgi/farfield.py, tests/pbgi/test_pbgi_farfield.py) and of the metric itself
(tests/pbgi/test_block_steps.py)."""

from __future__ import annotations

import numpy as np

from app.bench.image_metrics import LUMA


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
