"""Alpha compositing of premultiplied linear RGBA (the renders' convention: RGB premultiplied by
coverage, A = coverage), shared by ``render``, ``render --compare`` and ``turntable``."""

from __future__ import annotations

import numpy as np


def over(front: np.ndarray, back: np.ndarray) -> np.ndarray:
    """``front`` (premultiplied RGBA: passes average coverage) over ``back``."""
    out = front.copy()
    a = front[..., 3:4]
    out[..., :3] = front[..., :3] + back[..., :3] * (1.0 - a)
    out[..., 3] = np.maximum(front[..., 3], back[..., 3])
    return out


__all__ = ["over"]
