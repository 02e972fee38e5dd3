"""The viewer's display transform: every tone mapper of the registry and the false-colour EV view
in the composite pass (shaders/viewer_composite.glsl) against their numpy twins
(app/render/tonemap.py) on the displayed image; the exposure snap; the legends' colours."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support.viewer import small_session

from app.pbgi.renderer import Relighter
from app.render import tonemap as T
from app.ui.engine import ViewerEngine


@pytest.fixture(scope="module")
def engine(ctx):
    """One small converged engine (64x48), re-composited per test."""
    e = ViewerEngine(ctx, small_session(), size=(64, 48), relighter=Relighter)
    e.frame()
    e.finish_refinement()
    return e


def _shown(e, **settings):
    for key, val in settings.items():
        e.session.settings.set(key, val)
    e.frame()
    return e.view.read_display().astype(int), e.view.read_linear()[..., :3]


@pytest.mark.parametrize("name", T.NAMES)
def test_viewport_shows_each_tone_mapper(engine, name):
    """The display image is the numpy tone mapper of the linear composite, within one 8-bit code
    (float32 on the GPU; tests/render/test_tonemap.py bounds the float error)."""
    shown, lin = _shown(engine, **{"view.tonemap": name, "view.exposure": 1.0,
                                   "view.false_colour": False})
    expect = T.tonemap_to_srgb8(lin, 1.0, name).astype(int)
    assert np.abs(shown - expect).max() <= 1
    if name != T.DEFAULT:     # and it is not the default's picture
        other = T.tonemap_to_srgb8(lin, 1.0, T.DEFAULT).astype(int)
        assert np.abs(shown - other).max() > 2


def test_viewport_false_colour_matches_twin(engine):
    shown, lin = _shown(engine, **{"view.false_colour": True, "view.exposure": 2.0})
    try:
        expect = np.round(T.false_colour(lin, 2.0) * 255).astype(int)
        ev = T.false_colour_ev(lin, 2.0)
        edges = np.asarray(T.FALSE_COLOUR_EDGES)
        near = np.min(np.abs(ev[..., None] - edges), axis=-1) < 1e-4
        ok = np.abs(shown - expect).max(axis=-1) <= 1
        assert np.all(ok | near) and (~near).mean() > 0.99
        assert len(np.unique(expect.reshape(-1, 3), axis=0)) >= 2   # more than one band shown
    finally:
        engine.session.settings.set("view.false_colour", False)


def test_exposure_snaps_to_third_stops():
    from app.ui.panels.display import snap_ev
    assert snap_ev(0.0) == 0.0
    assert snap_ev(0.3) == pytest.approx(1 / 3) and snap_ev(0.1) == 0.0
    assert snap_ev(-1.2) == pytest.approx(-4 / 3) and snap_ev(2.5) == pytest.approx(8 / 3)
    assert snap_ev(1.0 / 6.0 + 1e-9) == pytest.approx(1 / 3)
    thirds = np.array([snap_ev(x) for x in np.linspace(-10, 10, 2001)])
    np.testing.assert_allclose(thirds * 3, np.round(thirds * 3), atol=1e-12)
    assert np.all(np.abs(thirds - np.linspace(-10, 10, 2001)) <= 1 / 6 + 1e-12)
    assert snap_ev(9.99) == 10.0 and snap_ev(-10.0) == -10.0      # the slider's ends


def test_difference_legend_shows_the_maps_colours():
    """Each legend swatch is the colour the viewport shows (raw, sRGB-encoded) for a point whose
    HDR luminance is that many stops above its LDR one."""
    from app.ui.scene import DIFF_STOPS, difference_colors, difference_legend
    rows = difference_legend()
    assert [r[0] for r in rows] == [f"+{k} EV" for k in range(6)] + ["+6 EV or more"]
    ldr = np.full((7, 3), 1.0)     # bright: the map's eps (1e-4) shifts it by < 1e-4 stops
    hdr = ldr * 2.0 ** np.arange(7)[:, None]
    shown = T.srgb_encode(difference_colors(ldr, hdr))
    np.testing.assert_allclose([r[1] for r in rows], shown, atol=1e-4)  # ramp: < 0.6 / stop
    assert rows[0][1][0] < 0.15 and min(rows[-1][1]) > 0.999 and DIFF_STOPS == 6.0


def test_false_colour_legend_names_each_band_colour():
    rows = T.false_colour_legend()
    e = T.FALSE_COLOUR_EDGES
    for (text, rgb), lo in zip(rows[1:], e):
        assert text.split()[0 if lo < e[-1] else 1] == f"{lo:+g}"
        grey = 0.18 * 2.0 ** (lo + 0.01)                  # just inside the band
        assert T.false_colour([[grey] * 3])[0].tolist() == list(np.float32(rgb))
