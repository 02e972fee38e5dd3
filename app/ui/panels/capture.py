"""Capture cameras: add at the viewpoint, select, rename, move to, delete, cube-map preview."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui

from app.settings import CaptureCamera
from app.ui.widgets import tooltip

PREVIEW_FACE = 64
PREVIEW = "capture preview"   # its texture's name in ui.textures (app/ui/textures.py)
LIST_ROWS = 4


def draw(ui) -> None:
    s, e = ui.session, ui.engine
    cams = s.capture_cameras
    if imgui.button("add capture camera here"):
        n = len(cams) + 1
        names = {c.name for c in cams}
        while f"capture {n}" in names:
            n += 1
        s.set_capture_cameras(cams + [CaptureCamera(f"capture {n}", tuple(e.nav.position))])
        ui.selected_capture = len(s.capture_cameras) - 1
        cams = s.capture_cameras
    tooltip("The HDR expansion renders a cube map of the scan from each capture position.")
    # A fixed-height list, the editing rows always present (greyed out with no selection) and
    # the preview's space reserved: adding or deleting a camera never moves what is below.
    rows = imgui.get_text_line_height_with_spacing() * LIST_ROWS + 8
    imgui.begin_child("captures", (0, rows), imgui.ChildFlags_.borders)
    if not cams:
        imgui.text_disabled("no capture cameras")
    for i, c in enumerate(cams):
        if imgui.selectable(f"{c.name}##{i}", i == ui.selected_capture)[0]:
            ui.selected_capture = i
            ui.textures.drop(PREVIEW)
    imgui.end_child()
    i = ui.selected_capture
    selected = 0 <= i < len(cams)
    c = cams[i] if selected else CaptureCamera("", (0.0, 0.0, 0.0))
    imgui.begin_disabled(not selected)
    changed, name = imgui.input_text("name", c.name)
    if selected and changed and name.strip():
        cams[i] = CaptureCamera(name, c.position)
        s.set_capture_cameras(list(cams))
    changed, pos = imgui.drag_float3("position (m)", list(c.position), 0.01, 0, 0, "%.3f")
    if selected and changed:
        cams[i] = CaptureCamera(cams[i].name, tuple(pos))
        s.set_capture_cameras(list(cams))
        ui.textures.drop(PREVIEW)
    if imgui.button("move to") and selected:
        centre, _ = e.asset_sphere()
        target = centre if np.linalg.norm(centre - np.asarray(c.position)) > 1e-6 else \
            np.asarray(c.position) + (0, 0, -1)
        e.nav.look_from(c.position, target)
    imgui.same_line()
    if imgui.button("delete") and selected:
        s.set_capture_cameras(cams[:i] + cams[i + 1:])
        ui.selected_capture = min(i, len(s.capture_cameras) - 1)
        ui.textures.drop(PREVIEW)
    imgui.same_line()
    if imgui.button("preview cube map") and selected:
        img = e.guard("rendering the cube-map preview", e.capture_preview, c.position, PREVIEW_FACE)
        if img is not None:
            ui.textures.set(PREVIEW, img)
    imgui.end_disabled()
    avail = imgui.get_content_region_avail().x
    tex = ui.textures.get(PREVIEW)
    if tex is None:
        imgui.dummy((avail, avail * 3 / 4))      # the cross is 4 faces wide, 3 high
        return
    imgui.image(tex.glo, (avail, avail * 3 / 4))
    tooltip("-X, -Z, +X, +Z around the middle row; up (+Y) above and down (-Y) below -Z")
