"""Hybrid's block levels: the far field's quantisation error, taken out block by block.

Why. A block of receivers shares one far-field micro-buffer (app/pbgi/farfield.py), so the
error of quantising a bright far node into micro-pixels is the same over the block and jumps at
its edge: the block steps of issue 12 (4x4 and 8x8 squares on a diffuse sphere in one pass). In
Classic every receiver has its own error, which changes a little from pixel to pixel instead.

What. Per block, two irradiances at its centre with its normal: E_b from its far-field
micro-buffer (the shared part, with the block's quantisation error q_b), and E_env(n_b) from the
room's cube map seen from the asset's centre (app/pbgi/envmap.py: each micro-pixel reads the
cube map prefiltered over its solid angle, so a small bright light is spread, not hit or missed -
no quantisation step). Their ratio r_b = E_b / E_env(n_b) holds what the cube map lacks (parallax,
the asset's shadow on itself, the far field's lower bound at the block's ball) - smooth from
block to block - times (1 + q_b), which is not: each block's frame puts a bright node in another
micro-pixel. So a weighted least-squares fit of r over the neighbouring blocks (screen distance
up to ``reach`` x the block's side), linear in the normal,
    r_b' ~ c + g . (n_b' - n_b)    (per colour channel; n_b' - n_b in the tangent plane of n_b),
estimates the smooth part times (1 + the neighbourhood's mean q) at the block, and the block's
level is fit / r_b. The gather multiplies the block's far-field entries (MB_FAR_BIT, copied by the
merge) by it; the receiver's own near field and the lobe buffers are not shared and keep theirs
(shaders/pbgi_gather.glsl with FRAME_NORMALS). A receiver then carries the quantisation error
averaged over a dozen blocks, which changes smoothly from block to block.

Dividing by the cube map's irradiance first matters: the fit is linear, and a sunlit sphere's
irradiance curves strongly with the normal, so a fit of E_b itself pulled every block towards
its neighbours' mean curvature (4x4-pooled error against the path tracer, panorama room, sphere:
1.16 -> 1.36%; with the ratio 1.08%).

Where it does not apply. A neighbour whose normal is more than ~18 degrees off (GATE_COS), or
whose centre is farther away in the scene than the screen distance allows (a depth edge), does
not count. A block keeps level 1 when fewer than MIN_NEIGHBOURS blocks count (itself included),
when its neighbourhood is flat (the counting blocks' normals within ``flat`` of its own: their
frames are the same, so a distant node falls into the same micro-pixel of every one - no step
to take out, while a fit there would only smooth real changes of the far field, e.g. the gaps
between the boxes of a non-convex asset: 4x4 error against the path tracer 2.40 -> 5.04% and
5.01 -> 6.04% without this rule, unchanged with it), or when its level would move a channel by
more than MAX_CHANGE (a real change of light, not quantisation): over 16 views (demo and
panorama rooms, sphere and bunny, close-up and whole, M 16 and 24) no level moved by more than
0.23 (most by under 0.02), while a block twice as bright as its neighbours would get 0.6.
"""

from __future__ import annotations

import numpy as np

from app.pbgi.brdf import orthonormal_basis
from app.pbgi.gpu_layout import SHARE_NONE
REACH = 2.0            # neighbours up to this x the block's side (pixels) away on screen
GATE_COS = 0.95        # ... whose normal is within acos(0.95) = 18 degrees of the block's
MIN_NEIGHBOURS = 6     # blocks that must count (the block itself included) for a fit
MAX_CHANGE = 0.3       # a level moving a channel by more than this is left at 1
RIDGE = 1e-3           # radians: normal differences below this fit no slope
DEPTH_SLACK = 2.0      # a neighbour may be this x the expected world distance away (see below)


def screen_centres(pixels: np.ndarray, block_of: np.ndarray, blocks: int,
                   width: int) -> tuple[np.ndarray, np.ndarray]:
    """Per block, the mean (x, y) pixel of its receivers (blocks, 2) and its receiver count."""
    has = block_of != SHARE_NONE
    b = block_of[has].astype(np.int64)
    px = np.asarray(pixels, np.int64)[has]
    cnt = np.bincount(b, minlength=blocks).astype(np.float64)
    safe = np.maximum(cnt, 1.0)
    xy = np.stack([np.bincount(b, px % width, blocks) / safe,
                   np.bincount(b, px // width, blocks) / safe], 1)
    return xy, cnt


def neighbour_pairs(xy: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All ordered pairs (a, b) of blocks with b within radius[a] pixels of a on screen, the
    block itself included (a, a)."""
    from scipy.spatial import cKDTree
    n = len(xy)
    pairs = cKDTree(xy).query_pairs(float(radius.max()), output_type="ndarray")
    a = np.concatenate([pairs[:, 0], pairs[:, 1], np.arange(n)]).astype(np.int64)
    b = np.concatenate([pairs[:, 1], pairs[:, 0], np.arange(n)]).astype(np.int64)
    keep = np.linalg.norm(xy[b] - xy[a], axis=1) <= radius[a]
    return a[keep], b[keep]


def block_levels(values: np.ndarray, axis: np.ndarray, centre: np.ndarray, rho: np.ndarray,
                 side: np.ndarray, xy: np.ndarray, count: np.ndarray, flat: float = 0.0,
                 reach: float = REACH, gate_cos: float = GATE_COS,
                 min_neighbours: int = MIN_NEIGHBOURS,
                 max_change: float = MAX_CHANGE) -> np.ndarray:
    """Per block its level (blocks, 3): the fit of ``values`` over its neighbours at the block,
    over its own value (module docstring).

    ``values`` (B, 3): r_b, positive; ``axis`` (B, 3) unit normals; ``centre`` (B, 3) world
    centres; ``rho`` (B,) the largest distance of a receiver from the centre (world); ``side``
    (B,) the block's square side in pixels; ``xy`` (B, 2) and ``count`` (B,): screen_centres;
    ``flat`` (radians): the weighted RMS normal difference of the counting neighbours below
    which the block keeps level 1.
    Weights: a tent in screen distance (0 at reach x side) times the neighbour's receivers. The
    depth gate: a block spans about rho sqrt(2) / side world units per pixel, so a neighbour d
    pixels away should lie within DEPTH_SLACK x d x that (+ both radii) in the scene."""
    v = np.asarray(values, np.float64)
    nb = len(v)
    levels = np.ones((nb, 3))
    if nb == 0:
        return levels
    axis = np.asarray(axis, np.float64)
    xy = np.asarray(xy, np.float64)
    side = np.asarray(side, np.float64)
    radius = reach * side
    a, b = neighbour_pairs(xy, radius)
    d = np.linalg.norm(xy[b] - xy[a], axis=1)
    w = np.clip(1.0 - d / radius[a], 0.0, None) * np.asarray(count, np.float64)[b]
    w *= np.einsum("ij,ij->i", axis[a], axis[b]) >= gate_cos
    per_px = rho[a] * np.sqrt(2.0) / side[a]
    w *= (np.linalg.norm(centre[b] - centre[a], axis=1)
          <= DEPTH_SLACK * d * per_px + 2.0 * rho[a] + rho[b])
    t1, t2 = orthonormal_basis(axis)
    dn = axis[b] - axis[a]
    x = np.stack([np.ones(len(a)), np.einsum("ij,ij->i", dn, t1[a]),
                  np.einsum("ij,ij->i", dn, t2[a])], 1)
    normal_eq = np.zeros((nb, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            normal_eq[:, i, j] = normal_eq[:, j, i] = np.bincount(a, w * x[:, i] * x[:, j], nb)
    total = normal_eq[:, 0, 0]
    spread = np.sqrt(np.bincount(a, w * (dn * dn).sum(1), nb) / np.maximum(total, 1e-30))
    normal_eq[:, 1, 1] += RIDGE * RIDGE * total     # a ridge on the slopes
    normal_eq[:, 2, 2] += RIDGE * RIDGE * total
    counted = np.bincount(a, w > 0, nb)
    ok = (counted >= min_neighbours) & (total > 0) & (v > 0).all(1) & (spread >= flat)
    if not ok.any():
        return levels
    rhs = np.stack([np.stack([np.bincount(a, w * x[:, i] * v[b, c], nb) for i in range(3)], 1)
                    for c in range(3)], 2)          # (B, 3 unknowns, 3 channels)
    fit = np.linalg.solve(normal_eq[ok], rhs[ok])[:, 0, :]
    lv = fit / v[ok]
    lv[~np.isfinite(lv).all(1) | (np.abs(lv - 1.0) > max_change).any(1)] = 1.0
    levels[ok] = lv
    return levels
