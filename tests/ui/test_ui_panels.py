"""Every panel and overlay drawn in a headless imgui context (no window): the imgui calls are
valid, nothing ends up in the message list, and the widgets derive from the settings table."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

imgui_bundle = pytest.importorskip("imgui_bundle")
from imgui_bundle import imgui, imguizmo  # noqa: E402


class _Renderer:
    """Stands in for the imgui GL renderer: texture registration, and at render time the check
    moderngl-window's renderer makes - every texture a draw command names must be registered
    (else it raises "Texture N is not registered", which closed the window)."""

    def __init__(self):
        self.textures = {}
        self.drawn = set()

    def register_texture(self, tex):
        self.textures[tex.glo] = tex

    def remove_texture(self, tex):
        del self.textures[tex.glo]

    def render(self, draw_data):
        font = imgui.get_io().fonts.tex_id
        for i in range(draw_data.cmd_lists_count):
            for cmd in draw_data.cmd_lists[i].cmd_buffer:
                tid = cmd.get_tex_id()
                if tid != font:
                    assert tid in self.textures, f"Texture {tid} is not registered"
                    assert self.textures[tid].glo == tid   # still alive
                    self.drawn.add(tid)


@pytest.fixture
def ui(ctx, monkeypatch):
    from tests.support.viewer import small_session, spy_renders
    from app.ui.engine import ViewerEngine
    from app.ui.filedialog import FileDialog
    from app.ui.drag import DragOwner
    from app.ui.textures import PanelTextures
    from app.ui.window import ViewerWindow
    from app.pbgi.renderer import Relighter
    calls = spy_renders(monkeypatch)           # the real renderer, micro-buffer 8
    engine = ViewerEngine(ctx, small_session(), size=(900, 600), relighter=Relighter)
    engine.frame()
    assert calls and engine.renderer_available and engine.gi_stats.completed
    w = ViewerWindow.__new__(ViewerWindow)          # the window's state without a window
    w.engine, w.session, w.ctx = engine, engine.session, ctx
    w.imgui, w.dialog = _Renderer(), FileDialog()
    w.selected_capture, w.gizmo_op, w.fly = 0, "translate", False
    w.hdr_task, w.hdr_status, w.demo_request, w.leftover = None, "", None, None
    w.textures = PanelTextures(ctx, w.imgui)
    w.hdr_report = {"alpha": 0.9, "counts": {"overexposed": 10, "expanded_by_projection": 8,
                                             "filled_by_poisson": 2, "unresolved": 0},
                    "warnings": ["a warning"]}
    w.pending_screenshot, w.last_screenshot, w.frame_intervals = None, [], [16.0]
    w._keys_down, w.drag = set(), DragOwner()
    ctx_imgui = imgui.create_context()
    io = imgui.get_io()
    io.set_ini_filename("")
    io.display_size = (900, 600)
    io.fonts.get_tex_data_as_rgba32()
    yield w
    imgui.destroy_context(ctx_imgui)


def _draw(ui, frames=3):
    from app.ui import overlay, panels
    for _ in range(frames):
        imgui.get_io().delta_time = 1 / 60
        imgui.new_frame()
        imguizmo.im_guizmo.begin_frame()
        overlay.draw(ui)
        panels.draw(ui)
        ui.dialog.draw()
        imgui.render()
        ui.imgui.render(imgui.get_draw_data())   # as the window does, then frees what panels
        ui.textures.end_frame()                  # dropped during the frame
    return imgui.get_draw_data()


def test_every_panel_draws_without_errors(ui, monkeypatch):
    from app.pbgi.stats import ShareFigures
    from app.ui import panels
    monkeypatch.setattr(panels, "OPEN_BY_DEFAULT", {t for t, _ in panels.SECTIONS})
    ui.engine.cloud.hdr = ui.engine.cloud.ldr          # as after an expansion: LDR/HDR toggle
    ui.engine.gi_stats.share = ShareFigures(share_blocks=12, share_receivers=300)  # Hybrid's line
    data = _draw(ui)
    assert not ui.engine.messages, [m.text for m in ui.engine.messages]
    assert data.cmd_lists_count >= 2                   # panel column + stats box (+ overlays)
    from app.ui.panels.hdr import PHOTO
    photo = ui.textures.get(PHOTO)
    assert photo is not None and photo.glo in ui.imgui.textures


def test_run_expansion_keeps_the_photo_texture_until_the_frame_is_drawn(ui, monkeypatch):
    """Regression: "Run expansion" dropped the photo thumbnail after imgui.image() had queued
    it, and the renderer found an unregistered texture at the end of the frame (the window
    closed, every time). The texture must outlive the frame, then be freed."""
    from app.ui import panels
    from app.ui.panels.hdr import PHOTO
    monkeypatch.setattr(panels, "OPEN_BY_DEFAULT", {"HDR expansion"})   # the thumbnail in view
    _draw(ui, 1)
    before = ui.textures.get(PHOTO)
    assert before is not None and before.glo in ui.imgui.drawn
    started = []
    monkeypatch.setattr(ui, "start_expansion", lambda: started.append(True), raising=False)
    real_button = imgui.button
    monkeypatch.setattr(imgui, "button", lambda label, *a: label == "Run expansion"
                        or real_button(label, *a))
    _draw(ui, 1)                      # the click frame: the renderer's check runs inside
    assert started == [True]
    assert before.glo not in ui.imgui.textures and ui.textures.retired == 0   # freed after it
    monkeypatch.setattr(imgui, "button", real_button)
    _draw(ui, 1)                      # the thumbnail comes back, a new texture
    after = ui.textures.get(PHOTO)
    assert after is not None and after.glo in ui.imgui.textures


def test_panel_textures_outlive_the_frame_they_are_dropped_in(ctx):
    """drop() and clear() retire; only end_frame() unregisters and frees."""
    from app.ui.textures import PanelTextures
    r = _Renderer()
    tex = PanelTextures(ctx, r)
    a = tex.set("a", np.zeros((4, 4, 3), np.uint8))
    b = tex.set("a", np.ones((4, 4, 3), np.uint8))      # replaces a: a is retired, not freed
    assert tex.get("a") is b and a.glo in r.textures and tex.retired == 1
    tex.clear()
    assert tex.get("a") is None and b.glo in r.textures and tex.retired == 2
    tex.end_frame()
    assert r.textures == {} and tex.retired == 0


def test_file_dialog_browses_and_returns_a_path(ui, tmp_path):
    from app.ui.filedialog import FileDialog
    ui.dialog = FileDialog(native=False)       # the imgui browser, even where zenity exists
    (tmp_path / "room.ply").write_text("ply")
    (tmp_path / "notes.txt").write_text("x")
    chosen = []
    ui.dialog.folder = tmp_path
    ui.dialog.open("Open a point cloud", (".ply",), chosen.append)
    _draw(ui, 2)
    assert ui.dialog.active and imgui.is_popup_open(ui.dialog.POPUP, imgui.PopupFlags_.any_popup_id)
    ui.dialog.name = "room.ply"
    ui.dialog._finish(str(tmp_path / ui.dialog.name))
    assert chosen == [str(tmp_path / "room.ply")] and not ui.dialog.active


def test_widgets_follow_the_settings_table(ui):
    """A setting changed through the model shows in the next frame's widget state, and the
    change reaches the engine's change set exactly once."""
    from app.params import PARAMS
    s = ui.session.settings
    s.take_changes()
    s.set("pbgi.microbuffer", 16)
    _draw(ui, 1)
    assert s.take_changes() == {"pbgi.microbuffer"}
    assert {k.split(".")[0] for k in (x.key for x in PARAMS)} == {"view", "light", "compare",
                                                                   "pbgi", "hdr"}


def test_engine_and_settings_do_not_import_the_ui():
    """Import contract: the model and the engine work without imgui or a window toolkit."""
    code = ("import sys, app.settings, app.ui.engine, app.ui.refine, app.ui.composite;"
            "bad = [m for m in ('imgui_bundle', 'moderngl_window', 'pyglet') if m in sys.modules];"
            "print(','.join(bad))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_capture_camera_list_edits(ui):
    from app.settings import CaptureCamera
    s = ui.session
    s.settings.take_changes()
    s.set_capture_cameras(s.capture_cameras + [CaptureCamera("extra", (0.0, 1.0, 0.0))])
    assert s.settings.take_changes() == {"capture_cameras"}
    ui.selected_capture = 1
    _draw(ui, 1)
    assert [c.name for c in s.capture_cameras] == ["capture 1", "extra"]
    np.testing.assert_allclose(s.capture_cameras[1].position, (0, 1, 0))


def _record_text(monkeypatch) -> list[tuple[str, str]]:
    """(function, text) of every imgui.text / text_disabled call while drawing."""
    seen = []
    for fn in ("text", "text_disabled"):
        real = getattr(imgui, fn)

        def record(text, *a, _fn=fn, _real=real):
            seen.append((_fn, text))
            return _real(text, *a)
        monkeypatch.setattr(imgui, fn, record)
    return seen


def test_provenance_legend_counts_the_points_of_each_label(ui, monkeypatch):
    """The provenance view's legend: per label, in PROVENANCE's order, its name, its number of
    points and its share of the cloud (counted here from the labels); the "show" row with the
    new choice still fits the panel."""
    from app.cloud import PointCloud
    from app.hdr.result import (POISSON, PROJECTED, PROVENANCE, PROVENANCE_ATTR, REGISTERED,
                                SCORE_ATTR, UNCHANGED, UNRESOLVED)
    from app.ui import panels, provenance
    monkeypatch.setattr(panels, "OPEN_BY_DEFAULT", {"HDR expansion"})
    ldr = ui.engine.cloud.ldr
    n = len(ldr)
    counts = {REGISTERED: 1234, PROJECTED: 5678, POISSON: 90, UNRESOLVED: 0}
    counts[UNCHANGED] = n - sum(counts.values())
    labels = np.concatenate([np.full(c, k, np.uint8) for k, c in counts.items()])
    labels = np.random.default_rng(1).permutation(labels)
    scores = np.where(labels == REGISTERED, 0.75, np.nan).astype(np.float32)
    ui.engine.cloud.hdr = PointCloud(ldr.positions, ldr.normals, ldr.colors, True,
                                     attributes={PROVENANCE_ATTR: labels, SCORE_ATTR: scores})
    ui.session.settings.set("view.cloud", "provenance")
    edges = []
    real_radio = imgui.radio_button

    def radio(label, active):
        pressed = real_radio(label, active)
        edges.append(imgui.get_item_rect_max().x)
        return pressed
    monkeypatch.setattr(imgui, "radio_button", radio)
    seen = _record_text(monkeypatch)
    _draw(ui, 2)
    assert not ui.engine.messages, [m.text for m in ui.engine.messages]
    texts = [t for _, t in seen]
    at = texts.index(PROVENANCE[UNCHANGED][0])
    rows = [texts[at + 3 * i: at + 3 * i + 3] for i in range(len(PROVENANCE))]
    assert rows == [[name, f"{counts[k]:,}", f"{100 * counts[k] / n:.1f} %"]
                    for k, (name, _) in PROVENANCE.items()]
    assert ("text_disabled", PROVENANCE[UNRESOLVED][0]) in seen     # no point: greyed
    assert provenance.Q_NOTE in texts and provenance.NO_PROVENANCE_LINE not in texts
    legend = provenance.legend(ui.engine.cloud.hdr)
    assert [r.srgb for r in legend] == [tuple(c / 255 for c in provenance.PALETTE[k])
                                        for k in PROVENANCE]
    assert legend[list(PROVENANCE).index(REGISTERED)].median_score == 0.75
    style = imgui.get_style()
    assert max(edges) <= panels.PANEL_WIDTH - style.window_padding.x    # no clipped choice
    room = panels.PANEL_WIDTH - 2 * style.window_padding.x - style.scrollbar_size
    for line in (provenance.Q_NOTE, provenance.NO_PROVENANCE_LINE):  # one unclipped line each
        assert imgui.calc_text_size(line).x <= room, line


def test_provenance_legend_says_when_the_cloud_has_none(ui, monkeypatch):
    """An HDR cloud without the provenance attribute (a file from before it, say): one line
    says so, the legend has no rows, and the points are grey."""
    from app.ui import panels, provenance
    monkeypatch.setattr(panels, "OPEN_BY_DEFAULT", {"HDR expansion"})
    ui.engine.cloud.hdr = ui.engine.cloud.ldr        # no attributes
    ui.session.settings.set("view.cloud", "provenance")
    seen = _record_text(monkeypatch)
    _draw(ui, 2)
    assert not ui.engine.messages, [m.text for m in ui.engine.messages]
    assert ("text_disabled", provenance.NO_PROVENANCE_LINE) in seen
    assert provenance.Q_NOTE not in [t for _, t in seen]
    grey = ui.engine.cloud.colors("provenance")
    assert np.all(grey == grey[0]) and np.ptp(grey[0]) == 0   # one neutral grey


def test_report_lists_the_registered_points(ui, monkeypatch):
    from app.ui import panels
    monkeypatch.setattr(panels, "OPEN_BY_DEFAULT", {"HDR expansion"})
    ui.hdr_report["counts"]["projected_from_registered_photo"] = 4321
    wrapped = []
    real = imgui.text_wrapped
    monkeypatch.setattr(imgui, "text_wrapped", lambda t, *a: (wrapped.append(t), real(t, *a))[1])
    _draw(ui, 1)
    assert any("4,321 from the registered photo" in t for t in wrapped), wrapped


def test_report_says_which_path_the_expansion_took():
    from app.ui.panels.hdr import path_line
    assert path_line({"path": "registered", "registration": {"quality": 0.75, "agree": 0.95}}) \
        == "path: registered photo (q = 0.75, 95% of its points agree with the scan)"
    assert path_line({"path": "matching", "registration": {"reason": "only 40% agree"}}) \
        == "path: matching (not registered: only 40% agree)"
    assert path_line({"path": "matching"}) == "path: matching (registration off)"
