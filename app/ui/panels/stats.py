"""Stats box (top right): frame time, room and GI timings, refinement state."""

from __future__ import annotations

from imgui_bundle import imgui


def draw(ui) -> None:
    e = ui.engine
    w, _ = e.size
    st = e.stats()
    imgui.set_next_window_pos((w - 10, 10), imgui.Cond_.always, (1.0, 0.0))
    imgui.set_next_window_bg_alpha(0.6)
    flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize |
             imgui.WindowFlags_.no_saved_settings | imgui.WindowFlags_.no_focus_on_appearing |
             imgui.WindowFlags_.no_nav)
    imgui.begin("##stats", None, flags)
    recent = ui.frame_intervals[-60:] or [st["frame_ms"]]
    mean = sum(recent) / len(recent)
    imgui.text(f"frame {mean:.0f} ms (max {max(recent):.0f})  {1000.0 / max(mean, 1e-3):.1f} fps")
    imgui.text(f"room {st.get('room_ms', 0):.0f} ms   GI {st.get('gi_frame_ms', 0):.0f} ms/frame")
    if e.renderer_available:
        mode = ui.session.settings["pbgi.mode"]
        imgui.text(f"{mode}: {e.gi.status_words()}")
        gi = e.gi_stats
        if gi is not None:
            imgui.text(f"gather {gi.ms:.0f} ms, {int(gi.nodes_visited):,} nodes, {gi.mb:.0f} MB")
    else:
        imgui.text_colored((1, 0.6, 0.5, 1), "renderer unavailable")
    imgui.end()
