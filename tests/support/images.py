"""Image regression helper for the viewer's screenshot tests (see tests/ui/references/README.md).

Metric, on 8-bit sRGB images of the same size: ``mean`` = mean absolute difference over all
channels, in 8-bit steps; ``bad`` = fraction of pixels whose largest channel difference exceeds
``BAD_STEP``. Scale: mean 0 / bad 0 = identical; mean <= 0.5 and bad <= 0.2% = visually identical
(a few splat or silhouette pixels flipped); mean 2 = a visible change (an exposure change of
0.05 EV moves mid-tones by about 2 steps). A missing reference fails and writes the actual image
next to where the reference belongs (``*.actual.png``); a failed comparison also writes the
actual and a difference image. SCANLIGHT_UPDATE_REFERENCES=1 (re)writes the references instead.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

REFERENCES = Path(__file__).resolve().parent.parent / "ui" / "references"
UPDATE_ENV = "SCANLIGHT_UPDATE_REFERENCES"
MAX_MEAN = 0.5      # mean |difference| in 8-bit steps
MAX_BAD = 0.002     # fraction of pixels differing by more than BAD_STEP in some channel
BAD_STEP = 16


def read_png(path) -> np.ndarray:
    from PIL import Image
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def difference(actual: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    d = np.abs(actual.astype(np.int16) - ref.astype(np.int16))
    return float(d.mean()), float((d.max(axis=-1) > BAD_STEP).mean())


def check_reference(name: str, actual: np.ndarray, max_mean: float = MAX_MEAN,
                    max_bad: float = MAX_BAD) -> None:
    from app.io.images import write_png
    ref_path = REFERENCES / name
    if os.environ.get(UPDATE_ENV) == "1":
        write_png(ref_path, actual)
        return
    if not ref_path.is_file():
        write_png(ref_path.with_suffix(".actual.png"), actual)
        pytest.fail(f"missing reference {ref_path}; the actual image was written to "
                    f"{ref_path.with_suffix('.actual.png')} (check it, then rerun with "
                    f"{UPDATE_ENV}=1 to accept it)")
    ref = read_png(ref_path)
    if ref.shape != actual.shape:
        write_png(ref_path.with_suffix(".actual.png"), actual)
        pytest.fail(f"{name}: size {actual.shape} differs from the reference {ref.shape}")
    mean, bad = difference(actual, ref)
    if mean > max_mean or bad > max_bad:
        write_png(ref_path.with_suffix(".actual.png"), actual)
        diff = np.abs(actual.astype(np.int16) - ref.astype(np.int16)).max(axis=-1)
        write_png(ref_path.with_suffix(".diff.png"), np.clip(diff * 8, 0, 255).astype(np.uint8))
        pytest.fail(f"{name}: mean difference {mean:.3f} (max {max_mean}), {100 * bad:.3f}% "
                    f"pixels off by > {BAD_STEP} (max {100 * max_bad}%); actual and diff "
                    f"images written beside the reference")
