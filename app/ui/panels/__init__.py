"""The panels: one module each, drawn into one docked column on the left of the viewport
(collapsing sections) plus the stats box at the top right. Each panel only edits the session
(through Settings.set / Session.set_*), and the engine picks the changes up next frame."""

from __future__ import annotations

from imgui_bundle import imgui

from app.ui.panels import brdf, capture, display, hdr, light, pbgi, scene, stats

PANEL_WIDTH = 340
SECTIONS = (("Scene", scene), ("Capture cameras", capture), ("HDR expansion", hdr),
            ("PBGI", pbgi), ("BRDF", brdf), ("Light & compare", light), ("Display", display))
OPEN_BY_DEFAULT = {"Scene", "BRDF", "PBGI"}


def draw(ui) -> None:
    w, h = ui.engine.size
    imgui.set_next_window_pos((0, 0), imgui.Cond_.always)
    imgui.set_next_window_size((PANEL_WIDTH, h), imgui.Cond_.always)
    imgui.set_next_window_bg_alpha(0.92)
    flags = (imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize |
             imgui.WindowFlags_.no_collapse | imgui.WindowFlags_.no_saved_settings)
    imgui.begin("Scanlight", None, flags)
    for title, module in SECTIONS:
        open_flag = imgui.TreeNodeFlags_.default_open if title in OPEN_BY_DEFAULT else 0
        if imgui.collapsing_header(title, open_flag):
            imgui.push_id(title)
            ui.engine.guard(f"{title} panel", module.draw, ui)
            imgui.pop_id()
    imgui.end()
    stats.draw(ui)
