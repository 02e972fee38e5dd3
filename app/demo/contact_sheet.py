"""The demo's contact sheet: every image of ``scanlight demo`` on one labelled PNG.

The demo writes a dozen separate files at render size; a person wants one picture that shows
what the pipeline did: the LDR room against the expanded HDR room and the ground truth, where
the expansion added light (log2 of the HDR / LDR luminance, in false colour with its legend),
and the asset relit in every render mode. This module only composes images it is given (numpy
and Pillow, no GL), so the layout is tested without rendering; app/demo/pipeline.py renders.

A tile shows ``tonemap_to_srgb8`` of its linear image (the PNGs' tone mapper and exposure, both
named on the sheet) scaled to the tile with Pillow's Lanczos filter, under a label band. The
difference colours use a luminance-monotone ramp (control points of matplotlib's "inferno"), so
brighter always means more stops, also in grey print; that tile is scaled nearest-neighbour so
each of its pixels keeps a colour of the legend.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from app.color import luminance
from app.render.tonemap import tonemap_to_srgb8

TILE = 224            # px of a tile's image: a 128-256 px render is legible at this size
LABEL_H = 16          # the label band above each tile
GAP = 8               # between tiles
MARGIN = 12           # around the sheet
HEADER_TITLE_H = 21   # the title line
HEADER_LINE_H = 15    # each further header line (tone mapper, exposure, sizes)
LEGEND_W = 84         # the difference legend: bar, ticks and their labels
BAR_W = 14
BACKGROUND = (255, 255, 255)
EMPTY = (236, 236, 236)          # a tile's area where its image does not reach (aspect)
NO_DATA = (160, 160, 160)        # difference pixels where neither image has light
TEXT = (20, 20, 20)

# inferno at 0, 1/4, 1/2, 3/4, 1 (sRGB display values): luminance rises monotonically
RAMP = np.array([(0.001, 0.000, 0.014), (0.341, 0.062, 0.429), (0.735, 0.216, 0.330),
                 (0.978, 0.557, 0.035), (0.988, 0.998, 0.645)], dtype=np.float64)


@dataclass(frozen=True)
class Tile:
    label: str
    pixels: np.ndarray            # (h, w, 3) uint8 sRGB: what the tile shows, before scaling
    smooth: bool = True           # scaled with Lanczos; False: nearest (false colour: Lanczos
                                  # would ring into colours that are not on the legend)


@dataclass
class Legend:
    """The difference tile's scale: ``ticks`` (value, text) from ``lo`` (bottom) to ``hi``."""
    lo: float
    hi: float
    ticks: list[tuple[float, str]]
    title: str = "stops"


@dataclass
class Layout:
    """Where everything went (pixel boxes x0, y0, x1, y1, end exclusive), for tests and docs."""
    size: tuple[int, int]                                   # (width, height)
    tiles: dict[str, tuple[int, int, int, int]] = field(default_factory=dict)   # label -> image
    labels: dict[str, tuple[int, int, int, int]] = field(default_factory=dict)  # label -> band
    legend: tuple[int, int, int, int] | None = None         # the colour bar itself
    header: tuple[int, int, int, int] = (0, 0, 0, 0)        # the title and its lines
    lines: list[str] = field(default_factory=list)          # the header's text


def tone_mapped(label: str, linear_rgb: np.ndarray, exposure: float, tonemapper: str) -> Tile:
    """A tile of a linear image as the demo's PNGs show it."""
    return Tile(label, tonemap_to_srgb8(np.asarray(linear_rgb)[..., :3], exposure, tonemapper))


def fit(pixels: np.ndarray, size: int = TILE, smooth: bool = True) -> np.ndarray:
    """``pixels`` scaled (Lanczos, or nearest where not ``smooth``; aspect kept) to fit a
    size x size square, centred on EMPTY."""
    from PIL import Image
    h, w = pixels.shape[:2]
    s = size / max(h, w)
    nw, nh = max(1, round(w * s)), max(1, round(h * s))
    img = Image.fromarray(np.ascontiguousarray(pixels[..., :3]))
    if (nw, nh) != (w, h):
        img = img.resize((nw, nh), Image.Resampling.LANCZOS if smooth else
                         Image.Resampling.NEAREST)
    out = np.empty((size, size, 3), np.uint8)
    out[:] = EMPTY
    y0, x0 = (size - nh) // 2, (size - nw) // 2
    out[y0:y0 + nh, x0:x0 + nw] = np.asarray(img)
    return out


def ramp(t) -> np.ndarray:
    """(...) values in [0, 1] -> (..., 3) uint8 colours of the difference ramp."""
    t = np.clip(np.nan_to_num(np.asarray(t, np.float64)), 0.0, 1.0) * (len(RAMP) - 1)
    i = np.minimum(t.astype(int), len(RAMP) - 2)
    f = (t - i)[..., None]
    return np.round(255.0 * (RAMP[i] * (1 - f) + RAMP[i + 1] * f)).astype(np.uint8)


def log_ratio(hdr: np.ndarray, ldr: np.ndarray, floor: float = 1e-4) -> np.ndarray:
    """log2(Y_hdr / Y_ldr) per pixel (the stops the expansion added); NaN where both are below
    ``floor`` (no splat there). A clipped LDR pixel still has light, so the ratio is finite."""
    yh = np.maximum(luminance(np.nan_to_num(hdr[..., :3])), 0.0).astype(np.float64)
    yl = np.maximum(luminance(np.nan_to_num(ldr[..., :3])), 0.0).astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.log2(np.maximum(yh, floor) / np.maximum(yl, floor))
    r[(yh < floor) & (yl < floor)] = np.nan
    return r


def difference_tile(label: str, hdr: np.ndarray, ldr: np.ndarray,
                    hi: float | None = None) -> tuple[Tile, Legend]:
    """The stops the HDR room has over the LDR one in false colour, 0 (black) to ``hi`` (pale
    yellow; None: the 99th percentile rounded up to whole stops, at least 1). Values below 0
    (HDR darker than the scan) show as 0; pixels without light in grey."""
    r = log_ratio(hdr, ldr)
    valid = np.isfinite(r)
    if hi is None:
        top = float(np.percentile(r[valid], 99)) if valid.any() else 1.0
        hi = float(max(1, int(np.ceil(top - 1e-6))))
    px = ramp(r / hi)
    px[~valid] = NO_DATA
    step = 1 if hi <= 6 else int(np.ceil(hi / 6))
    ticks = [(float(v), "0" if v == 0 else f"+{v:g}") for v in np.arange(0, hi + 1e-9, step)]
    return Tile(label, px, smooth=False), Legend(0.0, hi, ticks, "stops")


def _font(size: int = 12):
    from PIL import ImageFont
    try:
        return ImageFont.load_default(size=size)
    except TypeError:                      # Pillow < 10.1: the fixed bitmap font
        return ImageFont.load_default()


def compose(rows: list[list[Tile | None]], header: list[str],
            legend: tuple[int, int, Legend] | None = None,
            tile: int = TILE) -> tuple[np.ndarray, Layout]:
    """The sheet: ``header`` lines (the first as the title) over ``rows`` of tiles (None leaves
    a cell empty); ``legend`` = (row, column, Legend) puts a colour bar right of that tile.
    Returns (H, W, 3) uint8 and where everything is."""
    from PIL import Image, ImageDraw
    cols = max(len(r) for r in rows)
    cell_w, cell_h = tile + GAP, LABEL_H + tile + GAP
    head_h = HEADER_TITLE_H + HEADER_LINE_H * (len(header) - 1) + GAP
    width = 2 * MARGIN + cols * cell_w - GAP + (LEGEND_W if legend else 0)
    height = 2 * MARGIN + head_h + len(rows) * cell_h - GAP
    sheet = np.empty((height, width, 3), np.uint8)
    sheet[:] = BACKGROUND
    layout = Layout((width, height), header=(MARGIN, MARGIN, width - MARGIN, MARGIN + head_h),
                    lines=list(header))
    top = MARGIN + head_h
    for ri, row in enumerate(rows):
        for ci, t in enumerate(row):
            if t is None:
                continue
            x0, y0 = MARGIN + ci * cell_w, top + ri * cell_h
            if t.label in layout.tiles:
                raise ValueError(f"two tiles are labelled {t.label!r}")
            layout.labels[t.label] = (x0, y0, x0 + tile, y0 + LABEL_H)
            layout.tiles[t.label] = (x0, y0 + LABEL_H, x0 + tile, y0 + LABEL_H + tile)
            sheet[y0 + LABEL_H:y0 + LABEL_H + tile, x0:x0 + tile] = fit(t.pixels, tile, t.smooth)
    texts = []                                    # (x, top y, text)
    if legend:
        ri, ci, leg = legend
        x0 = MARGIN + ci * cell_w + tile + 6
        y0 = top + ri * cell_h + LABEL_H
        layout.legend = (x0, y0, x0 + BAR_W, y0 + tile)
        t = 1.0 - (np.arange(tile) + 0.5) / tile         # top row = hi
        sheet[y0:y0 + tile, x0:x0 + BAR_W] = ramp(t)[:, None, :]
        for v, text in leg.ticks:
            y = y0 + int(round((1.0 - (v - leg.lo) / (leg.hi - leg.lo)) * (tile - 1)))
            sheet[y, x0 + BAR_W:x0 + BAR_W + 4] = TEXT
            texts.append((x0 + BAR_W + 6, int(np.clip(y, y0 + 6, y0 + tile - 7)) - 7, text))
        texts.append((x0, y0 - LABEL_H + 1, leg.title))
    img = Image.fromarray(sheet)
    draw = ImageDraw.Draw(img)
    small = _font(12)
    draw.text((MARGIN, MARGIN), header[0], fill=TEXT, font=_font(15))
    for i, line in enumerate(header[1:]):
        texts.append((MARGIN, MARGIN + HEADER_TITLE_H + i * HEADER_LINE_H, line))
    texts += [(x0 + 1, y0 + 1, label) for label, (x0, y0, _, _) in layout.labels.items()]
    for x, y, text in texts:         # no anchors: Pillow 10.0's bitmap font has none
        draw.text((x, y), text, fill=TEXT, font=small)
    return np.asarray(img).copy(), layout


# what the demo's sheet shows in its asset rows: two of app.material.PRESETS
ASSET_MATERIALS = {"diffuse": "white diffuse", "glossy": "gold"}


def demo_sheet(room: dict[str, np.ndarray], relit: dict[str, np.ndarray],
               modes: dict[tuple[str, str], np.ndarray], tonemapper: str,
               room_exposure: float, relit_mode: str,
               render_size: int, passes: dict | None = None) -> tuple[np.ndarray, Layout]:
    """The demo's sheet from its linear images: ``room`` {"ldr", "hdr", "gt"} (one view,
    ground-truth units) all shown at ``room_exposure`` EV, so the scan's clipped lights look as
    dull as they are; ``relit`` {"ldr",
    "expanded", "gt"}: the asset lit by each cloud in ``relit_mode``; ``modes`` {(material
    kind, mode): image}: the asset lit by the expanded cloud, one row per material kind of
    ASSET_MATERIALS, ``passes`` {material kind: passes averaged} where more than one. Asset
    images at 0 EV."""
    from app.render.tonemap import get
    names = {"ldr": "LDR scan", "hdr": "HDR expanded", "gt": "ground truth"}
    diff, legend = difference_tile("log2 HDR/LDR luminance", room["hdr"], room["ldr"])
    rows = [[tone_mapped(f"room: {names[k]}", room[k], room_exposure, tonemapper)
             for k in ("ldr", "hdr", "gt") if k in room]
            + [diff]]
    lit = {"ldr": "LDR scan", "expanded": "expanded HDR", "gt": "ground truth"}
    rows.append([tone_mapped(f"{relit_mode}, lit by {lit[k]}", relit[k], 0.0, tonemapper)
                 for k in lit if k in relit])
    kinds = list(dict.fromkeys(kind for kind, _ in modes))
    for kind in kinds:
        rows.append([tone_mapped(f"{kind} ({ASSET_MATERIALS.get(kind, kind)}), {mode}", img, 0.0,
                                 tonemapper) for (k, mode), img in modes.items() if k == kind])
    header = ["Scanlight demo: HDR expansion of the LDR scan, and the asset relit by it",
              f"tone mapper: {get(tonemapper).title}; exposure: room (row 1) {room_exposure:+g} "
              "EV, asset (rows 2+) +0 EV; EXRs beside this sheet are linear",
              f"renders {render_size} x {render_size} px, shown at {TILE} px; rows 3+: the asset "
              "lit by the expanded HDR scan in each render mode"]
    many = [f"{kind} {n}" for kind, n in (passes or {}).items() if n > 1]
    if many:
        header.append(f"passes averaged, as scanlight render gives them: {', '.join(many)} "
                      "(pbgi.glossy_passes), 1 for the others")
    return compose(rows, header, legend=(0, len(rows[0]) - 1, legend))


__all__ = ["Tile", "Legend", "Layout", "TILE", "ASSET_MATERIALS", "tone_mapped", "fit", "ramp",
           "log_ratio", "difference_tile", "compose", "demo_sheet"]
