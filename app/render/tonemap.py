"""Display transform for PNG output and the viewer: exposure in stops, the Khronos PBR Neutral
tone mapper, sRGB encoding. GLSL twin: shaders/lib/tonemap.glsl (same formula, tested).

PBR Neutral rather than ACES: it leaves base colours below ~0.8 untouched (a look-dev viewer
must show the material's colour as authored) and only rolls highlights off to white.
"""

from __future__ import annotations

import numpy as np

from app.errors import ScanlightError

MAX_INPUT = 1e30  # cap before mapping: Inf and 1e38 would overflow the highlight formula
_START = 0.8 - 0.04
_DESAT = 0.15


def sanitize(rgb) -> np.ndarray:
    """Linear radiance made safe to map: NaN -> 0, negatives -> 0, capped at MAX_INPUT."""
    c = np.nan_to_num(np.asarray(rgb, dtype=np.float64), nan=0.0, posinf=MAX_INPUT, neginf=0.0)
    return np.clip(c, 0.0, MAX_INPUT)


def pbr_neutral(rgb) -> np.ndarray:
    """Khronos PBR Neutral tone mapper on (..., 3) non-negative linear RGB -> [0, 1)."""
    c = np.asarray(rgb, dtype=np.float64)
    x = c.min(axis=-1, keepdims=True)
    offset = np.where(x < 0.08, x - 6.25 * x * x, 0.04)
    c = c - offset
    peak = c.max(axis=-1, keepdims=True)
    d = 1.0 - _START
    new_peak = 1.0 - d * d / (peak + d - _START)
    compress = peak >= _START
    scaled = c * (new_peak / np.where(compress, peak, 1.0))
    g = 1.0 - 1.0 / (_DESAT * (peak - new_peak) + 1.0)
    return np.where(compress, scaled + (new_peak - scaled) * g, c)


def srgb_encode(linear) -> np.ndarray:
    """sRGB OETF (IEC 61966-2-1) of linear values, clamped to [0, 1]."""
    c = np.clip(np.asarray(linear, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92,
                    1.055 * np.maximum(c, 0.0031308) ** (1.0 / 2.4) - 0.055)


def tonemap(linear_rgb, exposure_stops: float = 0.0) -> np.ndarray:
    """(..., 3) linear radiance -> display-encoded sRGB float32 in [0, 1]."""
    c = sanitize(sanitize(linear_rgb) * 2.0 ** float(exposure_stops))
    return srgb_encode(pbr_neutral(c)).astype(np.float32)


def tonemap_to_srgb8(linear_rgb, exposure_stops: float = 0.0) -> np.ndarray:
    """(..., 3) or (..., 4) linear radiance -> uint8 sRGB for a PNG. Alpha (4th channel) is
    coverage, not light: it is clipped to [0, 1] and stored linearly, not tone mapped."""
    a = np.asarray(linear_rgb)
    if a.ndim < 1 or a.shape[-1] not in (3, 4):
        raise ScanlightError(None, f"tone mapping needs (..., 3) or (..., 4) colours, got shape "
                                   f"{a.shape}")
    if not np.isfinite(exposure_stops):
        raise ScanlightError(None, f"exposure must be a finite number of stops, "
                                   f"got {exposure_stops}")
    out = tonemap(a[..., :3], exposure_stops)
    if a.shape[-1] == 4:
        alpha = np.clip(np.nan_to_num(np.asarray(a[..., 3:], dtype=np.float64)), 0.0, 1.0)
        out = np.concatenate([out, alpha.astype(np.float32)], axis=-1)
    return np.round(out * 255.0).astype(np.uint8)
