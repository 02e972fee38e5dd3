"""8-bit PNG output (renders, reports), written atomically; ``read_image`` re-exported so that
callers have one images module for reading any image and writing PNGs."""

from __future__ import annotations

import numpy as np

from app.io.exr import LinearImage, read_image  # noqa: F401  (re-exported)
from app.io.files import atomic_output


def write_png(path, image) -> None:
    """Write a uint8 (H, W), (H, W, 3) or (H, W, 4) array; row 0 is the top of the picture.

    Anything else is a programming error (ValueError): convert with app.color.to_uint8_srgb first.
    """
    from PIL import Image

    a = np.asarray(image)
    if a.dtype != np.uint8:
        raise ValueError(f"write_png needs uint8 pixels, got {a.dtype}")
    if not (a.ndim == 2 or (a.ndim == 3 and a.shape[2] in (1, 3, 4))) or a.size == 0:
        raise ValueError(f"write_png needs a non-empty (H, W[, 1|3|4]) array, got {a.shape}")
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[..., 0]
    with atomic_output(path) as tmp:
        Image.fromarray(np.ascontiguousarray(a)).save(tmp, format="PNG")
