"""What is drawn over the viewport itself: the asset transform gizmo (ImGuizmo), the capture
cameras, the refinement progress, the fly-mode hint and the message list."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui, imguizmo

from app.render.splat import near_far
from app.settings import AssetTransform

gizmo = imguizmo.im_guizmo
OPS = {"translate": gizmo.OPERATION.translate, "rotate": gizmo.OPERATION.rotate,
       "scale": gizmo.OPERATION.scale}
PANEL_X = 350  # status lines start right of the panel column (app/ui/panels PANEL_WIDTH)
COLOURS = {"error": (1.0, 0.45, 0.4, 1.0), "warning": (1.0, 0.8, 0.3, 1.0),
           "info": (0.6, 0.9, 0.6, 1.0)}


def _col(r, g, b, a=1.0) -> int:
    return imgui.get_color_u32((r, g, b, a))


def project(cam, points: np.ndarray):
    """(N, 2) window pixels (top-left origin) and (N,) in-front flags."""
    p = np.c_[np.asarray(points, float), np.ones(len(points))]
    near, far = 0.01, 1000.0
    clip = (cam.projection(near, far) @ cam.view() @ p.T).T
    w = clip[:, 3]
    front = w > 1e-6
    ndc = clip[:, :2] / np.where(front, w, 1.0)[:, None]
    xy = np.c_[(ndc[:, 0] + 1) / 2 * cam.width, (1 - ndc[:, 1]) / 2 * cam.height]
    return xy, front


def draw_capture_cameras(ui) -> None:
    s = ui.session
    if not s.settings["view.show_cameras"] or not s.capture_cameras:
        return
    cam = ui.engine.camera()
    dl = imgui.get_background_draw_list()
    half = 0.08
    cube = np.array([[x, y, z] for x in (-half, half) for y in (-half, half)
                     for z in (-half, half)])
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
    for i, c in enumerate(s.capture_cameras):
        pts = cube + np.asarray(c.position)
        xy, front = project(cam, np.vstack([pts, [c.position]]))
        if not front.all():
            continue
        sel = i == ui.selected_capture
        col = _col(1.0, 0.75, 0.2) if sel else _col(0.4, 0.8, 1.0)
        for a, b in edges:
            dl.add_line(tuple(xy[a]), tuple(xy[b]), col, 2.0 if sel else 1.0)
        dl.add_text((float(xy[8][0]) + 6, float(xy[8][1]) - 6), col, c.name)


def draw_asset_gizmo(ui) -> None:
    e, s = ui.engine, ui.session
    if not s.settings["view.show_gizmo"] or e.mesh is None or ui.fly:
        return
    w, h = e.size
    cam = e.camera()
    lo, hi = e.view.splat.bounds if e.view.splat is not None else (np.zeros(3), np.ones(3))
    mlo, mhi = e.mesh.bounds()
    near, far = near_far(cam, np.minimum(lo, mlo), np.maximum(hi, mhi))
    view = gizmo.Matrix16(list(cam.view().flatten(order="F")))
    proj = gizmo.Matrix16(list(cam.projection(near, far).flatten(order="F")))
    obj = gizmo.Matrix16(list(s.transform.matrix().flatten(order="F")))
    gizmo.set_drawlist(imgui.get_background_draw_list())
    gizmo.set_rect(0, 0, w, h)
    gizmo.set_orthographic(False)
    if gizmo.manipulate(view, proj, OPS[ui.gizmo_op], gizmo.MODE.world, obj):
        m = np.asarray(obj.values, np.float64).reshape(4, 4, order="F")
        new = AssetTransform.from_matrix(m)
        if ui.gizmo_op == "translate":  # keep rotation/scale bit-exact while moving
            new = AssetTransform(new.translate, s.transform.rotate_deg, s.transform.scale)
        s.set_transform(new)


def draw_status(ui) -> None:
    e = ui.engine
    w, h = e.size
    dl = imgui.get_foreground_draw_list()
    lines = []
    if ui.fly:
        lines.append(("FLY: W A S D move, Q / E down / up, drag to look, wheel = speed "
                      f"({ui.session.settings['view.fly_speed']:.2g} m/s), Esc leaves",
                      (1, 0.85, 0.3)))
    if not e.renderer_available:
        lines.append(("relighting renderer unavailable: " + (e.relighter_error or "?"),
                      (1, 0.6, 0.5)))
    if e.gi.refining and e.renderer_available:
        frac = e.gi.progress
        bar_w = 220
        x0, y0 = w - bar_w - 12, h - 26
        dl.add_rect_filled((x0, y0), (x0 + bar_w, y0 + 14), _col(0, 0, 0, 0.6), 3)
        dl.add_rect_filled((x0, y0), (x0 + bar_w * frac, y0 + 14), _col(0.3, 0.6, 1.0, 0.9), 3)
        label = e.gi.status_words()       # "refining 40%, about 6 s left"
        backed_text(dl, (x0 - 12 - imgui.calc_text_size(label).x, y0), label, (1, 1, 1))
    if e.b_refining:
        lines.append((f"B (compare): {e.gi_b.status_words()}", (0.7, 0.9, 1.0)))
    task = ui.hdr_task
    if task is not None and task.running:
        _, frac, stage = task.snapshot()
        lines.append((f"HDR expansion running: {stage} {100 * frac:.0f}% (HDR panel: Cancel)",
                      (0.6, 0.85, 1.0)))
    if ui.pending_screenshot:
        lines.append((f"screenshot waits for the refinement ({100 * e.gi.progress:.0f}%)",
                      (0.7, 0.9, 1.0)))
    y = h - 26 - 18 * len(lines)
    for text, c in lines:
        backed_text(dl, (PANEL_X + 8, y), text, c)
        y += 18


def backed_text(dl, pos, text: str, colour) -> None:
    """Text on a dark rounded backing, readable over any part of the room."""
    x, y = pos
    size = imgui.calc_text_size(text)
    dl.add_rect_filled((x - 4, y - 2), (x + size.x + 4, y + size.y + 2), _col(0, 0, 0, 0.7), 3)
    dl.add_text((x, y), _col(*colour), text)


def draw_messages(ui) -> None:
    msgs = ui.engine.messages
    if not msgs:
        return
    w, h = ui.engine.size
    imgui.set_next_window_pos((w / 2, 10), imgui.Cond_.always, (0.5, 0.0))
    imgui.set_next_window_bg_alpha(0.85)
    flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize |
             imgui.WindowFlags_.no_saved_settings | imgui.WindowFlags_.no_focus_on_appearing)
    imgui.begin("##messages", None, flags)
    for m in msgs[-5:]:
        imgui.push_text_wrap_pos(imgui.get_font_size() * 45)
        imgui.text_colored(COLOURS.get(m.level, COLOURS["error"]), m.text)
        imgui.pop_text_wrap_pos()
    if imgui.small_button("dismiss"):
        msgs.clear()
    imgui.end()


DIVIDER_GRIP = 12   # pixels either side of the A/B divider that grab it


def draw_divider(ui) -> None:
    """The A/B compare's divider (drawn by the composite) as a handle: an invisible imgui
    button over it, so dragging it moves ``compare.split`` rather than orbiting the view."""
    from app.ui.compare import split_column
    e, s = ui.engine, ui.session.settings
    if not (s["compare.enabled"] and e.compare_labels):
        return
    w, h = e.size
    x = split_column(s["compare.split"], w)
    imgui.set_next_window_pos((x - DIVIDER_GRIP, 0), imgui.Cond_.always)
    imgui.set_next_window_size((2 * DIVIDER_GRIP, h), imgui.Cond_.always)
    flags = (imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.no_background |
             imgui.WindowFlags_.no_saved_settings | imgui.WindowFlags_.no_focus_on_appearing |
             imgui.WindowFlags_.no_nav | imgui.WindowFlags_.no_move)
    imgui.push_style_var(imgui.StyleVar_.window_padding, (0, 0))
    imgui.begin("##ab divider", None, flags)
    imgui.invisible_button("##divider", (2 * DIVIDER_GRIP, h))
    if imgui.is_item_hovered() or imgui.is_item_active():
        imgui.set_mouse_cursor(imgui.MouseCursor_.resize_ew)
    if imgui.is_item_active():
        s.set("compare.split", min(max(imgui.get_io().mouse_pos.x / max(w, 1), 0.0), 1.0))
    imgui.end()
    imgui.pop_style_var()


def draw(ui) -> None:
    draw_divider(ui)
    draw_capture_cameras(ui)
    draw_asset_gizmo(ui)
    draw_status(ui)
    draw_messages(ui)
