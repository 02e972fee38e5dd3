"""The demo's contact sheet (app/demo/contact_sheet.py): layout, labels, legend and that every
tile shows the tone-mapped image it names. Pure numpy/Pillow: no GL."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from app.demo import contact_sheet as cs
from app.render.tonemap import TONEMAPPERS, tonemap_to_srgb8


def hdr_image(h=32, w=32, seed=0):
    """Linear radiance from 0 to ~16 (several stops over 1), as the demo's renders have."""
    rng = np.random.default_rng(seed)
    return (rng.random((h, w, 3)) ** 3 * 16.0).astype(np.float32)


def crop(sheet, box):
    x0, y0, x1, y1 = box
    return sheet[y0:y1, x0:x1]


def test_a_tile_at_its_own_size_is_exactly_the_tone_mapped_image():
    src = hdr_image(40, 40)
    for name in TONEMAPPERS:
        sheet, lay = cs.compose([[cs.tone_mapped("a", src, -1.5, name)]], ["t"], tile=40)
        assert np.array_equal(crop(sheet, lay.tiles["a"]), tonemap_to_srgb8(src, -1.5, name))
    # the tone mapper is the one asked for: two of them give different tiles
    a = cs.tone_mapped("a", src, 0.0, "pbr-neutral").pixels
    b = cs.tone_mapped("a", src, 0.0, "aces").pixels
    assert np.abs(a.astype(int) - b).max() > 10


def test_a_scaled_tile_is_the_tone_mapped_image_resized_with_lanczos():
    src = hdr_image(24, 24, seed=1)
    sheet, lay = cs.compose([[cs.tone_mapped("up", src, 0.5, "agx")]], ["t"], tile=60)
    want = np.asarray(Image.fromarray(tonemap_to_srgb8(src, 0.5, "agx")).resize(
        (60, 60), Image.Resampling.LANCZOS))
    assert np.array_equal(crop(sheet, lay.tiles["up"]), want)


def test_a_wide_image_keeps_its_aspect_centred_in_the_tile():
    px = np.zeros((10, 20, 3), np.uint8)
    out = cs.fit(px, 40)
    assert (out[10:30] == 0).all()                       # 20 x 40 of image, centred
    assert (out[:10] == cs.EMPTY).all() and (out[30:] == cs.EMPTY).all()


def test_layout_places_tiles_on_a_grid_with_labels_above():
    t = 36
    rows = [[cs.Tile(f"r0c{c}", np.full((8, 8, 3), 50 * c, np.uint8)) for c in range(3)],
            [cs.Tile("r1c0", np.zeros((8, 8, 3), np.uint8)), None,
             cs.Tile("r1c2", np.zeros((8, 8, 3), np.uint8))]]
    sheet, lay = cs.compose(rows, ["title", "line two"], tile=t)
    assert sheet.shape == (lay.size[1], lay.size[0], 3) and sheet.dtype == np.uint8
    assert set(lay.tiles) == {"r0c0", "r0c1", "r0c2", "r1c0", "r1c2"}
    x00, y00 = lay.tiles["r0c0"][:2]
    for name, (x0, y0, x1, y1) in lay.tiles.items():
        r, c = int(name[1]), int(name[3])
        assert (x0 - x00, y0 - y00) == (c * (t + cs.GAP), r * (t + cs.LABEL_H + cs.GAP))
        assert (x1 - x0, y1 - y0) == (t, t)
        assert lay.labels[name] == (x0, y0 - cs.LABEL_H, x1, y0)   # the band right above
        assert x1 <= lay.size[0] - cs.MARGIN and y1 <= lay.size[1] - cs.MARGIN
        assert y0 - cs.LABEL_H >= lay.header[3]                      # below the header
        # the tile holds its image: the constant grey of its source
        assert (crop(sheet, (x0, y0, x1, y1)) == 50 * c * (r == 0)).all()
    # labels and header lines are drawn: dark pixels in each band, none in the gaps
    for box in list(lay.labels.values()) + [lay.header]:
        assert (crop(sheet, box).min(axis=2) < 100).sum() > 10, box
    x1 = lay.tiles["r0c0"][2]
    assert (sheet[lay.header[3]:, x1:x1 + cs.GAP] == cs.BACKGROUND).all()
    # the empty cell (row 1, column 1) stays background
    empty = (lay.tiles["r0c1"][0], lay.tiles["r1c0"][1] - cs.LABEL_H,
             lay.tiles["r0c1"][2], lay.tiles["r1c0"][3])
    assert (crop(sheet, empty) == cs.BACKGROUND).all()
    with pytest.raises(ValueError, match="two tiles"):
        cs.compose([[rows[0][0], rows[0][0]]], ["t"], tile=t)


def test_log_ratio_is_the_stops_between_luminances():
    ldr = np.full((2, 3, 3), 0.5, np.float32)
    hdr = ldr * np.array([[1, 2, 8], [0.5, 1, 1]], np.float32)[..., None]
    hdr[1, 2] = ldr[1, 2] = 0.0                                # no splat: no data
    r = cs.log_ratio(hdr, ldr)
    assert np.allclose(r[0], [0, 1, 3], atol=1e-5) and np.isclose(r[1, 0], -1, atol=1e-5)
    assert np.isnan(r[1, 2]) and np.isfinite(r[:, :2]).all()


def test_difference_tile_colours_stops_on_the_ramp_with_its_legend():
    ldr = np.full((4, 4, 3), 0.25, np.float32)
    stops = np.array([0, 1, 2, 3] * 4, np.float32).reshape(4, 4)
    stops[3, 3] = -2.0                                          # HDR darker: shown as 0
    hdr = ldr * 2.0 ** stops[..., None]
    hdr[0, 0] = ldr[0, 0] = 0.0
    tile, legend = cs.difference_tile("d", hdr, ldr)
    assert legend.hi == 3 and legend.lo == 0                   # ceil of the 99th percentile
    assert [v for v, _ in legend.ticks] == [0, 1, 2, 3]
    assert [s for _, s in legend.ticks] == ["0", "+1", "+2", "+3"]
    assert np.array_equal(tile.pixels[1, 2], cs.ramp(2 / 3))
    assert np.array_equal(tile.pixels[3, 3], cs.ramp(0.0))
    assert np.array_equal(tile.pixels[0, 0], cs.NO_DATA)
    _, legend = cs.difference_tile("d", hdr, ldr, hi=12)
    assert [v for v, _ in legend.ticks] == [0, 2, 4, 6, 8, 10, 12]


def test_ramp_luminance_rises_and_the_legend_bar_shows_it():
    lum = cs.ramp(np.linspace(0, 1, 257)) @ np.array([0.2126, 0.7152, 0.0722])
    assert (np.diff(lum) >= 0).all() and lum[-1] - lum[0] > 200
    hdr = np.full((8, 8, 3), 4.0, np.float32)
    hdr[:, :4] = 1.0
    tile, legend = cs.difference_tile("diff", hdr, np.ones((8, 8, 3), np.float32))
    t = 64
    sheet, lay = cs.compose([[tile]], ["t"], legend=(0, 0, legend), tile=t)
    x0, y0, x1, y1 = lay.legend
    assert (x0, y0, y1) == (lay.tiles["diff"][2] + 6, lay.tiles["diff"][1], lay.tiles["diff"][3])
    bar = sheet[y0:y1, (x0 + x1) // 2].astype(float) @ np.array([0.2126, 0.7152, 0.0722])
    assert (np.diff(bar) <= 1.0).all() and bar[0] - bar[-1] > 200   # bright (hi) on top
    # a tick mark at each end and a label beside it (dark pixels right of the bar)
    assert (sheet[y0, x1:x1 + 4] == cs.TEXT).all() and (sheet[y1 - 1, x1:x1 + 4] == cs.TEXT).all()
    labels = sheet[y0:y1, x1 + 6:x1 + 40].min(axis=2) < 100
    assert labels[:12].any() and labels[-12:].any()
    # the tile: half at 0 stops (black end), half at +2 (the top of the scale), scaled
    # nearest-neighbour: only those two colours, no ringing in between
    px = crop(sheet, lay.tiles["diff"])
    assert np.array_equal(px[:, : t // 2], np.broadcast_to(cs.ramp(0.0), (t, t // 2, 3)))
    assert np.array_equal(px[:, t // 2:], np.broadcast_to(cs.ramp(1.0), (t, t // 2, 3)))


def test_demo_sheet_names_everything_and_shows_each_source():
    room = {k: hdr_image(20, 20, seed=i) for i, k in enumerate(("ldr", "hdr", "gt"))}
    relit = {k: hdr_image(20, 20, seed=5 + i) for i, k in enumerate(("ldr", "expanded", "gt"))}
    modes = {(kind, m): hdr_image(20, 20, seed=9 + 4 * j + i)
             for j, kind in enumerate(("diffuse", "glossy"))
             for i, m in enumerate(("classic", "mipmapped", "hybrid", "envmap"))}
    sheet, lay = cs.demo_sheet(room, relit, modes, "aces", -2.0, "hybrid", 20)
    assert len(lay.tiles) == 3 + 1 + 3 + 8 and lay.legend is not None
    assert TONEMAPPERS["aces"].title in lay.lines[1] and "-2 EV" in lay.lines[1]
    assert sheet.shape[1] == lay.size[0] and lay.tiles["room: LDR scan"][2] - \
        lay.tiles["room: LDR scan"][0] == cs.TILE

    def shown(src, ev):
        return np.asarray(Image.fromarray(tonemap_to_srgb8(src, ev, "aces")).resize(
            (cs.TILE, cs.TILE), Image.Resampling.LANCZOS))
    assert np.array_equal(crop(sheet, lay.tiles["room: HDR expanded"]), shown(room["hdr"], -2.0))
    assert np.array_equal(crop(sheet, lay.tiles["hybrid, lit by expanded HDR"]),
                          shown(relit["expanded"], 0.0))
    assert np.array_equal(crop(sheet, lay.tiles["glossy (gold), mipmapped"]),
                          shown(modes[("glossy", "mipmapped")], 0.0))
    diff = cs.difference_tile("d", room["hdr"], room["ldr"])[0].pixels
    assert np.array_equal(crop(sheet, lay.tiles["log2 HDR/LDR luminance"]), np.asarray(
        Image.fromarray(diff).resize((cs.TILE, cs.TILE), Image.Resampling.NEAREST)))
    # rows: room + difference, relit by each cloud, then one row per material in mode order
    ys = sorted({box[1] for box in lay.tiles.values()})
    assert len(ys) == 4
    assert [n for n, b in lay.tiles.items() if b[1] == ys[3]] == [
        f"glossy (gold), {m}" for m in ("classic", "mipmapped", "hybrid", "envmap")]
    assert lay.tiles["log2 HDR/LDR luminance"][1] == ys[0]
    # a material row averaged over passes is named in the header; one pass is the default
    assert not any("passes" in line for line in lay.lines)
    _, lay4 = cs.demo_sheet(room, relit, modes, "aces", -2.0, "hybrid", 20,
                            {"diffuse": 1, "glossy": 4})
    assert [line for line in lay4.lines if "passes" in line] == [
        "passes averaged, as scanlight render gives them: glossy 4 (pbgi.glossy_passes), 1 "
        "for the others"]
