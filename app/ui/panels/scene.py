"""Scene: the files (cloud, asset, photo, session), the asset transform, screenshots."""

from __future__ import annotations

from pathlib import Path

from imgui_bundle import imgui

from app.settings import BUILTIN_ASSETS, AssetTransform
from app.ui.widgets import tooltip


def _name(value) -> str:
    if value is None:
        return "(none)"
    return value if value in ("demo",) + BUILTIN_ASSETS else Path(value).name


def _open(ui, title, exts):
    ui.dialog.open(title, exts, lambda p: ui.engine.guard(f"opening {Path(p).name}",
                                                          ui.open_path, p))


def draw(ui) -> None:
    from app.io.exr import IMAGE_EXTENSIONS
    from app.io.mesh import MESH_EXTENSIONS
    from app.io.pointcloud import CLOUD_EXTENSIONS
    s, e = ui.session, ui.engine
    imgui.text(f"cloud: {_name(s.cloud)}"
               + (f" ({len(e.cloud.ldr):,} points)" if e.cloud is not None else ""))
    imgui.same_line()
    if imgui.small_button("open##cloud"):
        _open(ui, "Open a point cloud", CLOUD_EXTENSIONS)
    tooltip("PLY / PCD / XYZ / PTS; 8-bit colours are an LDR scan, float colours HDR. "
            "You can also drop files onto the window.")
    if imgui.small_button("built-in demo room"):
        s.hdr_cloud = None
        s.set_file("cloud", "demo")
        s.set_file("photo", "demo")
        ui.check_demo_light = True     # lit by its HDR light again (app/ui/demo_light.py)
    imgui.text(f"photo: {_name(s.photo)}")
    imgui.same_line()
    if imgui.small_button("open##photo"):
        _open(ui, "Open the HDR photo", IMAGE_EXTENSIONS)
    imgui.text(f"asset: {_name(s.asset)}")
    imgui.same_line()
    if imgui.small_button("open##asset"):
        _open(ui, "Open an asset", MESH_EXTENSIONS + (".json",))
    for name in BUILTIN_ASSETS:
        imgui.same_line()
        if imgui.small_button(name) and s.asset != name:
            s.materials = None
            s.set_file("asset", name)

    imgui.separator_text("asset transform")
    t = s.transform
    ch1, tr = imgui.drag_float3("translate (m)", list(t.translate), 0.01, 0, 0, "%.3f")
    ch2, rot = imgui.drag_float3("rotate (deg)", list(t.rotate_deg), 0.5, -360, 360, "%.1f")
    ch3, sc = imgui.drag_float("scale", float(t.scale), 0.005, 0.001, 100.0, "%.3f")
    if ch1 or ch2 or ch3:
        s.set_transform(AssetTransform(tuple(tr), tuple(rot), max(float(sc), 1e-3)))
    for op, key in (("translate", "G"), ("rotate", "R"), ("scale", "S")):
        if imgui.radio_button(f"{op} ({key})", ui.gizmo_op == op):
            ui.gizmo_op = op
        imgui.same_line()
    imgui.new_line()
    if imgui.button("frame asset (F)"):
        e.frame_asset()
    imgui.same_line()
    if imgui.button("fly mode (Shift+F)"):
        ui.set_fly(not ui.fly)

    imgui.separator_text("session")
    if imgui.button("save..."):
        ui.save_session_dialog()
    imgui.same_line()
    if imgui.button("open..."):
        _open(ui, "Open a session", (".json",))
    imgui.same_line()
    if imgui.button("reopen last"):
        from app.settings import load_last_session
        last = e.guard("reopening the last session", load_last_session)
        if last is not None:
            ui.replace_session(last)
            return
    if imgui.button("screenshot (F12)"):
        ui.request_screenshot()
    tooltip("PNG of the viewport plus an EXR of the linear image, saved in the current folder "
            "once the refinement is complete.")
    # always one line (a screenshot saved later must not push the panels below down)
    imgui.text_disabled("last: " + (Path(ui.last_screenshot[0]).name if ui.last_screenshot
                                    else "(none yet)"))
    if ui.last_screenshot:
        tooltip(ui.last_screenshot[0])
