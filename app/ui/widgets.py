"""imgui widgets derived from the parameter table (app/params.py): one call draws the right
control for a key, with its unit and tooltip, and writes the value back through Settings.set
(which records the change for the engine); ``panel_group`` draws every ``ui`` row of a group in
the table's order."""

from __future__ import annotations

from imgui_bundle import imgui

from app.params import BY_KEY, group as table_group
from app.settings import Settings


def tooltip(text: str) -> None:
    if text and imgui.is_item_hovered(imgui.HoveredFlags_.delay_short):
        imgui.set_tooltip(text)


def setting(settings: Settings, key: str, width: float = -1.0) -> bool:
    """Draw the control for ``key``; True when the user changed it this frame."""
    spec = BY_KEY[key]
    label = f"{spec.title}##{key}"
    value = settings[key]
    changed = False
    imgui.set_next_item_width(width if width > 0 else imgui.get_content_region_avail().x * 0.6)
    if spec.kind == "bool":
        changed, new = imgui.checkbox(label, bool(value))
    elif spec.kind == "choice":
        idx = spec.choices.index(value)
        changed, idx = imgui.combo(label, idx, list(spec.choices))
        new = spec.choices[idx]
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
    tip = spec.help + (f"  [{spec.unit}]" if spec.unit else "") + \
        "  (right-click: reset to default)"
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
