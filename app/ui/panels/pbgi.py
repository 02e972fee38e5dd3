"""PBGI: mode, micro-buffer, render scales, Hybrid's Omega_tr factor and parallax tolerance,
live stats of the gather."""

from __future__ import annotations

from imgui_bundle import imgui

from app.ui import widgets


def draw(ui) -> None:
    e = ui.engine
    widgets.panel_group(ui.session.settings, "pbgi")
    if not e.renderer_available:
        imgui.text_colored((1, 0.6, 0.5, 1), "renderer unavailable")
        imgui.text_wrapped(e.relighter_error or "")
        return
    st = e.gi_stats
    if st:
        imgui.separator_text("last gather")
        imgui.text(f"mode {st.get('mode', '?')}   {st.get('ms', 0):.1f} ms per pass")
        imgui.text(f"nodes visited {int(st.get('nodes_visited', 0) or 0):,}")
        imgui.text(f"extra memory {float(st.get('mb', 0) or 0):.1f} MB   "
                   f"M = {st.get('microbuffer', '?')}")
        imgui.text(f"last tile {st.get('width', '?')} x {st.get('height', '?')} px"
                   + ("" if st.get("completed", True) else "   INCOMPLETE"))
        if st.get("share_blocks"):
            shared = st.get("share_receivers", 0) / max(st.get("receivers", 1) or 1, 1)
            imgui.text(f"far field shared by {int(st['share_blocks']):,} blocks "
                       f"({100 * shared:.0f}% of pixels)")
