"""Repair of invalid radiance values read from files (point colours, image pixels).

Real captures are not clean: resampled HDR panoramas carry negative ringing, half-float overflow
gives +Inf, broken exporters write NaN. Radiance is non-negative and must be finite for every later
sum, so the loaders repair these values and *count* them instead of failing:

- negative (including -Inf) -> 0: negative light does not exist; ringing is the usual cause;
- NaN -> 0: no information, and 0 is the value that adds no energy;
- +Inf -> HALF_MAX (65504): Inf mostly comes from half-float overflow, so the largest half is the
  best finite guess. Finite values above 65504 (possible in float files) are kept as they are,
  up to MAX_RADIANCE (app.io.limits, 1e15);
- finite values above MAX_RADIANCE -> MAX_RADIANCE: no light is that bright, and float32 sums of
  such values (a node's colour times a BRDF peak times a solid angle, the differential
  rendering's difference) overflowed to Inf and NaN in the renderer.

The counts are of items (points or pixels) with at least one repaired channel.
"""

from __future__ import annotations

import logging

import numpy as np

from app.io.limits import MAX_RADIANCE

HALF_MAX = 65504.0

log = logging.getLogger(__name__)


def clean_rgb(rgb: np.ndarray, item: str) -> tuple[np.ndarray, dict]:
    """Float32 copy of ``rgb`` (..., C) with NaN/Inf/negatives repaired, and the counts.

    ``item`` names what a row is ("colors", "pixels"); the report keys are
    ``clamped_negative_<item>``, ``clamped_nan_<item>``, ``clamped_inf_<item>`` and
    ``clamped_huge_<item>``.
    """
    rgb = np.asarray(rgb, dtype=np.float32)
    flat = rgb.reshape(-1, rgb.shape[-1]) if rgb.ndim > 1 else rgb.reshape(-1, 1)
    nan = np.isnan(flat)
    pos_inf = np.isposinf(flat)
    neg = flat < 0  # includes -Inf; NaN compares False
    huge = np.isfinite(flat) & (flat > MAX_RADIANCE)
    counts = {
        f"clamped_negative_{item}": int(neg.any(axis=1).sum()),
        f"clamped_nan_{item}": int(nan.any(axis=1).sum()),
        f"clamped_inf_{item}": int(pos_inf.any(axis=1).sum()),
        f"clamped_huge_{item}": int(huge.any(axis=1).sum()),
    }
    if any(counts.values()):
        out = np.where(nan | neg, np.float32(0.0), flat)
        out = np.where(pos_inf, np.float32(HALF_MAX), out)
        out = np.where(huge, np.float32(MAX_RADIANCE), out).astype(np.float32)
        rgb = out.reshape(rgb.shape)
    else:
        rgb = rgb.copy()
    return rgb, counts


def describe_counts(counts: dict) -> str:
    """One human line for the non-zero counts, e.g. '12 negative pixels set to 0'."""
    parts = []
    for key, n in counts.items():
        if not n:
            continue
        kind, item = key.removeprefix("clamped_").split("_", 1)
        fix = {"negative": "set to 0", "nan": "set to 0", "inf": f"set to {HALF_MAX:g}",
               "huge": f"set to {MAX_RADIANCE:g}"}[kind]
        what = {"nan": "NaN values", "huge": f"values above {MAX_RADIANCE:g}"}.get(
            kind, f"{kind} values")
        parts.append(f"{n} {item} with {what} {fix}")
    return "; ".join(parts)
