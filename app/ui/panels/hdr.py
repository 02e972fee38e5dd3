"""HDR expansion: the photo and the exposure found, method and thresholds, Run / Cancel with
progress while the job runs in the background, then LDR / HDR / difference."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui

from app.params import BY_KEY
from app.ui import widgets
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


def draw(ui) -> None:
    s, e = ui.session, ui.engine
    if e.photo is None:
        imgui.text_disabled("no HDR photo: open one in the Scene panel")
    else:
        tex = ui.textures.get(PHOTO) or _photo_thumbnail(ui)
        tw, th = tex.size
        avail = imgui.get_content_region_avail().x
        imgui.image(tex.glo, (avail, avail * th / tw))
        alpha = (ui.hdr_report or {}).get("alpha")
        imgui.text(f"exposure found: alpha = {alpha:.4g} ({np.log2(alpha):+.2f} EV)" if alpha
                   else "exposure: found when the expansion runs")
    method = s.settings["hdr.method"]
    if method.startswith("pmatch"):
        imgui.text("transfer:")
        imgui.same_line()
        if imgui.radio_button("colour", method == "pmatch-rgb"):
            s.settings.set("hdr.method", "pmatch-rgb")
        imgui.same_line()
        if imgui.radio_button("luminance", method == "pmatch-lum"):
            s.settings.set("hdr.method", "pmatch-lum")
    widgets.panel_group(s.settings, "hdr")
    task = ui.hdr_task
    if task is not None and task.running:
        state, frac, stage = task.snapshot()
        imgui.progress_bar(frac, (-1, 0), f"{stage} {100 * frac:.0f}%")
        if imgui.button("Cancel"):
            task.cancel()
    else:
        imgui.begin_disabled(e.photo is None or not s.capture_cameras)
        if imgui.button("Run expansion"):
            e.guard("starting the HDR expansion", ui.start_expansion)
            ui.textures.drop(PHOTO)   # re-made with the alpha found; freed after this frame
        imgui.end_disabled()
        tooltip("Runs in the background; the viewport stays interactive.")
    if e.cloud is not None and e.cloud.hdr is not None:
        imgui.separator_text("show")
        cur = s.settings["view.cloud"]
        for i, name in enumerate(BY_KEY["view.cloud"].choices):
            if i:
                imgui.same_line()
            if imgui.radio_button(name.upper() if name != "difference" else "difference",
                                  cur == name):
                s.settings.set("view.cloud", name)
        tooltip("difference: log2(Y_hdr / Y_ldr) per point, black = unchanged, white = 6 stops")
    rep = ui.hdr_report
    if rep:
        c = rep.get("counts", {})
        imgui.text_wrapped(
            f"{c.get('overexposed', 0):,} overexposed points: "
            f"{c.get('expanded_by_projection', 0):,} projected, "
            f"{c.get('filled_by_poisson', 0):,} by Poisson, "
            f"{c.get('unresolved', 0):,} unresolved")
        for wmsg in rep.get("warnings", [])[:3]:
            imgui.text_colored((1, 0.8, 0.3, 1), wmsg)
