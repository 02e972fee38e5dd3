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
    """Stands in for the imgui GL renderer: only texture registration is used by panels."""

    def __init__(self):
        self.textures = {}

    def register_texture(self, tex):
        self.textures[tex.glo] = tex

    def remove_texture(self, tex):
        del self.textures[tex.glo]


@pytest.fixture
def ui(ctx, monkeypatch):
    from tests.support.viewer import small_session, spy_renders
    from app.ui.engine import ViewerEngine
    from app.ui.filedialog import FileDialog
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
    w.capture_texture = w.photo_texture = w.hdr_task = None
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
    assert ui.photo_texture is not None and ui.photo_texture.glo in ui.imgui.textures


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
