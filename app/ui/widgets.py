"""imgui widgets derived from the parameter table (app/params.py): one call draws the right
control for a key, with its unit and tooltip, and writes the value back through Settings.set
(which records the change for the engine); ``panel_group`` draws every ``ui`` row of a group in
the table's order."""

from __future__ import annotations

from imgui_bundle import imgui

from app.params import BY_KEY, group as table_group
from app.settings import Settings


TOOLTIP_EMS = 28   # tooltip text wraps at this many font heights, so it never leaves the window


def tooltip(text: str) -> None:
    """``text`` in a wrapped tooltip when the last item is hovered (disabled items too: a greyed
    widget says why it is greyed)."""
    flags = imgui.HoveredFlags_.delay_short | imgui.HoveredFlags_.allow_when_disabled
    if text and imgui.is_item_hovered(flags):
        imgui.begin_tooltip()
        imgui.push_text_wrap_pos(imgui.get_font_size() * TOOLTIP_EMS)
        imgui.text_unformatted(text)
        imgui.pop_text_wrap_pos()
        imgui.end_tooltip()


def choice(label: str, value: str, choices) -> tuple[bool, str]:
    """A combo box of ``choices`` built from selectables, so every entry is an ordinary item
    (hover, click, automation) rather than a string inside one widget."""
    new = value
    if imgui.begin_combo(label, value):
        for c in choices:
            if imgui.selectable(c, c == value)[0]:
                new = c
            if c == value:
                imgui.set_item_default_focus()
        imgui.end_combo()
    return new != value, new


def setting(settings: Settings, key: str, width: float = -1.0) -> bool:
    """Draw the control for ``key``; True when the user changed it this frame."""
    spec = BY_KEY[key]
    label = f"{spec.title}##{key}"
    value = settings[key]
    changed = False
    idle = not spec.applies(settings)
    imgui.begin_disabled(idle)
    imgui.set_next_item_width(width if width > 0 else imgui.get_content_region_avail().x * 0.6)
    if spec.kind == "bool":
        changed, new = imgui.checkbox(label, bool(value))
    elif spec.kind == "choice":
        changed, new = choice(label, value, spec.choices)
    elif spec.kind == "int":
        lo, hi = spec.slider_range
        changed, new = imgui.slider_int(label, int(value), int(lo), int(hi),
                                        f"%d {spec.unit}".strip())
    else:
        flags = imgui.SliderFlags_.logarithmic if spec.log else 0
        lo, hi = spec.slider_range
        digits = "%.0f" if hi >= 100 else "%.3g" if spec.log else "%.2f"
        fmt = f"{digits} {spec.unit}".strip()
        changed, new = imgui.slider_float(label, float(value), float(lo), float(hi),
                                          fmt, flags)
    imgui.end_disabled()
    tip = spec.help + (f"  [{spec.unit}]" if spec.unit else "") + \
        "  (right-click: reset to default)"
    if idle:
        k, values = spec.when
        tip = f"Not used now: only when {BY_KEY[k].title} is {' or '.join(values)}. " + tip
    tooltip(tip)
    if imgui.is_item_clicked(imgui.MouseButton_.right):
        settings.reset(key)
        return True
    return bool(changed) and settings.set(key, new)


def group(settings: Settings, keys) -> bool:
    changed = False
    for key in keys:
        changed |= setting(settings, key)
    return changed


def panel_group(settings: Settings, name: str) -> bool:
    """Every parameter of group ``name`` that the table marks ``ui``, in the table's order."""
    return group(settings, [p.key for p in table_group(name, ui_only=True)])


def apply_style() -> None:
    """The dark style with thin, translucent slider handles: imgui writes a slider's value in
    the middle of its frame, and a wide opaque handle sitting there hid the number."""
    imgui.style_colors_dark()
    style = imgui.get_style()
    style.grab_min_size = 5.0
    style.grab_rounding = 2.0
    style.frame_rounding = 2.0
    style.set_color_(imgui.Col_.slider_grab, (0.35, 0.6, 1.0, 0.45))
    style.set_color_(imgui.Col_.slider_grab_active, (0.45, 0.7, 1.0, 0.65))
