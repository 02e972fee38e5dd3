"""The prompt after a crash: restore the autosaved session, discard it, or decide later.

Shown over the viewport at the window's first frames when app/ui/autosave.py found a session
whose window did not close normally. "Later" keeps the files, so the question comes back at the
next start; nothing is deleted unless the user says so.
"""

from __future__ import annotations

from imgui_bundle import imgui

from app.ui import autosave

WIDTH_EMS = 34


def draw(ui) -> None:
    left = ui.leftover
    if left is None:
        return
    w, h = ui.engine.size
    imgui.set_next_window_pos((w / 2, h / 2), imgui.Cond_.always, (0.5, 0.5))
    imgui.set_next_window_size((imgui.get_font_size() * WIDTH_EMS, 0), imgui.Cond_.always)
    imgui.set_next_window_bg_alpha(0.96)
    flags = (imgui.WindowFlags_.no_collapse | imgui.WindowFlags_.no_saved_settings |
             imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_move)
    imgui.begin("Restore the last session?", None, flags)
    imgui.text_wrapped("Scanlight did not close normally last time. Its session was autosaved:")
    imgui.text_wrapped(left.describe())
    imgui.spacing()
    if imgui.button("Restore"):
        ui.engine.guard("restoring the autosaved session", ui.restore_leftover, left)
        ui.leftover = None
    imgui.same_line()
    if imgui.button("Discard"):
        ui.engine.guard("discarding the autosave", autosave.discard, left)
        ui.leftover = None
    imgui.same_line()
    if imgui.button("Later"):
        ui.leftover = None
    imgui.end()
