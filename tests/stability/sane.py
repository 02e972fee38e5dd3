"""What every stability case asserts of a render (not a test module: imported by
tests/stability/test_*_extremes.py)."""

from __future__ import annotations

import numpy as np

from app.pbgi.renderer import RenderParams

MODES = ("classic", "mipmapped", "hybrid", "envmap")
PBGI_MODES = ("classic", "mipmapped", "hybrid")   # one gather, one node layout, one cut rule
M = 8                                             # micro-buffer size: the cheapest allowed


def params(mode: str, **kw) -> RenderParams:
    return RenderParams(mode=mode, microbuffer=M, **kw)


def assert_sane(res, case: str, min_receivers: int = 1) -> np.ndarray:
    """Finite, non-negative radiance, zero alpha off the object, a completed render with no
    non-finite pixel; returns the object pixels' RGB."""
    img, s = res.image, res.stats
    assert s.receivers >= min_receivers, (case, s.receivers)
    assert np.isfinite(img).all(), case
    assert (img[..., :3] >= 0).all(), (case, float(img[..., :3].min()))
    assert s.nonfinite_pixels == 0, (case, s.nonfinite_pixels)
    assert s.completed, (case, s.to_dict())
    cover = img[..., 3] > 0
    assert not img[~cover].any(), case              # nothing leaks off the object
    return img[..., :3][cover]
