"""The provenance view (``view.cloud`` = "provenance"): every point of the cloud that lights the
asset in the false colour of where its HDR colour came from (app.hdr.result.PROVENANCE), and the
figures of the HDR panel's legend. No imgui and no GL here: the engine colours the splats with
``provenance_colors`` and the panel draws ``legend``.

The palette is declared once, below, in 8-bit sRGB: the legend's swatches use it as it is, the
splats get it linearised (the composite shows false colours raw, without exposure or tone
mapping, and sRGB-encodes them back). Its hues are from Okabe & Ito's set, chosen to stay apart
for protanopia, deuteranopia and tritanopia; "kept" is a dim grey so that what the expansion
changed stands out. A registered point's brightness follows its quality q (the only score that
reads as "how good" on a fixed scale); the other labels are flat colours.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.cloud import PointCloud
from app.color import srgb_to_linear
from app.hdr.result import (POISSON, PROJECTED, PROVENANCE, PROVENANCE_ATTR, REGISTERED,
                            SCORE_ATTR, UNCHANGED, UNRESOLVED)

# label -> 8-bit sRGB
PALETTE = {
    UNCHANGED: (96, 96, 96),        # dim grey: the scan's own colour
    REGISTERED: (0, 158, 115),      # Okabe-Ito bluish green
    PROJECTED: (230, 159, 0),       # Okabe-Ito orange
    POISSON: (0, 114, 178),         # Okabe-Ito blue
    UNRESOLVED: (213, 94, 0),       # Okabe-Ito vermillion
}
NO_PROVENANCE = (150, 150, 150)     # every point, when the cloud carries no provenance
# a registered point's sRGB colour is scaled by Q_FLOOR + (1 - Q_FLOOR) * q, q clipped to [0, 1];
# a NaN q shows the full colour
Q_FLOOR = 0.4
NO_PROVENANCE_LINE = "no provenance in this cloud: grey points"
Q_NOTE = f"{PROVENANCE[REGISTERED][0]}: brighter = higher q"
assert set(PALETTE) == set(PROVENANCE) and 255 not in PALETTE, "one colour per label"


def provenance_of(cloud: PointCloud | None) -> tuple[np.ndarray, np.ndarray] | None:
    """(labels uint8, scores float32 with NaN where none) of ``cloud``, or None without them."""
    if cloud is None or PROVENANCE_ATTR not in cloud.attributes:
        return None
    labels = np.asarray(cloud.attributes[PROVENANCE_ATTR])
    if labels.dtype != np.uint8:    # a code beyond a byte is no label: 255 (none) stands for it
        labels = np.where((labels >= 0) & (labels < 256), labels, 255).astype(np.uint8)
    scores = cloud.attributes.get(SCORE_ATTR)
    scores = (np.full(len(labels), np.nan, np.float32) if scores is None
              else np.asarray(scores, np.float32))
    return labels, scores


def provenance_colors(cloud: PointCloud) -> np.ndarray:
    """(N, 3) linear false colours of ``cloud``'s provenance; NO_PROVENANCE grey everywhere
    when it has none (and for a code outside PALETTE)."""
    prov = provenance_of(cloud)
    if prov is None:
        return np.tile(srgb_to_linear(np.array(NO_PROVENANCE) / 255.0), (len(cloud), 1))
    labels, scores = prov
    table = np.tile(np.array(NO_PROVENANCE, np.float32) / 255.0, (256, 1))
    for label, rgb in PALETTE.items():
        table[label] = np.array(rgb, np.float32) / 255.0
    srgb = table[labels]
    reg = labels == REGISTERED
    if reg.any():
        q = np.clip(np.nan_to_num(scores[reg], nan=1.0), 0.0, 1.0)
        srgb[reg] *= (Q_FLOOR + (1.0 - Q_FLOOR) * q)[:, None]
    return srgb_to_linear(srgb)


@dataclass(frozen=True)
class LegendRow:
    label: int
    name: str                       # PROVENANCE's short name
    meaning: str                    # what the score means (PROVENANCE)
    count: int
    share: float                    # of all the cloud's points, 0..1
    srgb: tuple[float, float, float]   # the swatch, 0..1
    median_score: float             # NaN when the label has no finite score


_last_legend: list = [None, None, None]    # labels, scores (the arrays themselves), rows


def legend(cloud: PointCloud | None) -> list[LegendRow] | None:
    """One row per provenance label, in PROVENANCE's order; None when ``cloud`` has none. The
    panel asks every frame: the rows of the last arrays asked about are kept."""
    prov = provenance_of(cloud)
    if prov is None:
        return None
    key = (cloud.attributes[PROVENANCE_ATTR], cloud.attributes.get(SCORE_ATTR))
    if _last_legend[0] is key[0] and _last_legend[1] is key[1]:
        return _last_legend[2]
    _last_legend[:] = [*key, _legend_rows(*prov)]
    return _last_legend[2]


def _legend_rows(labels: np.ndarray, scores: np.ndarray) -> list[LegendRow]:
    counts = np.bincount(labels, minlength=256)
    total = max(len(labels), 1)
    rows = []
    for label, (name, meaning) in PROVENANCE.items():
        mine = scores[labels == label]
        mine = mine[np.isfinite(mine)]
        rows.append(LegendRow(label, name, meaning, int(counts[label]),
                              float(counts[label]) / total,
                              tuple(c / 255.0 for c in PALETTE[label]),
                              float(np.median(mine)) if mine.size else float("nan")))
    return rows
