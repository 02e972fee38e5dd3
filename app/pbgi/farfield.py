"""Far-field sharing: Hybrid PBGI's shared walk on a CPU.

Why: on llvmpipe the paper's Hybrid speed-up (coherent breadth-first refinement on thousands of
GPU threads) does not exist - all three modes reach the same cut, and finding and rasterising
that cut per receiver is nearly all of a frame. The only way to do less per receiver is to share
the *result* of the walk between neighbours, and the part of the scene where that is exact up to
a tolerance is the far field:

* receivers are grouped into aligned square blocks of the pixel grid (2x2 .. 2^L x 2^L, L =
  ``max_level``), the grid shifted by a per-pass offset (grid_offset; below). A block is
  usable when its receivers' normals lie within ``max_cone`` of their mean; each receiver takes
  the coarsest usable block above it (none: it walks alone, exactly as in Classic);
* the block's ball: centre = the mean of its receivers' positions, D = rho / tol with rho the
  largest distance of a receiver from the centre and tol = eps x 2 / M radians (eps = the
  parallax tolerance in micro-pixels, 2 / M a micro-pixel's narrowest angular size). A BSH node
  whose sphere lies outside the ball is *far*: seen from any receiver of the block rather than
  from the centre, its direction moves by less than rho / D = tol. A parent's sphere contains its
  children's (app/pbgi/hierarchy.py), so a far node's sub-tree is far, and the far/near split of
  the tree is a partition: every leaf is drawn exactly once, by the block or by the receiver;
* per block, one Classic walk of the far field only, from the centre, in the frame of the cone
  axis (shaders/pbgi_classic.glsl with SHARE_SPLIT 1), into a block micro-buffer;
* per receiver: its micro-buffer is kept in its block's frame; copy the block's buffer into it
  entry for entry (shaders/pbgi_share_merge.glsl), then a Classic walk of the near field only
  (SHARE_SPLIT 2) into it, depth tested. The gather is every mode's, told the frame
  (FRAME_NORMALS): each entry is weighted by the cosine about the receiver's own normal,
  max(n . flux_k, 0) with flux_k the integral of the direction over the entry
  (app/pbgi/microbuffer.py), and the BRDF uses the receiver's own normal.

The approximation: far nodes are drawn from the block centre (<= eps micro-pixels off); the
entries the receiver's horizon cuts are weighted as if the region lay wholly above it, and the
sliver above the receiver's horizon but below the block's is missing (<= max_cone wide: about
max_cone^2 / 4 of the cosine-weighted hemisphere, 0.25% at 0.1 rad); a far node competing with a
near one for an entry has its depth measured from the centre. The quantisation of a bright light
into micro-pixels is then the same over a block instead of varying pixel to pixel - not larger:
against Classic at M = 32, Hybrid at M = 16 is as close as Classic at M = 16
(tests/pbgi/test_pbgi_farfield.py). eps = 0 turns the sharing off (app/pbgi/hybrid.py).

Block steps (issue 12). The error of that quantisation is shared too: the same over a block, it
jumps at the block's edge - 4x4 and 8x8 squares on a diffuse sphere. Two things shrink them.
Dithered membership (DITHER, choose_blocks): a receiver within two pixels of its square's edge
may join the neighbouring block of its level (a hash of pixel and pass; only into an existing
block whose cone holds its normal and within GUEST_REACH of its radius), and the ball keeps its
square's radius, so a block's edge is a ragged band rather than a line. One pass, demo close-up
96 x 96, M 16, grid aligned: across / inside 4.77 / 3.24% (ratio 1.48; square blocks 2.55,
Classic M 16 1.10), error against Classic M 32 7.1% per pixel and 5.2% 4x4-pooled (square 7.3
/ 6.6%, Classic M 16 7.8 / 4.4%); frame 124 ms against 121 (128 x 128, M 24: 299 against 276
ms, +8%). One pixel's reach gave 1.6-1.9; letting guests make new blocks or grow the ball cost
1.2-1.35x the frame. So one pass keeps weaker steps. And each pass moves the
block grid by a (dx, dy) in [0, 2^L)^2 (grid_offset: the pass's point of the
R2 sequence), so the mean of passes (the viewer's idle passes,
``render --passes``) has its edges in different places and the steps average away; the grid
no longer follows the Z-order, so a block is any set of receivers and the merge of a chunk
dispatches over the range its blocks span. Free: no extra walk. Measured on the demo close-up
(96 x 96, diffuse 0.6, llvmpipe; tests/support/block_steps.py: mean adjacent-pixel
difference across / inside the blocks of the render's own grid, in % of the mean radiance;
error against Classic at M = 32 with as many passes):

====================================  ======  ==================  =====  ===========
variant (M = 16)                      passes  across / inside     ratio  rmse / 4x4
====================================  ======  ==================  =====  ===========
Classic                               1       3.95 / 3.58         1.10   7.8 / 4.4%
Hybrid, grid aligned (before)         1       5.76 / 2.26         2.55   7.4 / 6.6%
Hybrid, grid offset                   1       6.59 / 2.23         2.96   8.3 / 6.7%
Hybrid, grid aligned + dither         1       4.77 / 3.24         1.48   7.1 / 5.2%
Classic                               4       3.36 / 2.94         1.14   6.9 / 4.2%
Hybrid, grid aligned (before)         4       5.41 / 2.10         2.57   6.4 / 6.0%
Hybrid, grid offset                   4       2.47 / 2.34         1.06   4.7 / 3.3%
====================================  ======  ==================  =====  ===========

(The helper that built it drew the offsets at random; they are now the R2 sequence, pass 0
aligned.) With random offsets the mean of few passes varied: over 8 sets of 4 at 64 x 64
the worst ratio over every phase of the 4 x 4 grid was 1.2-1.55 (aligned 1.9, Classic 1.2) and
the 4x4-pooled error 2.8-4.3% (aligned 5.8%, Classic 3.0%); at 96 x 96 2 passes give 1.8, 8
passes 1.3. Frame time unchanged (11 interleaved frames: median 302 ms vs 304 ms aligned).
Tried and dropped: tilting each block's frame by a random angle up to one micro-pixel per pass
(a stand-in for the random azimuth the gather's frame could not express then): blocks become
independent, one pass gets worse (ratio 2.86), 4 passes 1.84;
with the offset no better than the offset alone. Looking the block buffer up through each
receiver's own frame instead of copying it: a second quantisation on top (ratio 4.8, error
8.9%). Leaving the far nodes brighter than 4x the scene's mean to each receiver (drawn in its
own frame): ratio 1.23, but inside differences 5.2%, error 11.5% and the frame 75% slower.
Glossy (the lobe buffer is never shared, app/pbgi/lobe.py): a plastic at roughness 0.3 keeps
the steps of its diffuse part, ratio 1.46 in one pass, and with 4 passes 1.19 (aligned 1.63)
and a 4x4-pooled error of 3.5% (aligned 5.1%, Classic 3.5%); a gold metal at roughness 0.3
renders as in Classic (no step).

Block levels (app/pbgi/block_levels.py; ``level_fit``). What one pass still shows is each
block's own quantisation error. Per block the far field's irradiance at its centre is gathered
from its micro-buffer, divided by the room cube map's irradiance for its normal (smooth), and
fitted over its neighbours linearly in the normal: fit / own is the block's level, by which the
gather scales the entries the merge copied from the block (MB_FAR_BIT). The error then is the
neighbourhood's mean, smooth from block to block. Demo, diffuse, one pass, against Classic at
M = 32: 96 x 96 close-up at M 16, across / inside 3.19 / 2.44% (ratio 1.31; without 4.77 /
3.24, 1.48), error 4.4% per pixel and 2.4% 4x4-pooled (without 7.1 / 5.2%, Classic M 16 7.8 /
4.4%); 128 x 128 whole view at M 24, 3.4 / 1.8% (without 4.7 / 3.1%, Classic M 24 4.5 / 1.3%).
The cost: three small gathers per block and a least-squares fit on the CPU, about 3% of the
frame (256 x 256: 24-25 of ~720 ms, the third gather 2-3 of them), plus the cube map once per
room and asset position (~1 s).

The ratio is taken over the share of the hemisphere the block's far field holds (``COVERAGE``,
LEVEL_COVERAGE): far irradiance / (the cube map's irradiance x that share), the share from a
third gather of the block's buffer with every held entry white. Without it the ratio also held
how much of the hemisphere was far: near a close surface (a sphere's underside over the floor)
that share falls with the height above it, the fit's neighbours sit at other heights, and in
a room of one colour levels came out up to 1.12 away from 1 (96 x 96, M 16) and moved with
the block grid from pass to pass - 3.7% per-pass spread (median) in the sphere's lowest fifth
against Classic's 0.2% (192 x 192, M 24, 8 passes). With it those levels are 1 to 1e-6
(tests/pbgi/test_block_levels.py), that spread is 0.2%, and with the scan's colours it is
4.1 -> 0.9% (the rest of the sphere 1.0% either way; tests/pbgi/make_level_share_figure.py).
Against Mitsuba, `balanced` on the demo close-up at 256 x 256 (4x4-pooled, reference noise
2.1% included): diffuse one pass 3.77 -> 3.53%, four 3.45 -> 3.40%; rough metal 0.6 4.84 ->
4.76%, 3.65 -> 3.61%; FLIP 0.074 -> 0.066, 0.065 -> 0.061.

Turned frames (issue 12). Classic's receivers turn their micro-buffer frames about the normal by
a random angle per pixel and pass (lib/microbuffer.glsl: mb_frame), which makes their
quantisation noise. A block turns too, by one angle per block and pass: the far walk, the near
walks and the gather take it from the row's record (ShareRow.seed, Frame.seed; a receiver
without a block has its own pixel's turn). The seed is the block's square (square_seeds), the
same for a layer's tiles and for one render of the layer. Seeding by the block's axis was tried
first: every block of a plane took one turn. Demo close-up, diffuse, M 16, one run against the
fixed frames (4x4-pooled error against Classic at M = 32): 160 x 160, single passes 3.3 ->
2.5% (mean of 8), 4 passes 2.0 -> 1.2%, 8 passes 1.8 -> 1.0% (Classic at M 16: 1.8% one pass,
1.3% four); 96 x 96 with the levels, single passes 2.8 -> 2.5% (mean of passes 0-3), block-step
ratio 1.40 -> 1.36 (mean of 8); the mean of 8 passes of a quad at 2 degrees 9% -> 2.6% off
Classic's (the fixed frames' error was the same in every pass). One pass is one draw of its
blocks' turns, so a single pass can be worse than with the fixed frames (96 x 96: 2.1-3.4%
over passes 0-7, fixed 2.6-3.2%). Frame time unchanged (256 x 256, M 24: 704-709 against
710-711 ms).

Batches (``begin_group``). A frame whose receivers do not fit one batch (the memory budget, or
the micro-buffer image's 16384 rows: a 256 x 256 close-up holds about 50,000 receivers) is
filled batch by batch, in Z-order. Choosing the blocks per batch made each batch edge a straight
block edge that no receiver could be dithered across, with levels fitted from one side: a seam
along the Z-order's split. On the demo close-up at 256 x 256 it was a vertical line down the
middle of the sphere: the mean relative difference of horizontally adjacent pixels across that
column was 2.2% (diffuse; rough metal 0.6: 2.6%), against 0.7% (1.0%) between columns inside
the blocks and 1.0% (1.4%) across the other block edges; now 1.3% (1.6%), like any block edge.
So the blocks are chosen once for the whole group of receivers, and each batch walks the blocks
its receivers take - and, for their levels, the blocks within the fit's reach of those
(block_levels.REACH x their side) whose irradiance no earlier batch gave; a block's level is
then fitted over the neighbours a single batch would give it. A block a later batch takes too
(a margin block, or one whose receivers the split divides) keeps its walked micro-buffer row
for it (``_Group.carry``, a few hundred rows of entries(M) texels on the CPU), so no block is
walked twice. The image no longer depends on the batches (to float rounding:
tests/pbgi/test_pbgi_farfield.py), and the frame walks as many blocks as before (256 x 256:
1156 against 1159, 512 x 512: 3460 against 3471 - before, a block the split divided was two);
without the carry, walking the margin again cost 10-15% of a 256 x 256 frame.

Layers (``Frame.layer``). The viewer refines its layer in tiles (app/ui/refine.py), each a
render call of its own, so a tile was a group of its own: its blocks ended at its edges, and one
pass showed the tile grid as lines (demo close-up 96 x 96, M 16, cells of 16: across / inside
the cell edges 1.74, against 1.15 in one render of the layer; 256 x 256, M 24, cells of 32:
1.83 against 1.34). A tile that names its layer is a batch of the layer's group instead: the
Relighter rasterises the layer's G-buffer once per pass and hands each tile its rows of it, and
the blocks are chosen over the whole layer at its first tile and kept (``_Group.key``: the
layer's view and its receivers' geometry - not their materials, which the viewer may edit in
the middle of a pass and refine on) until every receiver of the layer has been filled
(``pending``, ``left``); a later tile whose receivers were filled already (the same view begun
again) begins the group anew. The tiles then add up to one render of the layer, to
float rounding (tests/ui/test_ui_refine.py), at the cost of the tiles (the orbit at 900 x 520
took as long as before).

Memory: the block micro-buffers (one row of entries(M) texels per block) are most of the extra
memory; blocks are walked in chunks of at most MAX_CHUNK (fewer when the budget is small), so it
stays bounded whatever the number of blocks.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from app.material import Material
from app.pbgi.block_levels import REACH, block_levels, neighbour_pairs, screen_centres
from app.pbgi.classic import ClassicCut
from app.pbgi.gbuffer import material_table, r2_point
from app.pbgi.gpu_layout import (BLOCK_OF, CLASSIC_STATE, FRAME, FRAME_SEED_BLOCK, GATHER_OUTPUT,
                                 IMAGE, MB_ENTRY, RECEIVER, SHARE_NONE, SHARE_ROW, SSBO,
                                 dispatch_groups)
from app.pbgi.microbuffer import ENTRY_BYTES, MicroBuffers, entries
from app.pbgi.modebase import Batch, CutFigures, CutFinder
from app.pbgi.stats import ShareFigures
from app.render.programs import load_compute

NONE = SHARE_NONE
DEFAULT_TOLERANCE = 1.0       # eps, in micro-pixels
DEFAULT_MAX_LEVEL = 3         # blocks up to 8 x 8 receivers
DEFAULT_MAX_CONE = 0.1        # radians: the most a receiver's normal may differ from its block's
MIN_BLOCK = 4                 # receivers; a smaller block shares too little to pay its walk
MAX_CHUNK = 512               # blocks walked per chunk: bounds the block micro-buffers (6.4 MB at
                              # M = 32). Each chunk's far walk is a few resumed dispatches with a
                              # read-back between them; 128 took 2-3x the dispatches of one chunk
                              # per batch and 3-6% more of the frame (demo close-up, Hybrid:
                              # 128 / M 16 149-150 -> 144-145 ms, 256 / M 24 754-811 -> 723-754,
                              # 512 / M 24 2488-2512 -> 2324-2377; the same images bit for bit)
# Work-group size of the blocks' far walk (the near walk keeps gpu_layout.WORKGROUP, 64): a
# viewer tile holds a few dozen blocks, one 64-wide work group, which llvmpipe runs on one core;
# at 8 (its SIMD width) they spread over both. The layer of the 1280x800 close-up refined in
# 64 x 16 tiles: far walk 1265-1328 -> 896-934 ms, the tiles 3106-3154 -> 2410-2580 ms; whole
# frames 0-3% faster (128 / M 16, 256 and 512 / M 24); the same images bit for bit. 8 for the
# near walk too was slower (its tiles hold about a thousand receivers).
FAR_WORKGROUP = 8
# Block levels (app/pbgi/block_levels.py): the cube-map face of the room the blocks' far-field
# irradiance is divided by (pbgi.envmap_face's default, so the Relighter's one cached cube map
# serves the baseline too), and the normal spread, in micro-pixels, below which a block's
# neighbourhood is flat and keeps level 1. A group of fewer blocks than LEVEL_MIN_BLOCKS (a
# frame of 16 x 16 pixels holds 4 to 16) leaves them all at 1: its blocks have too few
# neighbours for a fit, and the gathers and the fit cost a small frame 10-20%.
LEVEL_ENV_FACE = 128
LEVEL_FLAT = 0.35
LEVEL_MIN_BLOCKS = 12
# the ratio over the share of the hemisphere the block's far field holds (the module's
# docstring, "Block levels"); False: the ratio of the two irradiances alone (as before)
LEVEL_COVERAGE = True
# a block whose far field holds less of the hemisphere than this gives its neighbours no ratio
LEVEL_MIN_COVER = 0.05
INF = 3.0e38
# GPU bytes besides the block micro-buffers: per receiver the near walk's resume state, ball and
# frame, block index and the gather's frame (and level); per block its pseudo-receiver record,
# ball and frame, the far walk's resume state and its three irradiances (the block levels).
RECEIVER_BYTES = CLASSIC_STATE.nbytes + SHARE_ROW.nbytes + BLOCK_OF.nbytes + FRAME.nbytes
BLOCK_BYTES = (RECEIVER.nbytes + SHARE_ROW.nbytes + CLASSIC_STATE.nbytes
               + 3 * GATHER_OUTPUT.nbytes)


def micro_pixel_angle(m: int) -> float:
    """Narrowest angular size of a micro-pixel: 2 / M radians (at the zenith of the disc)."""
    return 2.0 / m


# Dithered membership: per level, how far (pixels) a receiver's coordinates are moved at random
# before its block is chosen, so receivers near an edge join the neighbouring block by chance
# (module docstring, "Block steps"). 2x2 blocks are too small for it.
DITHER = {2: 2, 3: 2}
# ... and only where it lies within GUEST_REACH x the block's own radius of its centre: a pixel
# away can be far in the scene (a surface seen at a grazing angle), and the ball keeps the
# square's radius, so a guest sees the far field up to GUEST_REACH x the parallax tolerance off.
GUEST_REACH = 3.0


def _sum3(inv: np.ndarray, v: np.ndarray, k: int) -> np.ndarray:
    """Per group 0 .. k-1 of ``inv``, the sum of the rows of v (n, 3)."""
    return np.stack([np.bincount(inv, v[:, j], k) for j in range(3)], 1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-30)


def _norm(v: np.ndarray) -> np.ndarray:
    """Row lengths of v (n, 3), without np.linalg.norm's generic reduction."""
    return np.sqrt(np.einsum("ij,ij->i", v, v))


def _groups(key: np.ndarray, span: int):
    """np.unique(key, return_inverse=True, return_counts=True) for keys in [0, span), by a
    count per possible key instead of a sort: the keys here are squares of the image, so span
    is about the receivers' number, and the sort was most of choose_blocks' time."""
    if span > 8 * len(key) + 4096:       # sparse: the sort is cheaper than the table
        return np.unique(key, return_inverse=True, return_counts=True)
    counts = np.bincount(key, minlength=span)
    present = np.flatnonzero(counts)
    slot = np.zeros(span, np.int64)
    slot[present] = np.arange(len(present))
    return present, slot[key], counts[present]


def choose_blocks(pixels: np.ndarray, positions: np.ndarray, normals: np.ndarray, width: int,
                  m: int, tolerance: float, max_level: int = DEFAULT_MAX_LEVEL,
                  max_cone: float = DEFAULT_MAX_CONE, min_block: int = MIN_BLOCK,
                  offset=(0, 0), dither: bool = False, seed_origin=(0, 0)) -> dict:
    """Per receiver, the coarsest usable block (see the module docstring).

    ``offset`` (dx, dy) >= 0 shifts the block grid: the blocks are the aligned squares of pixel
    (x + dx, y + dy); with an offset a block is no longer a run of the Z-order, and blocks are
    numbered in the order of their first receiver. ``dither``: each receiver's pixel is moved by
    up to DITHER[level] pixels at random (a hash of the pixel and the offset) before its block at
    that level is chosen, so a block's edge is a random band, not a line.
    Returns block_of (n,) uint32 (NONE: walks alone), and per block: centre (B, 3), axis (B, 3),
    radius D of its ball (B,), rho (B,) the receivers' largest distance from the centre (of its
    square, guests left out), level (B,), size (B,) receivers, first (B,) and last (B,)
    receiver, seed (B,) its frame's turn (square_seeds; ``seed_origin``: the pixels' origin in
    the image).
    """
    n = len(pixels)
    block_of = np.full(n, NONE, np.uint32)
    empty = {"block_of": block_of, "centre": np.zeros((0, 3)), "axis": np.zeros((0, 3)),
             "ball": np.zeros(0), "rho": np.zeros(0), "level": np.zeros(0, np.int64),
             "size": np.zeros(0, np.int64),
             "first": np.zeros(0, np.int64), "last": np.zeros(0, np.int64),
             "seed": np.zeros(0, np.uint32)}
    if n == 0 or tolerance <= 0 or max_level < 1:
        return empty
    tol = tolerance * micro_pixel_angle(m)
    px = np.asarray(pixels, np.int64)
    x, y = px % width + int(offset[0]), px // width + int(offset[1])
    stride = width + int(offset[0]) + 1
    p = np.asarray(positions, np.float64)
    nrm = np.asarray(normals, np.float64)
    chosen_level = np.zeros(n, np.int64)
    chosen_key = np.full(n, -1, np.int64)
    guest = np.zeros(n, bool)           # dithered into a neighbour's block
    if dither:                          # a hash of the pixel and the pass's grid offset
        h = (px * 2654435761 + int(offset[0]) * 40503 + int(offset[1]) * 9973) & 0xFFFFFFFF
        h = (h ^ (h >> 15)) * 2246822519 & 0xFFFFFFFF
        h ^= h >> 13
    # the squares; with the dither every coordinate moves by a whole largest block (the grid
    # stays where it was, and no coordinate of a dithered pixel x - j .. x + j is negative)
    reach = (1 << max_level) if dither else 0       # a whole block: the grid stays aligned
    x, y, stride = x + reach, y + reach, stride + 2 * reach
    rows = int(y.max()) + 1
    spans = [((rows - 1 >> level) + 1) * stride for level in range(max_level + 1)]
    for level in range(1, max_level + 1):
        key = (y >> level) * stride + (x >> level)
        uniq, inv, cnt = _groups(key, spans[level])
        k = len(uniq)
        a = _unit(_sum3(inv, nrm, k))
        # the widest normal's angle from the axis: the least cosine (arccos is decreasing)
        least = np.ones(k)
        np.minimum.at(least, inv, np.einsum("ij,ij->i", nrm, a[inv]))
        ok = (least >= np.cos(max_cone)) & (cnt >= min_block)
        take = ok[inv]
        chosen_level[take] = level
        chosen_key[take] = key[take]
    # dithered membership: a receiver near its square's edge joins the neighbouring square of
    # its own level when that one is a block of that level too (never a new block: each costs a
    # far walk) and its normal lies within that block's cone
    for level, jd in (DITHER.items() if dither else ()):
        at = np.flatnonzero(chosen_level == level)
        if jd <= 0 or level > max_level or not len(at):
            continue
        xl = x[at] - jd + ((h[at] >> 3 * level) % (2 * jd + 1)).astype(np.int64)
        yl = y[at] - jd + ((h[at] >> (3 * level + 12)) % (2 * jd + 1)).astype(np.int64)
        dk = (yl >> level) * stride + (xl >> level)
        keys, kinv, _ = _groups(chosen_key[at], spans[level])
        nk = len(keys)
        ax = _unit(_sum3(kinv, nrm[at], nk))
        ce = _sum3(kinv, p[at], nk) / np.bincount(kinv, minlength=nk)[:, None]
        rk = np.zeros(nk)
        np.maximum.at(rk, kinv, _norm(p[at] - ce[kinv]))
        slot = np.minimum(np.searchsorted(keys, dk), nk - 1)
        move = ((dk != chosen_key[at]) & (keys[slot] == dk)       # a block of this level,
                & (np.einsum("ij,ij->i", nrm[at], ax[slot]) >= np.cos(max_cone))   # in its cone
                & (_norm(p[at] - ce[slot]) <= GUEST_REACH * rk[slot]))
        chosen_key[at[move]] = dk[move]
        guest[at[move]] = True
    shared = chosen_key >= 0
    if not shared.any():
        return empty
    # blocks numbered in the order of their first receiver
    # a block's code: its key among its level's squares, the levels one after another
    base = np.concatenate([[0], np.cumsum(spans)])
    code = base[chosen_level] + chosen_key
    idx = np.flatnonzero(shared)
    _, inv, _ = _groups(code[idx], int(base[-1]))
    first_pos = np.full(int(inv.max()) + 1, len(idx), np.int64)
    np.minimum.at(first_pos, inv, np.arange(len(idx)))
    order = np.argsort(idx[first_pos], kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    bid = rank[inv]
    nb = len(order)
    block_of[idx] = bid.astype(np.uint32)
    cnt = np.bincount(bid, minlength=nb)
    c = _sum3(bid, p[idx], nb) / cnt[:, None]
    a = _unit(_sum3(bid, nrm[idx], nb))
    # the ball's radius from the block's own square: a guest dithered in from a neighbour sees
    # the far field up to GUEST_REACH x the parallax tolerance off, but the ball, hence the near
    # field every receiver walks, stays that of a square block (with the guests: 1.35x the frame)
    rho = np.zeros(nb)
    dist = _norm(p[idx] - c[bid])
    np.maximum.at(rho, bid, np.where(guest[idx], 0.0, dist))
    lone = rho <= 0.0                   # only guests: their own extent
    if lone.any():
        np.maximum.at(rho, bid, np.where(lone[bid], dist, 0.0))
    first = np.full(nb, n, np.int64)
    np.minimum.at(first, bid, idx)
    last = np.zeros(nb, np.int64)
    np.maximum.at(last, bid, idx)
    level = np.zeros(nb, np.int64)
    level[bid] = chosen_level[idx]
    square = np.zeros(nb, np.int64)
    square[bid] = chosen_key[idx]
    rho = np.maximum(rho, 1e-9)
    return {"block_of": block_of, "centre": c, "axis": a, "ball": rho / tol, "rho": rho,
            "level": level, "size": cnt, "first": first, "last": last,
            "seed": square_seeds(level, square % stride, square // stride, seed_origin)}


def grid_offset(pass_index: int, max_level: int = DEFAULT_MAX_LEVEL) -> tuple[int, int]:
    """The block grid's offset (dx, dy) for a pass, each in [0, 2^max_level): the pass's point
    of the R2 sequence, (0, 0) for pass 0 - well spread over the passes, the same for every
    batch and tile of a pass and for the same scene anywhere (a render is repeatable, and
    moving the whole scene by a million metres does not move its blocks). The mean of passes
    then has its block edges in different places and averages the steps away."""
    side = 1 << int(max_level)
    u, v = r2_point(int(pass_index))
    return int(u * side), int(v * side)


def square_seeds(level: np.ndarray, sx: np.ndarray, sy: np.ndarray,
                 origin=(0, 0)) -> np.ndarray:
    """The frame seeds (ShareRow.seed, Frame.seed) of blocks on squares (sx, sy) of their
    ``level``'s grid: each block's micro-buffer frame turns about its axis by its own angle per
    pass (lib/microbuffer.glsl: mb_frame_shared), so neighbouring blocks quantise their far
    field differently and the passes average that error, as Classic's receivers do. Why the
    square: it is what the block is, whatever the order of the receivers it was chosen from
    (a layer's tiles and one render of the layer number their blocks differently, and must
    turn them alike) - not the block's axis, which every block of a plane shares (tried: a wall
    or a floor took one turn for all its blocks, README "Frames turned per receiver").
    ``origin`` (x0, y0): the image pixel of the grid's pixel 0. A tile rendered as a group of
    its own has squares counted from its corner, and without its origin every such tile would
    repeat the same turns, a pattern with the tiles' period."""
    # (level, sx, sy) packed into 30 bits, distinct for every square of an image up to 16384
    # pixels wide (a square at level >= 1 is at most 8200 away from the grid's corner), then
    # XORed with the origin's hash: the same bijection for every square of one grid
    body = ((np.asarray(level, np.int64) - 1 & 3) << 28 | (np.asarray(sy, np.int64) & 0x3FFF) << 14
            | (np.asarray(sx, np.int64) & 0x3FFF))
    tile = (int(origin[0]) * 0x27D4EB2F ^ int(origin[1]) * 0x165667B1) & 0x7FFFFFFF
    return ((body ^ tile) & 0x7FFFFFFF | FRAME_SEED_BLOCK).astype(np.uint32)


@dataclass
class _Group:
    """The blocks of one group of receivers (FarFieldShare.begin_group), chosen over all of it;
    each batch walks the part it needs (batch_blocks). The group's receivers are its rows
    0 .. count - 1: a frame's receivers, or a whole layer's, whose tiles are render calls of
    their own (``key``: what the blocks were chosen for; see "Layers" in the module docstring)."""
    key: tuple | None                 # the layer's key and M, or None: the blocks of one frame
    m: int
    blocks: dict                      # choose_blocks over the group (receiver rows from 0)
    xy: np.ndarray                    # (B, 2) screen centres of the blocks
    count_of: np.ndarray              # (B,) their receivers
    normal: np.ndarray                # (count, 3) the receivers' normals
    ms: float                         # seconds choosing them (reported by the first batch)
    _pairs: tuple | None = None
    before_cut: bool = False          # chosen in begin_group: outside the cut's timer
    ratio: np.ndarray = field(init=False)   # (B, 3) the walked blocks' E_b / E_env (remember)
    ok: np.ndarray = field(init=False)      # (B,) their far walk completed, irradiances > 0
    known: np.ndarray = field(init=False)   # (B,) walked by an earlier batch of the group
    pending: np.ndarray = field(init=False)  # (count,) receivers no batch has filled yet
    left: np.ndarray = field(init=False)    # (B,) per block, its receivers still pending
    # walked by an earlier batch and taken by a later one: group block -> (its micro-buffer row
    # (E, 2) MB_ENTRY words, its far walk completed), so that no block is walked twice
    carry: dict = field(default_factory=dict)

    def __post_init__(self):
        nb = len(self.blocks["ball"])
        self.ratio, self.ok, self.known = np.ones((nb, 3)), np.zeros(nb, bool), np.zeros(nb, bool)
        self.pending = np.ones(len(self.normal), bool)
        self.left = self.taken(np.arange(len(self.normal)))

    @property
    def count(self) -> int:
        return len(self.normal)

    def taken(self, rows: np.ndarray) -> np.ndarray:
        """(B,) how many of receivers ``rows`` each block takes."""
        mine = self.blocks["block_of"][rows]
        return np.bincount(mine[mine != NONE].astype(np.int64),
                           minlength=len(self.blocks["ball"]))

    def batch_blocks(self, rows: np.ndarray,
                     levelled: bool) -> tuple[dict, np.ndarray, np.ndarray, int]:
        """What the batch of receivers ``rows`` (group rows, none filled yet) merges, walks and
        fits.

        Returns (blocks, ids, fit, carried). ``ids``: the group indices of the batch's blocks,
        the first ``carried`` of them kept from an earlier batch's walk (``carry``), the rest
        walked now; ``blocks``: those blocks as choose_blocks returns them for the batch,
        numbered by their place in ``ids`` (block_of per batch receiver; first / last: the
        batch receivers of each block, count / -1 for a block none of them takes). ``fit``: the
        blocks whose irradiance the levels are fitted over. The batch needs the blocks its
        receivers take; with ``levelled`` also every block within reach of those whose
        irradiance no earlier batch gave (``remember``): block_levels.block_levels fits each
        block over its neighbours within REACH x its side, so with all of them in ``fit`` a
        block's level is the one a single batch would give it, whichever batch walks it."""
        g = self.blocks
        nb_group = len(g["ball"])
        count = len(rows)
        mine = g["block_of"][rows]
        has = mine != NONE
        if count == self.count:
            walk = fit = np.arange(nb_group)
        else:
            walk = fit = np.unique(mine[has]).astype(np.int64)
            if levelled and len(walk):
                a, b = self.pairs()
                fit = np.union1d(walk, b[np.isin(a, walk)])
                walk = np.union1d(walk, fit[~self.known[fit]])
        kept = np.array(sorted(self.carry), np.int64)
        kept = kept[np.isin(kept, walk)]
        ids = np.concatenate([kept, walk[~np.isin(walk, kept)]])
        local = np.full(max(nb_group, 1), NONE, np.uint32)
        local[ids] = np.arange(len(ids), dtype=np.uint32)
        block_of = np.full(count, NONE, np.uint32)
        block_of[has] = local[mine[has]]
        out = {k: g[k][ids] for k in ("centre", "axis", "ball", "rho", "level", "size",
                                      "seed")}
        at = np.flatnonzero(has)
        out["first"] = np.full(len(ids), count, np.int64)
        np.minimum.at(out["first"], block_of[at].astype(np.int64), at)
        out["last"] = np.full(len(ids), -1, np.int64)
        np.maximum.at(out["last"], block_of[at].astype(np.int64), at)
        out["block_of"] = block_of
        return out, ids, fit, len(kept)

    def later(self, ids: np.ndarray, mine: np.ndarray) -> np.ndarray:
        """Which of the blocks ``ids`` a receiver outside the batch that takes ``mine`` of
        each (and not filled yet) takes too: a walk of theirs is worth keeping (``carry``)."""
        return self.left[ids] > mine

    def filled(self, rows: np.ndarray) -> None:
        """Receivers ``rows`` are filled: their blocks wait for that many fewer."""
        rows = rows[self.pending[rows]]
        self.left -= self.taken(rows)
        self.pending[rows] = False

    def remember(self, walk: np.ndarray, ratio: np.ndarray, ok: np.ndarray) -> None:
        """The walked blocks' ratio E_b / E_env(n_b) and whether their level may move."""
        self.ratio[walk], self.ok[walk], self.known[walk] = ratio, ok, True

    def levels(self, walk: np.ndarray, fit: np.ndarray, flat: float) -> np.ndarray:
        """The walked blocks' levels (len(walk), 3), fitted over ``fit`` (all remembered)."""
        g = self.blocks
        lv = block_levels(self.ratio[fit], g["axis"][fit], g["centre"][fit], g["rho"][fit],
                          2.0 ** g["level"][fit], self.xy[fit], self.count_of[fit], flat=flat)
        lv[~self.ok[fit]] = 1.0
        return lv[np.searchsorted(fit, walk)]

    def pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """The group's ordered pairs of blocks (a, b), b within a's fitting reach on screen."""
        if self._pairs is None:
            self._pairs = neighbour_pairs(self.xy, REACH * 2.0 ** self.blocks["level"])
        return self._pairs


class FarFieldShare(CutFinder):
    """The cut finder (app/pbgi/modebase.py) that fills a batch's micro-buffers with far-field
    sharing; it reads the batch's tile width and budget."""

    clears_microbuffers = True        # fill writes every entry: the renderer need not empty them

    def __init__(self, ctx, tolerance: float = DEFAULT_TOLERANCE,
                 max_level: int = DEFAULT_MAX_LEVEL, max_cone: float = DEFAULT_MAX_CONE,
                 share_fraction: float = 0.25, stop_factor: float = 4.0,
                 defines: dict | None = None):
        if not tolerance > 0:
            raise ValueError(f"parallax tolerance must be > 0, got {tolerance!r}")
        self.ctx = ctx
        self.tolerance, self.max_level = float(tolerance), int(max_level)
        self.max_cone = float(max_cone)
        self.share_fraction = float(share_fraction)
        self.far = ClassicCut(ctx, stop_factor=stop_factor,
                              defines={"SHARE_SPLIT": 1, **(defines or {})},
                              workgroup=FAR_WORKGROUP)
        self.near = ClassicCut(ctx, stop_factor=stop_factor,
                               defines={"SHARE_SPLIT": 2, **(defines or {})})
        self.merge = load_compute(ctx, "pbgi_share_merge.glsl")
        self.block_mb = MicroBuffers(ctx)
        self.offset = (0, 0)          # the last batch's block-grid offset (grid_offset)
        self.dither = True            # dithered block membership (DITHER); False: square blocks
        self._merge_s = 0.0           # seconds of the batch's copies (_merge), so far
        self.level_fit = True         # block levels (app/pbgi/block_levels.py); False: all 1
        # the last batch's blocks (choose_blocks), their E / pi and levels (tests, debugging)
        self.last_blocks = self.last_irradiance = self.last_levels = None
        self._bufs = []
        self.frames = None            # per batch receiver: its micro-buffer's frame normal
        self._group = None            # the blocks of the group being filled (begin_group)
        self._span = None             # (first, rows): the frame's receivers first .. in it

    def bytes_per_receiver(self, m: int) -> int:
        """What a receiver costs besides its micro-buffer, plus a quarter of a block's (blocks
        hold >= 4 receivers)."""
        return RECEIVER_BYTES + (entries(m) * ENTRY_BYTES + BLOCK_BYTES) // MIN_BLOCK

    def reserve_bytes(self, budget_bytes: float) -> int:
        return 0                      # the block buffers are chunked within the batch's share

    def _buffer(self, data: np.ndarray):
        b = self.ctx.buffer(np.ascontiguousarray(data).tobytes())
        self._bufs.append(b)
        return b

    def _merge(self, mb, block_buf, r0: int, r1: int, b0: int, b1: int, clear: bool = False,
               source=None):
        """Receivers [r0, r1) of the batch: copy blocks [b0, b1)'s buffers (rows 0 .. of
        ``source``, default the block micro-buffers) into theirs (the shader skips receivers of
        other blocks), or (``clear``) empty the rows of those without a block."""
        block_buf.bind_to_storage_buffer(SSBO.BLOCK_OF)
        mb.bind()
        if source is not None:
            source.bind_to_image(IMAGE.SHARE_SOURCE, read=True, write=False)
        elif self.block_mb.image is not None:
            self.block_mb.image.bind_to_image(IMAGE.SHARE_SOURCE, read=True, write=False)
        else:       # no block at all: the shader still needs an image on that unit
            mb.image.bind_to_image(IMAGE.SHARE_SOURCE, read=True, write=False)
        pr = self.merge
        pr["u_begin"], pr["u_end"] = r0, r1
        pr["u_block0"], pr["u_block1"] = b0, b1
        pr["u_clear_unshared"] = bool(clear)
        self.ctx.finish()             # timed apart (ShareFigures.ms_share_merge)
        t = time.perf_counter()
        pr.run(dispatch_groups(r1 - r0))
        self.ctx.memory_barrier()
        self.ctx.finish()
        self._merge_s += time.perf_counter() - t

    def begin_group(self, frame, first: int, count: int, m: int) -> None:
        """(CutFinder) The group's blocks, chosen once over all its receivers (see "Batches"
        in the module docstring) - or over the whole layer of a tile (``frame.layer``), kept
        for the layer's next tiles (see "Layers")."""
        layer = frame.layer
        if layer is None:
            self._choose(frame.receivers, first, count, m, frame.tile[2], frame.pass_index,
                         frame.tile[:2])
            self._group.before_cut = True
            return
        rows = layer.rows[first:first + count]
        tag, members = layer.group_of(rows)
        key = (layer.key, m, tag)
        g = self._group
        grow = np.searchsorted(members, rows)
        if g is None or g.key != key or not g.pending[grow].all():   # new, or done again
            t0 = time.perf_counter()
            rec = layer.receivers[members]
            self._group = g = self._new_group(key, rec, m, layer.width, frame.pass_index,
                                              t0, (0, 0))   # one group for all the tiles
            g.before_cut = True
        self._span = (first, grow)

    def _choose(self, receivers, first: int, count: int, m: int, width: int,
                pass_index: int, origin) -> None:
        """Blocks over the frame's receivers ``first`` .. ``first + count - 1`` alone, of the
        tile at ``origin`` (x0, y0) of the image."""
        t0 = time.perf_counter()
        rec = RECEIVER.view(receivers.read(size=RECEIVER.nbytes * count,
                                           offset=RECEIVER.nbytes * first))
        self._group = self._new_group(None, rec, m, width, pass_index, t0, origin)
        self._span = (first, np.arange(count))

    def _new_group(self, key, rec: np.ndarray, m: int, width: int, pass_index: int,
                   t0: float, origin) -> _Group:
        """``origin``: where the receivers' pixel 0 lies in the image, so that tiles rendered
        as groups of their own seed their blocks' frames differently (square_seeds)."""
        self.offset = grid_offset(pass_index, self.max_level)
        blocks = choose_blocks(rec["pixel"], rec["position"], rec["normal"], width, m,
                               self.tolerance, self.max_level, self.max_cone, offset=self.offset,
                               dither=self.dither, seed_origin=origin)
        xy, cnt = screen_centres(rec["pixel"], blocks["block_of"], len(blocks["ball"]), width)
        return _Group(key, m, blocks, xy, cnt, rec["normal"].copy(), time.perf_counter() - t0)

    def fill(self, batch: Batch) -> CutFigures:
        ctx = self.ctx
        mb, receivers, first, count, m = (batch.microbuffers, batch.receivers, batch.first,
                                          batch.count, batch.m)
        nodes, cell_size, width, budget_bytes = (batch.nodes, batch.cell_size, batch.width,
                                                 batch.budget_bytes)
        t0 = time.perf_counter()
        g, grp = self._group, None
        if g is not None and g.m == m and self._span is not None:
            f0, grow = self._span
            if f0 <= first and first + count <= f0 + len(grow):
                grp = grow[first - f0:first - f0 + count]
        if grp is None:                       # not in the group begun: a group of its own
            self._choose(receivers, first, count, m, width, batch.pass_index,
                         batch.seed_tile[:2])
            g, grp = self._group, self._span[1]
        t_choose, g.ms = g.ms, 0.0            # counted once, in the group's first batch
        t_before = t_choose if g.before_cut else 0.0
        levelled = (len(g.blocks["ball"]) >= LEVEL_MIN_BLOCKS and self.level_fit
                    and batch.environment is not None and batch.gather is not None)
        blocks, ids, fit, nc = g.batch_blocks(grp, levelled)
        nb = len(ids)                 # blocks 0 .. nc - 1 kept from earlier batches (carry)
        block_of = blocks["block_of"]
        mine = np.bincount(block_of[block_of != NONE].astype(np.int64), minlength=nb)
        t1 = time.perf_counter()
        row_bytes = entries(m) * ENTRY_BYTES
        cap = int(max(1, min(nb - nc, self.share_fraction * budget_bytes // row_bytes, MAX_CHUNK,
                             int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 16384)))))
        far_visited = np.zeros(max(nb, 1), np.int64)
        far_done = np.ones(max(nb, 1), bool)
        far_done[:nc] = [g.carry[b][1] for b in ids[:nc]]
        rounds = chunks = 0
        peak_bytes = 0
        t_lv = 0.0                    # the block levels' share of the chunk loop
        self._merge_s = 0.0           # the copies' share of it (_merge)
        env_bytes = 0                 # the room's cube map (the Relighter's, shared)
        try:
            block_buf = self._buffer(block_of)
            self._merge(mb, block_buf, 0, count, NONE, NONE, clear=True)
            if nc:                    # the blocks an earlier batch walked for this one
                kept = np.stack([g.carry[b][0] for b in ids[:nc]])
                tex = ctx.texture((entries(m), nc), MB_ENTRY.texel_components, kept.tobytes(),
                                  dtype=MB_ENTRY.texture_dtype)
                self._bufs.append(tex)
                self._merge(mb, block_buf, int(blocks["first"][:nc].min()),
                            int(blocks["last"][:nc].max()) + 1, 0, nc, source=tex)
            if nb > nc:
                pseudo = RECEIVER.zeros(nb)     # a block walks as one receiver at its centre
                pseudo["position"] = blocks["centre"]
                pseudo["normal"] = blocks["axis"]
                pseudo["pixel"] = np.arange(nb)   # its irradiance's slot in the gather output
                pseudo_buf = self._buffer(pseudo)
                if levelled:
                    white = self._buffer(material_table([Material()]))
                    far_e = self._buffer(GATHER_OUTPUT.zeros(nb))
                    cov_e = self._buffer(GATHER_OUTPUT.zeros(nb))
                    env_e = self._buffer(GATHER_OUTPUT.zeros(nb))
                balls = SHARE_ROW.zeros(nb)
                balls["center"] = blocks["centre"]
                balls["ball"] = blocks["ball"]
                balls["frame"] = blocks["axis"]
                balls["seed"] = blocks["seed"]
                for b0 in range(nc, nb, cap):
                    b1 = min(nb, b0 + cap)
                    chunks += 1
                    self.block_mb.prepare(m, cap, b1 - b0)
                    ball_buf = self._buffer(balls[b0:b1])
                    res = self.far.fill(Batch(self.block_mb, pseudo_buf, b0, b1 - b0, m, nodes,
                                              cell_size, pass_index=batch.pass_index,
                                              turned_frames=batch.turned_frames),
                                        share=ball_buf)
                    far_visited[b0:b1] = res.visited
                    far_done[b0:b1] = res.done
                    rounds += res.rounds
                    later = g.later(ids[b0:b1], mine[b0:b1])
                    if later.any():         # a later batch takes them: keep, not walk again
                        rows = self.block_mb.read(b1 - b0)
                        for j in np.flatnonzero(later):
                            g.carry[int(ids[b0 + j])] = (rows[j].copy(), bool(res.done[j]))
                    # copy the chunk's block buffers into its receivers' micro-buffers (a chunk
                    # of margin blocks only, walked for their neighbours' levels, has none)
                    r0 = int(blocks["first"][b0:b1].min())
                    r1 = int(blocks["last"][b0:b1].max()) + 1
                    if r1 > r0:
                        self._merge(mb, block_buf, r0, r1, b0, b1)
                    peak_bytes = max(peak_bytes, self.block_mb.nbytes)
                    if levelled:        # the far field's irradiance at the block's centre
                        # (unturned: a Lambertian gather about the buffer's own axis weighs a
                        # micro-pixel by its area alone, whatever the frame's turn)
                        tl = time.perf_counter()
                        batch.gather.run(pseudo_buf, white, far_e, b0, b1 - b0, m,
                                         np.zeros(3), mb=self.block_mb, nodes=nodes,
                                         irradiance=True, turned=False)
                        if LEVEL_COVERAGE:
                            batch.gather.run(pseudo_buf, white, cov_e, b0, b1 - b0, m,
                                             np.zeros(3), mb=self.block_mb, nodes=nodes,
                                             irradiance=True, turned=False, coverage=True)
                        t_lv += time.perf_counter() - tl
            t2 = time.perf_counter()
            levels = np.ones((nb, 3))
            if levelled and nb > nc:    # ... over the room's, seen from the asset's centre
                env = batch.environment(LEVEL_ENV_FACE)
                env_bytes = env.nbytes
                batch.gather.run(pseudo_buf, white, env_e, nc, nb - nc, m, np.zeros(3), env=env,
                                 irradiance=True)
                e = GATHER_OUTPUT.view(far_e.read())
                e_env = GATHER_OUTPUT.view(env_e.read())
                ratio = e["radiance"].astype(np.float64) / np.maximum(e_env["radiance"], 1e-30)
                if LEVEL_COVERAGE:
                    cov = GATHER_OUTPUT.view(cov_e.read())["radiance"][:, :1].astype(np.float64)
                    ratio /= np.maximum(cov, 1e-6)
                ok = far_done[:nb] & (e["status"] > 0) & (e_env["status"] > 0)
                ok &= (e_env["radiance"] > 0).all(1)
                if LEVEL_COVERAGE:
                    ok &= cov[:, 0] > LEVEL_MIN_COVER
                g.remember(ids[nc:], ratio[nc:], ok[nc:])
                self.last_irradiance = e["radiance"][nc:].copy()
            if levelled and nb:
                levels = g.levels(ids, fit, LEVEL_FLAT * micro_pixel_angle(m))
            self.last_blocks, self.last_levels = blocks, levels
            t_levels = time.perf_counter()
            near_balls = SHARE_ROW.zeros(count)
            near_balls["ball"] = INF
            near_balls["frame"] = g.normal[grp]
            has = block_of != NONE
            near_balls["center"][has] = blocks["centre"][block_of[has]]
            near_balls["ball"][has] = blocks["ball"][block_of[has]]
            near_balls["frame"][has] = blocks["axis"][block_of[has]]
            near_balls["seed"] = SHARE_NONE
            near_balls["seed"][has] = blocks["seed"][block_of[has]]
            res = self.near.fill(Batch(mb, receivers, first, count, m, nodes, cell_size,
                                       seed_tile=batch.seed_tile, pass_index=batch.pass_index,
                                       turned_frames=batch.turned_frames),
                                 share=self._buffer(near_balls))
            if self.frames is not None:
                self.frames.release()
            frames = FRAME.zeros(count)
            frames["normal"] = near_balls["frame"]
            frames["seed"] = near_balls["seed"]
            frames["level"] = 1.0
            frames["level"][has] = levels[block_of[has]]
            self.frames = ctx.buffer(frames.tobytes())
            t3 = time.perf_counter()
            for b in ids[:nc][~g.later(ids[:nc], mine[:nc])]:
                del g.carry[int(b)]           # no later batch takes it
            g.filled(grp)
            if not g.pending.any():
                self._group = self._span = None   # the group's last batch is done
        finally:
            for b in self._bufs:
                b.release()
            self._bufs = []
        done = res.done.copy()
        if nb:
            done[has] &= far_done[block_of[has]]
        bsize = blocks["size"]
        return CutFigures(
            visited=res.visited, done=done, tests=res.tests, rounds=rounds + res.rounds,
            cut_short=res.cut_short,
            nbytes=(peak_bytes + RECEIVER_BYTES * count + BLOCK_BYTES * nb + env_bytes
                    + nc * row_bytes),          # the kept blocks' rows, uploaded for the merge
            frames=self.frames,
            share=ShareFigures(
                share_blocks=nb - nc, share_chunks=chunks, share_receivers=int(has.sum()),
                share_block_visits=int(far_visited[:nb].sum()),
                ms_share_blocks=(t1 - t0 + t_choose) * 1e3,
                ms_share_chosen_before=t_before * 1e3, ms_share_far=(t2 - t1 - t_lv) * 1e3,
                ms_share_merge=self._merge_s * 1e3,
                ms_share_levels=(t_lv + t_levels - t2) * 1e3, ms_share_near=(t3 - t_levels) * 1e3,
                share_levelled=int(((levels != 1.0).any(1) & (blocks["last"] >= 0)).sum()),
                share_block_max=int(bsize.max()) if nb else 0))

    def release(self) -> None:
        for c in (self.far, self.near):
            c.release()
        self.block_mb.release()
        if self.frames is not None:
            self.frames.release()
            self.frames = None
