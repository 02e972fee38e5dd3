"""HDR expansion: the photo and the exposure found, method and thresholds, Run / Cancel with
progress while the job runs in the background, then LDR / HDR / difference / provenance, with
the provenance legend (app/ui/provenance.py) or the difference map's legend (stops added,
app/ui/scene.py) while that view is shown."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui

from app.params import BY_KEY
from app.ui import provenance, widgets
from app.ui.widgets import tooltip

THUMB = 256
PHOTO = "photo"   # the thumbnail's name in ui.textures (app/ui/textures.py)


def _photo_thumbnail(ui):
    from app.render.tonemap import tonemap_to_srgb8
    photo = ui.engine.photo
    h, w = photo.shape[:2]
    step = max(1, int(np.ceil(max(h, w) / THUMB)))
    small = photo[::step, ::step]
    alpha = (ui.hdr_report or {}).get("alpha")
    # Shown as the scan saw it when the exposure is known (alpha x photo), else as is.
    ev = float(np.log2(alpha)) if alpha else ui.session.settings["view.exposure"]
    return ui.textures.set(PHOTO, tonemap_to_srgb8(small, ev))


REPORT_LINES = 6   # the report area's fixed height, in lines: the panel never reflows


def _photo(ui) -> None:
    e = ui.engine
    avail = imgui.get_content_region_avail().x
    if e.photo is None:
        imgui.text_disabled("no HDR photo: open one in the Scene panel")
        imgui.text("exposure: -")
        return
    tex = ui.textures.get(PHOTO) or _photo_thumbnail(ui)
    tw, th = tex.size
    imgui.image(tex.glo, (avail, avail * th / tw))
    alpha = (ui.hdr_report or {}).get("alpha")
    imgui.text(f"exposure found: alpha = {alpha:.4g} ({np.log2(alpha):+.2f} EV)" if alpha
               else "exposure: found when the expansion runs")


def _run_controls(ui) -> None:
    """Run and Cancel on one row, the job's progress bar under them: always both rows, greyed
    out when they do not apply."""
    s, e = ui.session, ui.engine
    task = ui.hdr_task
    running = task is not None and task.running
    missing = ("open an HDR photo first" if e.photo is None else
               "add a capture camera first" if not s.capture_cameras else "")
    imgui.begin_disabled(running or bool(missing))
    if imgui.button("Run expansion"):
        e.guard("starting the HDR expansion", ui.start_expansion)
        ui.textures.drop(PHOTO)   # re-made with the alpha found; freed after this frame
    imgui.end_disabled()
    tooltip("Running in the background: Cancel stops it." if running else
            missing or "Runs in the background; the viewport stays interactive.")
    imgui.same_line()
    imgui.begin_disabled(not running)
    if imgui.button("Cancel") and running:
        task.cancel()
    imgui.end_disabled()
    if running:
        _, frac, stage = task.snapshot()
        imgui.progress_bar(frac, (-1, 0), f"{stage} {100 * frac:.0f}%")
    else:
        imgui.progress_bar(0.0, (-1, 0), ui.hdr_status or "idle")


SHOW_TIPS = {
    "ldr": "The scan's clipped LDR colours; the asset is lit by them too.",
    "hdr": "The HDR-expanded colours, which light the asset.",
    "difference": "log2(Y_hdr / Y_ldr) per point, black = unchanged, white = 6 stops; the asset "
                  "stays lit by the HDR cloud.",
    "provenance": "Where each point's HDR colour came from, in false colour (legend below); the "
                  "asset stays lit by the HDR cloud.",
}


def _show_choice(ui) -> None:
    s, e = ui.session, ui.engine
    imgui.separator_text("show")
    has_hdr = e.cloud is not None and e.cloud.hdr is not None
    imgui.begin_disabled(not has_hdr)
    cur = s.settings["view.cloud"]
    for i, name in enumerate(BY_KEY["view.cloud"].choices):
        if i:
            imgui.same_line()
        if imgui.radio_button(name.upper() if name in ("ldr", "hdr") else name, cur == name):
            s.settings.set("view.cloud", name)
        tooltip(SHOW_TIPS.get(name, "") if has_hdr else "Available once the expansion has run.")
    imgui.end_disabled()
    if cur == "provenance":
        _legend(ui)
    elif cur == "difference" and has_hdr:
        from app.ui.panels.display import swatch_legend
        from app.ui.scene import difference_legend
        swatch_legend("difference legend", difference_legend(),
                      "log2(Y_hdr / Y_ldr): the light the expansion added to each point.")


def _legend(ui) -> None:
    """Swatch, name, points and share of each provenance label of the cloud that lights the
    asset (the one shown), or one line saying it has none (its points are grey)."""
    e = ui.engine
    rows = provenance.legend(e.cloud.lighting("provenance") if e.cloud is not None else None)
    if rows is None:
        imgui.text_disabled(provenance.NO_PROVENANCE_LINE)
        tooltip("Only an expansion by this version records it (saved in the HDR cloud's PLY as "
                "the 'provenance' property): run the expansion again to see it.")
        return
    flags = imgui.TableFlags_.sizing_fixed_fit | imgui.TableFlags_.no_host_extend_x
    if imgui.begin_table("provenance legend", 4, flags):
        side = imgui.get_text_line_height()
        for r in rows:
            imgui.table_next_row()
            imgui.table_next_column()
            imgui.color_button(f"##swatch{r.label}", (*r.srgb, 1.0),
                               imgui.ColorEditFlags_.no_tooltip, (side, side))
            imgui.table_next_column()
            (imgui.text if r.count else imgui.text_disabled)(r.name)
            score = "" if np.isnan(r.median_score) else f"\nmedian score: {r.median_score:.3g}"
            tooltip(f"score: {r.meaning}{score}")
            imgui.table_next_column()
            _right_aligned(f"{r.count:,}")
            imgui.table_next_column()
            _right_aligned(f"{100 * r.share:.1f} %")
        imgui.end_table()
    imgui.text_disabled(provenance.Q_NOTE)


def _right_aligned(text: str) -> None:
    pad = imgui.get_content_region_avail().x - imgui.calc_text_size(text).x
    if pad > 0:
        imgui.set_cursor_pos_x(imgui.get_cursor_pos_x() + pad)
    imgui.text(text)


def path_line(rep: dict) -> str:
    """Which path the expansion took, in one line (the report's "path" and "registration")."""
    reg = rep.get("registration") or {}
    if rep.get("path") == "registered":
        return (f"path: registered photo (q = {reg.get('quality', 0):.2f}, "
                f"{reg.get('agree', 0):.0%} of its points agree with the scan)")
    if reg:
        return f"path: matching (not registered: {reg.get('reason', '?')})"
    return "path: matching (registration off)" if rep.get("path") == "matching" else ""


def _report(ui) -> None:
    rep = ui.hdr_report
    h = imgui.get_text_line_height_with_spacing() * REPORT_LINES + 4
    imgui.begin_child("report", (0, h))
    if not rep:
        imgui.text_disabled("no expansion yet")
    else:
        c = rep.get("counts", {})
        imgui.text_wrapped(path_line(rep))
        imgui.text_wrapped(
            f"{c.get('overexposed', 0):,} overexposed points: "
            f"{c.get('projected_from_registered_photo', 0):,} from the registered photo, "
            f"{c.get('expanded_by_projection', 0):,} projected, "
            f"{c.get('filled_by_poisson', 0):,} by Poisson, "
            f"{c.get('unresolved', 0):,} unresolved")
        for wmsg in rep.get("warnings", [])[:3]:
            imgui.text_colored((1, 0.8, 0.3, 1), wmsg)
            tooltip(wmsg)
    imgui.end_child()


def draw(ui) -> None:
    s = ui.session
    _photo(ui)
    method = s.settings["hdr.method"]
    imgui.begin_disabled(not method.startswith("pmatch"))
    imgui.text("transfer:")
    imgui.same_line()
    if imgui.radio_button("colour", method == "pmatch-rgb"):
        s.settings.set("hdr.method", "pmatch-rgb")
    imgui.same_line()
    if imgui.radio_button("luminance", method == "pmatch-lum"):
        s.settings.set("hdr.method", "pmatch-lum")
    imgui.end_disabled()
    widgets.panel_group(s.settings, "hdr")
    _run_controls(ui)
    _show_choice(ui)
    _report(ui)
