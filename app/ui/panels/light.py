"""Light & compare: what lights the asset (the scan, or an HDRI file turned by a rotation) and
the A/B compare (what B changes, the divider, and B against A's metrics once both are
refined). Only the session is edited here; the engine picks the changes up."""

from __future__ import annotations

from pathlib import Path

from imgui_bundle import imgui

from app.ui import widgets
from app.ui.compare import metrics_lines


def draw(ui) -> None:
    s, e = ui.session, ui.engine
    widgets.panel_group(s.settings, "light")
    imgui.text(f"HDRI: {Path(s.hdri).name if s.hdri else '(none)'}")
    imgui.same_line()
    if imgui.small_button("open##hdri"):
        from app.ui.files import open_hdri
        ui.dialog.open("Open an HDRI (equirectangular EXR)", (".exr",),
                       lambda p: e.guard(f"opening {Path(p).name}", open_hdri, s, p))
    widgets.tooltip("An equirectangular EXR panorama lights the asset through the environment "
                    "map and is shown behind it. Dropping an .exr onto the window opens it as "
                    "the HDR photo of the expansion, not as the HDRI: open it here.")
    imgui.separator_text("A/B compare")
    widgets.panel_group(s.settings, "compare")
    if not s.settings["compare.enabled"]:
        return
    if e.compare_labels:
        imgui.text("   ".join(e.compare_labels))
    widgets.tooltip("A is left of the divider, B right of it; drag the divider in the viewport.")
    for line in metrics_lines(e.compare_metrics):
        imgui.text(line)
    widgets.tooltip("B against A over the asset pixels both cover, as render --compare "
                    "computes them (app/commands/compare.py).")
