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
    # The same five lines in every mode and before the first gather, so switching mode never
    # moves the widgets below (the BRDF sliders) under the cursor.
    imgui.separator_text("last gather")
    if st is None:
        lines = ["mode -", "nodes visited -", "extra memory -", "last tile -"]
    else:
        handed = (f" (for {st.envmap_instead_of}: the asset is {st.clearance:.1f} radii "
                  f"from the scan)" if st.envmap_instead_of else "")
        lines = [f"mode {st.mode}   {st.ms:.1f} ms per pass" + handed,
                 f"nodes visited {int(st.nodes_visited):,}",
                 f"extra memory {st.mb:.1f} MB   M = {st.microbuffer}",
                 f"last tile {st.width} x {st.height} px"
                 + ("" if st.completed else "   INCOMPLETE")]
    for line in lines:
        imgui.text(line)
    if st is not None and st.share is not None and st.share.share_blocks:
        shared = st.share.share_receivers / max(st.receivers, 1)
        imgui.text(f"far field shared by {st.share.share_blocks:,} blocks "
                   f"({100 * shared:.0f}% of pixels)")
    else:
        imgui.text_disabled("far field shared: Hybrid only")
