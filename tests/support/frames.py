"""A numpy twin of the receivers' turned micro-buffer frames (shaders/lib/microbuffer.glsl:
mb_frame, mb_frame_seeded and mb_frame_shared, with lib/common.glsl's hash_pcg): the tests that
check a micro-buffer's entries direction by direction need the frame its cut was drawn in."""
from __future__ import annotations

import numpy as np

from app.pbgi.brdf import orthonormal_basis
from app.pbgi.gpu_layout import SHARE_NONE

_MASK = 0xFFFFFFFF


def hash_pcg(x: int) -> int:
    x = (x * 747796405 + 2891336453) & _MASK
    w = (((x >> ((x >> 28) + 4)) ^ x) * 277803737) & _MASK
    return ((w >> 22) ^ w) & _MASK


def turned_frame(normal, tile_pixel: int, seed_tile=(0, 0, 1, 1), pass_index: int = 0):
    """(T, B) of the receiver at ``tile_pixel`` of the tile ``seed_tile`` (x0, y0, tile width,
    image width) in pass ``pass_index``: orthonormal_basis(normal) turned about the normal by
    the receiver's hashed angle, (cos, sin) from tan(phi / 2) as the shader draws them."""
    x0, y0, w, image_w = (int(v) for v in seed_tile)
    w = max(w, 1)
    pixel = ((y0 + tile_pixel // w) * image_w + x0 + tile_pixel % w) & _MASK
    return seeded_frame(normal, pixel, pass_index)


def shared_frame(normal, seed: int, tile_pixel: int, seed_tile=(0, 0, 1, 1),
                 pass_index: int = 0):
    """mb_frame_shared: the frame of a Hybrid row whose record holds ``seed`` (ShareRow.seed,
    Frame.seed): its block's turn, or with SHARE_NONE its receiver's own (turned_frame)."""
    if int(seed) == SHARE_NONE:
        return turned_frame(normal, tile_pixel, seed_tile, pass_index)
    return seeded_frame(normal, int(seed), pass_index)


def seeded_frame(normal, seed: int, pass_index: int = 0):
    """mb_frame_seeded: orthonormal_basis(normal) turned by the angle hashed from ``seed``."""
    t, b = orthonormal_basis(np.asarray(normal, dtype=np.float64))
    h = hash_pcg((int(seed) * 7919 + pass_index * 104729 + 0x9E3779B9) & _MASK)
    q = np.float32(h & 0xFFFF) * np.float32(2.0 / 65535.0) - np.float32(1.0)   # tan(phi / 2)
    k = (-1.0 if h & 0x10000 else 1.0) / (1.0 + float(q) ** 2)
    c, s = (1.0 - float(q) ** 2) * k, 2.0 * float(q) * k
    return c * t + s * b, c * b - s * t
