"""Colour conventions used everywhere: sRGB transfer, CIE Y luminance."""

from __future__ import annotations

import numpy as np

# Rec.709 / sRGB primaries, CIE Y.
LUMA = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)


def srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(c):
    c = np.clip(np.asarray(c, dtype=np.float32), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055).astype(np.float32)


def luminance(rgb):
    return np.asarray(rgb, dtype=np.float32) @ LUMA


def to_uint8_srgb(linear):
    """Linear [0,1] -> 8-bit sRGB, as an LDR scanner stores colours."""
    return np.round(linear_to_srgb(linear) * 255.0).astype(np.uint8)
