"""BRDF: every Disney Principled parameter of the selected material, presets, reset."""

from __future__ import annotations

from imgui_bundle import imgui

from app.material import PRESETS, SCALAR_PARAMS
from app.ui.widgets import tooltip


def draw(ui) -> None:
    s, e = ui.session, ui.engine
    mats = s.materials or []
    if not mats:
        imgui.text_disabled("no asset")
        return
    idx = getattr(ui, "selected_material", 0)
    if idx >= len(mats):
        idx = 0
    if len(mats) > 1:
        _, idx = imgui.combo("material", idx, [f"{i}: {m.name}" for i, m in enumerate(mats)])
    ui.selected_material = idx
    m = mats[idx]
    if imgui.begin_combo("preset", "apply a preset..."):
        for name, values in PRESETS.items():
            if imgui.selectable(name, False)[0]:
                s.set_material(idx, values)
        imgui.end_combo()
    tooltip("Sets the preset's parameters on this material (others keep their values).")
    imgui.same_line()
    if imgui.small_button("reset"):
        e.reset_materials()
        return
    tooltip("Back to the asset's own material values.")
    changed, rgb = imgui.color_edit3("base colour", list(m.base_color),
                                     imgui.ColorEditFlags_.float)
    tooltip("Linear RGB base colour (albedo of the diffuse lobe, F0 tint of metals).")
    if changed:
        s.set_material(idx, {"base_color": rgb})
    for p in SCALAR_PARAMS:
        imgui.set_next_item_width(imgui.get_content_region_avail().x * 0.6)
        changed, v = imgui.slider_float(p.name.replace("_", " "), float(getattr(m, p.name)),
                                        p.lo, p.hi, "%.3f")
        tooltip(p.tooltip + "  (right-click: default)")
        if imgui.is_item_clicked(imgui.MouseButton_.right):
            changed, v = True, p.default
        if changed:
            s.set_material(idx, {p.name: v})
    textured = m.base_color_texture is not None or m.metallic_roughness_texture is not None
    imgui.text_disabled("textures multiply these factors" if textured else "no textures")
