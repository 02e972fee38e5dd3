"""A numpy twin of the receivers' turned micro-buffer frames (shaders/lib/microbuffer.glsl:
mb_frame, with lib/common.glsl's hash_pcg): the tests that check a micro-buffer's entries
direction by direction need the frame its cut was drawn in."""
from __future__ import annotations

import numpy as np

from app.pbgi.brdf import orthonormal_basis

_MASK = 0xFFFFFFFF


def hash_pcg(x: int) -> int:
    x = (x * 747796405 + 2891336453) & _MASK
    w = (((x >> ((x >> 28) + 4)) ^ x) * 277803737) & _MASK
    return ((w >> 22) ^ w) & _MASK


def turned_frame(normal, tile_pixel: int, seed_tile=(0, 0, 1, 1), pass_index: int = 0):
    """(T, B) of the receiver at ``tile_pixel`` of the tile ``seed_tile`` (x0, y0, tile width,
    image width) in pass ``pass_index``: orthonormal_basis(normal) turned about the normal by
    the receiver's hashed angle, (cos, sin) from tan(phi / 2) as the shader draws them."""
    t, b = orthonormal_basis(np.asarray(normal, dtype=np.float64))
    x0, y0, w, image_w = (int(v) for v in seed_tile)
    w = max(w, 1)
    pixel = ((y0 + tile_pixel // w) * image_w + x0 + tile_pixel % w) & _MASK
    h = hash_pcg((pixel * 7919 + pass_index * 104729 + 0x9E3779B9) & _MASK)
    q = np.float32(h & 0xFFFF) * np.float32(2.0 / 65535.0) - np.float32(1.0)   # tan(phi / 2)
    k = (-1.0 if h & 0x10000 else 1.0) / (1.0 + float(q) ** 2)
    c, s = (1.0 - float(q) ** 2) * k, 2.0 * float(q) * k
    return c * t + s * b, c * b - s * t
