"""The viewer's A/B compare (issue 18): A is the current settings, B the same with one thing
changed (``compare.b``), shown left and right of a divider the user drags (``compare.split``).

What B can change, as ``render --compare`` sides do (app/commands/compare.py):

    mode      B renders with ``compare.mode``
    quality   B renders with the ``compare.quality`` preset (mode, micro-buffer, GI scale, ...)
    cloud     B is lit by the other cloud: the HDR (expanded) one where A has the LDR scan, or
              the reverse (needs an expansion result)
    hdri      B is lit by the other light: the session's HDRI where A has the scan, or the
              reverse (``light.source``); an HDRI side shows the panorama behind the asset

The engine (app/ui/engine.py) keeps a second GI layer and a second renderer for B, so neither
side's caches are thrown away by the other's renders; the composite shows each side's pixels
in its own columns (app/ui/viewport.py). The room is the same on both sides except behind an
HDRI. Pure functions here; no GL.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from app.params import QUALITY_PRESETS

LABEL_MARGIN = 6        # pixels between a side's label and the divider / the top edge


class OverriddenSettings:
    """``settings`` with some keys replaced: what B's render parameters are made from."""

    def __init__(self, settings, overrides: dict):
        self.settings, self.overrides = settings, dict(overrides)

    def __getitem__(self, key):
        return self.overrides[key] if key in self.overrides else self.settings[key]


def b_overrides(settings) -> dict:
    """The settings B changes (empty for the cloud and HDRI kinds: B changes its light)."""
    kind = settings["compare.b"]
    if kind == "mode":
        return {"pbgi.mode": settings["compare.mode"]}
    if kind == "quality":
        return dict(QUALITY_PRESETS[settings["compare.quality"]])
    return {}


def b_settings(settings) -> OverriddenSettings:
    return OverriddenSettings(settings, b_overrides(settings))


def light_name(hdri_path) -> str:
    return "scan light" if hdri_path is None else f"HDRI {Path(hdri_path).name}"


def side_names(settings, a_light, b_light, a_cloud_hdr: bool, b_cloud_hdr: bool):
    """The two labels drawn over the picture, e.g. ("A: hybrid", "B: classic"); ``*_light`` is
    the HDRI path lighting that side or None (the scan)."""
    kind = settings["compare.b"]
    if kind == "mode":
        return f"A: {settings['pbgi.mode']}", f"B: {settings['compare.mode']}"
    if kind == "quality":
        return f"A: {settings['pbgi.quality']}", f"B: {settings['compare.quality']}"
    if kind == "cloud":
        word = {False: "LDR scan", True: "HDR cloud"}
        return f"A: {word[a_cloud_hdr]}", f"B: {word[b_cloud_hdr]}"
    return f"A: {light_name(a_light)}", f"B: {light_name(b_light)}"


def split_column(split: float, width: int) -> int:
    """The divider's column: pixels x < column are A's."""
    return int(np.clip(round(float(split) * width), 0, width))


def label_rects(split_x: int, width: int, a_size, b_size):
    """Top-left (x, y, w, h) of A's label (left of the divider) and B's (right of it), kept on
    screen."""
    (aw, ah), (bw, bh) = a_size, b_size
    ax = int(np.clip(split_x - LABEL_MARGIN - aw, 0, max(width - aw, 0)))
    bx = int(np.clip(split_x + LABEL_MARGIN, 0, max(width - bw, 0)))
    return (ax, LABEL_MARGIN, aw, ah), (bx, LABEL_MARGIN, bw, bh)


def as_rgba(gi: np.ndarray) -> np.ndarray:
    """A GI layer image (radiance, status) as RGBA with alpha 1 on the asset, else 0."""
    out = np.array(gi, np.float32, copy=True)
    out[..., 3] = (gi[..., 3] > 0.5).astype(np.float32)
    return out


def layer_metrics(full_a: np.ndarray, full_b: np.ndarray) -> dict:
    """``render --compare``'s metrics of B against A (app/commands/compare.py: metrics) over
    the asset's pixels of both GI layers; a layer of another size (a quality preset with
    another GI scale) is resampled to A's by nearest pixel first."""
    from app.commands.compare import metrics
    a, b = as_rgba(full_a), as_rgba(full_b)
    if b.shape != a.shape:
        h, w = a.shape[:2]
        rows = (np.arange(h) * b.shape[0] // h).clip(0, b.shape[0] - 1)
        cols = (np.arange(w) * b.shape[1] // w).clip(0, b.shape[1] - 1)
        b = b[rows][:, cols]
    return metrics(a, b)


def metrics_lines(m: dict | None) -> list[str]:
    """The panel's lines for the metrics (None: not both refined yet)."""
    if m is None:
        return ["metrics once both sides are refined"]
    if not m.get("pixels"):
        return ["no asset pixel on both sides"]
    out = [f"relative RMSE {m['rel_rmse']:.4f}"
           + ("" if m.get("rel_rmse_4x4") is None else f"   4x4 {m['rel_rmse_4x4']:.4f}"),
           f"mean luminance B / A {m['mean_luminance_ratio']:.3f}"]
    flip = m.get("flip")
    out.append("HDR-FLIP " + ("(flip-evaluator not installed)" if flip is None
                              else f"{flip:.4f}"))
    out.append(f"over {m['pixels']:,} asset pixels")
    return out


__all__ = ["OverriddenSettings", "b_overrides", "b_settings", "side_names", "split_column",
           "label_rects", "layer_metrics", "metrics_lines"]
