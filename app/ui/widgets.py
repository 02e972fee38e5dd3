"""imgui widgets derived from the settings table: one call draws the right control for a key,
with its unit and tooltip, and writes the value back through Settings.set (which records the
change for the engine)."""

from __future__ import annotations

from imgui_bundle import imgui

from app.settings import BY_KEY, Settings


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
        changed, new = imgui.slider_int(label, int(value), int(spec.lo), int(spec.hi),
                                        f"%d {spec.unit}".strip())
    else:
        flags = imgui.SliderFlags_.logarithmic if spec.log else 0
        digits = "%.0f" if spec.hi >= 100 else "%.3g" if spec.log else "%.2f"
        fmt = f"{digits} {spec.unit}".strip()
        changed, new = imgui.slider_float(label, float(value), float(spec.lo), float(spec.hi),
                                          fmt, flags)
    tip = spec.tooltip + (f"  [{spec.unit}]" if spec.unit else "") + \
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
