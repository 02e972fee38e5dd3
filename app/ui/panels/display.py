"""Display: exposure (snapped to 1/3 stops while Shift is held, as cameras step it), tone mapper,
the false-colour EV view with its legend, which cloud colours, field of view, splat size,
gizmos."""

from __future__ import annotations

from imgui_bundle import imgui

from app.params import group as table_group
from app.render import tonemap
from app.ui import widgets

EV_SNAPS_PER_STOP = 3   # third stops: the step of camera exposure dials


def snap_ev(ev: float, per_stop: int = EV_SNAPS_PER_STOP) -> float:
    """``ev`` rounded to the nearest 1/``per_stop`` stop (n / 3 exactly, so +-10 stays +-10)."""
    return round(float(ev) * per_stop) / per_stop


def swatch_legend(table_id: str, rows, tip: str = "") -> None:
    """A table of colour swatches and their meaning: ``rows`` of (text, display sRGB colour)."""
    flags = imgui.TableFlags_.sizing_fixed_fit | imgui.TableFlags_.no_host_extend_x
    if imgui.begin_table(table_id, 2, flags):
        side = imgui.get_text_line_height()
        for text, rgb in rows:
            imgui.table_next_row()
            imgui.table_next_column()
            imgui.color_button(f"##{table_id}{text}", (*rgb, 1.0),
                               imgui.ColorEditFlags_.no_tooltip, (side, side))
            imgui.table_next_column()
            imgui.text(text)
            widgets.tooltip(tip)
        imgui.end_table()


def _exposure(settings) -> None:
    """The exposure slider; with Shift held the value it is dragged to snaps to 1/3 stops."""
    if widgets.setting(settings, "view.exposure") and imgui.get_io().key_shift:
        settings.set("view.exposure", snap_ev(settings["view.exposure"]))


def draw(ui) -> None:
    settings = ui.session.settings
    for p in table_group("view", ui_only=True):
        if p.key == "view.exposure":
            _exposure(settings)
        else:
            widgets.setting(settings, p.key)
        if p.key == "view.false_colour" and settings[p.key]:
            swatch_legend("false colour legend", tonemap.false_colour_legend(),
                          "Luminance x 2^exposure in stops around middle grey (0.18).")
