"""The viewer's HDRI lighting and A/B compare (issue 18), offscreen: the engine the window and
``scanlight view --offscreen`` drive, with the real renderer kept cheap (tests/support/viewer.py:
small viewport, micro-buffer 8).

One pass of tiles (``pbgi.idle_passes`` 1) so a layer is one render, not a jittered average.
Tolerances: a refined GI layer equals the renderer's own image of the same camera within 1% of
its brightest pixel (tests/ui/test_ui_refine.py: tiles move positions by float rounding); the
tiling follows the measured speed, so two engines' images of one setting differ as much: each
side of the split equals the A-only / B-only engine's composite within that 1% on all but
0.5% of the pixels (silhouette texels), and the room outside the asset within 1e-5."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.support.viewer import small_session
from tests.ui.test_ui_panels import ui  # noqa: F401  (the panels fixture: imgui, no window)

from app.pbgi.renderer import Relighter
from app.ui.engine import ViewerEngine

SIZE = (120, 80)


def _engine(ctx, hdri=None, **settings) -> ViewerEngine:
    session = small_session(**{"pbgi.idle_passes": 1, **settings})
    session.hdri = None if hdri is None else str(hdri)
    return ViewerEngine(ctx, session, size=SIZE, relighter=Relighter)


@pytest.fixture(scope="module")
def pano(tmp_path_factory):
    """A small equirectangular EXR: dim blue sky, a warm bright patch on one side."""
    from app.io.exr import write_exr
    h, w = 32, 64
    img = np.full((h, w, 3), (0.05, 0.08, 0.2), np.float32)
    img[8:14, 10:20] = (40.0, 25.0, 10.0)
    img[h // 2:] = (0.1, 0.08, 0.06)               # the ground
    path = tmp_path_factory.mktemp("hdri") / "pano.exr"
    write_exr(path, img)
    return path


def _off(x: np.ndarray, ref: np.ndarray, peak: float) -> float:
    """Fraction of pixels off by more than 1% of ``peak`` (the brightest asset pixel), or by
    more than 1e-5 where neither shows the asset (the room: the same splats, the same pass)."""
    asset = (x[..., 3] > 0) | (ref[..., 3] > 0)
    d = np.abs(x - ref).max(axis=-1)
    return float(((d > 0.01 * peak) & asset).mean() + ((d > 1e-5) & ~asset).mean())


def _refined(e: ViewerEngine) -> np.ndarray:
    e.frame()
    e.finish_refinement()
    return e.view.read_linear()


def test_hdri_lights_the_asset_as_the_renderer_does(ctx, pano):
    """light.source = hdri: the asset's GI layer is Relighter.render's image with the same HDRI
    (turned by light.hdri_rotation), the background is that panorama, and the asset changed
    from the scan-lit one."""
    from app.pbgi.hdri import hdri_backdrop, load_hdri
    from app.pbgi.renderer import RenderParams
    scan = _engine(ctx)
    scan_lit = _refined(scan)
    scan.release()
    e = _engine(ctx, pano, **{"light.source": "hdri", "light.hdri_rotation": 90.0})
    lin = _refined(e)
    assert not [m.text for m in e.messages if m.level != "info"]
    hdri = load_hdri(pano, 90.0)
    r = Relighter(ctx)
    r.set_cloud(e.cloud.lighting(e.session.settings["view.cloud"]))
    r.set_asset(e.mesh)
    r.set_hdri(hdri)
    direct = r.render(e.gi.camera, e.session.materials,
                      RenderParams.from_settings(e.session.settings)).image
    r.release()
    asset = lin[..., 3] > 0
    assert (direct[..., 3] > 0).sum() > 300 and asset.sum() > 300
    np.testing.assert_array_equal(e.gi.full[..., 3], direct[..., 3])
    np.testing.assert_allclose(e.gi.full[..., :3], direct[..., :3],
                               atol=0.01 * direct[..., :3].max())
    # the panorama behind the asset, as Relighter.background shows it
    back = hdri_backdrop(hdri, e.camera())
    np.testing.assert_allclose(lin[~asset][:, :3], back[~asset][:, :3], rtol=1e-5, atol=1e-6)
    # lit by the warm patch instead of the room: the asset's colour is another
    both = asset & (scan_lit[..., 3] > 0)
    rel = np.abs(lin[both][:, :3] - scan_lit[both][:, :3]).mean() / scan_lit[both][:, :3].mean()
    assert rel > 0.2, rel
    # back to the scan: the scan's light and the room again
    e.session.settings.set("light.source", "scan")
    np.testing.assert_allclose(_refined(e), scan_lit, atol=1e-5)
    e.release()


@pytest.mark.parametrize("kind", ["mode", "hdri"])
def test_the_divider_splits_a_and_b(ctx, pano, kind):
    """compare.enabled: columns left of compare.split are the A-only engine's composite, the
    rest the B-only engine's (B: another mode; or the HDRI where A has the scan), with the
    divider line and both labels on the display image, and the metrics once refined."""
    from app.ui.compare import layer_metrics, split_column
    b_only = {"mode": {"pbgi.mode": "envmap"}, "hdri": {"light.source": "hdri"}}[kind]
    refs = []
    for extra in ({}, b_only):
        e = _engine(ctx, pano, **extra)
        refs.append((_refined(e), e.gi.full.copy()))
        e.release()
    (a, a_gi), (b, b_gi) = refs
    e = _engine(ctx, pano, **{"compare.enabled": True, "compare.b": kind,
                              "compare.mode": "envmap", "compare.split": 0.4})
    ab = _refined(e)
    x = split_column(0.4, SIZE[0])
    assert x == 48
    peak = max(a[..., :3][a[..., 3] > 0].max(), b[..., :3][b[..., 3] > 0].max())
    assert _off(b[:, x:], a[:, x:], peak) > 0.05    # the sides differ: the test can fail
    assert _off(ab[:, :x], a[:, :x], peak) < 0.005
    assert _off(ab[:, x:], b[:, x:], peak) < 0.005
    shown = e.view.read_display()
    assert (shown[30:, x - 1:x + 1] == 235).all()  # the divider line (0.92 of white) below
    assert (shown[30:, [x - 2, x + 1]] != 235).any()    # the labels, and only 2 pixels wide
    labels = {"mode": ("A: hybrid", "B: envmap"), "hdri": ("A: scan light", "B: HDRI pano.exr")}
    assert e.compare_labels == labels[kind]
    m = e.compare_metrics
    assert m is not None and m["pixels"] > 300
    # the separate engines' layers, tiled as their speed chose: within 5% of each other (Hybrid's
    # blocks, and the neighbourhoods their levels are fitted over, end at a tile's edge: 2.7%)
    assert m["rel_rmse"] > 0.01
    assert m["rel_rmse"] == pytest.approx(layer_metrics(a_gi, b_gi)["rel_rmse"], rel=0.05)
    # moving the divider re-composites only: no new gather
    e.session.settings.set("compare.split", 0.75)
    info = e.frame()
    assert not info["gi"] and not e.gi.refining and not e.gi_b.refining
    x = split_column(0.75, SIZE[0])
    ab = e.view.read_linear()
    assert _off(ab[:, :x], a[:, :x], peak) < 0.005
    assert _off(ab[:, x:], b[:, x:], peak) < 0.005
    e.release()


def test_light_and_compare_round_trip_through_a_saved_session(tmp_path, pano):
    from app.settings import load_session
    s = small_session(**{"light.source": "hdri", "light.hdri_rotation": -30.0,
                         "compare.enabled": True, "compare.b": "quality",
                         "compare.quality": "preview", "compare.split": 0.3})
    s.hdri = str(pano)
    path = s.save(tmp_path / "s.json")
    stored = json.loads(path.read_text())
    assert stored["files"]["hdri"] != str(pano)      # relative to the session, as the cloud
    back = load_session(path)
    assert Path(back.hdri).resolve() == pano.resolve()
    for key in ("light.source", "light.hdri_rotation", "compare.enabled", "compare.b",
                "compare.quality", "compare.split"):
        assert back.settings[key] == s.settings[key], key
    assert load_session(small_session().save(tmp_path / "t.json")).hdri is None


def test_bad_hdri_files_are_one_message_not_a_crash(ctx, tmp_path):
    """A file that is not an EXR, and an EXR that is not a panorama: one error line naming the
    file each, the scan keeps lighting the asset, later frames add nothing."""
    from app.io.exr import write_exr
    not_exr = tmp_path / "broken.exr"
    not_exr.write_text("not an image")
    square = tmp_path / "square.exr"
    write_exr(square, np.ones((8, 8, 3), np.float32))
    e = _engine(ctx)
    e.frame()
    for bad in (not_exr, square):
        e.messages.clear()
        e.session.set_file("hdri", str(bad))
        e.session.settings.set("light.source", "hdri")
        for _ in range(3):
            e.frame()
        errors = [m.text for m in e.messages if m.level == "error"]
        assert len(errors) == 1 and bad.name in errors[0], errors
        assert e.hdri_a is None and e.relighter.hdri is None
        e.session.settings.set("light.source", "scan")
        e.frame()
    e.finish_refinement()
    assert (e.view.read_linear()[..., 3] > 0).sum() > 300     # the asset is still relit
    e.release()


def test_dragging_the_divider_moves_the_split(ui):
    """The window's divider handle (app/ui/overlay.py) under imgui: a press on the line and a
    drag to 80% of the width set compare.split there, and imgui owns that drag (the window
    gives a drag imgui wants to the UI, not to the orbit: app/ui/drag.py)."""
    from tests.ui.test_ui_panels import _draw
    from imgui_bundle import imgui
    e, s = ui.engine, ui.session.settings
    s.set("compare.enabled", True)
    e.frame()
    assert e.compare_labels == ("A: hybrid", "B: classic")
    cam = e.camera()
    w = e.size[0]
    io = imgui.get_io()
    io.add_mouse_pos_event(0.5 * w, 300)
    _draw(ui, 2)
    io.add_mouse_button_event(0, True)
    _draw(ui, 2)
    wanted = []
    for x in (0.6 * w, 0.7 * w, 0.8 * w):
        io.add_mouse_pos_event(x, 300)
        _draw(ui, 2)
        wanted.append(io.want_capture_mouse)
    io.add_mouse_button_event(0, False)
    _draw(ui, 2)
    assert s["compare.split"] == pytest.approx(0.8, abs=1e-3) and all(wanted)
    np.testing.assert_allclose(e.camera().position, cam.position)
    assert not [m.text for m in e.messages if m.level != "info"]
