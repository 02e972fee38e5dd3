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
    w._keys_down, w._dragging = set(), False
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
    assert {k.split(".")[0] for k in (x.key for x in PARAMS)} == {"view", "pbgi", "hdr"}


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
