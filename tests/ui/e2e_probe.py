"""Automation hook for the end-to-end window tests (`scanlight view --script e2e_probe.py
--script-arg out=DIR`): it observes, it never drives.

Each frame it records the screen rectangle of every widget the panels drew, by label (the real
imgui functions run unchanged; the wrapper reads imgui's last-item rectangle after each call),
and writes DIR/state.json with those rectangles and what the viewer holds (settings, material,
capture cameras, navigation, GI and job progress, messages). The test (test_ui_e2e.py) reads it
to find widgets by label and to wait for results, and moves the mouse and keyboard through the
X server. A request file DIR/request.json ``{"id": N, "shot": NAME}`` asks for a window
screenshot (DIR/NAME.png and the engine's own image DIR/NAME.engine.png).
"""

import json
import os
import time
from pathlib import Path

from imgui_bundle import imgui

WRAPPED = ("button", "small_button", "checkbox", "radio_button", "slider_float", "slider_int",
           "selectable", "collapsing_header", "input_text", "drag_float", "drag_float3",
           "color_edit3", "progress_bar", "begin_combo")
state = {"rects": {}, "frame": 0, "installed": False, "last_write": 0.0, "request": None,
         "done": [], "intervals": [], "pass_words": []}


def _wrap(name):
    real = getattr(imgui, name)

    def call(*a, **kw):
        res = real(*a, **kw)
        label = a[0] if a and isinstance(a[0], str) else None
        if name == "progress_bar":
            label = "progress"
        opened_combo = name == "begin_combo" and res
        if label is not None and not opened_combo:   # an open combo's last item is its popup
            lo, hi = imgui.get_item_rect_min(), imgui.get_item_rect_max()
            # the frame ends where the label text (right of it) begins
            text = label.split("##")[0]
            tw = imgui.calc_text_size(text).x if text and name != "button" else 0.0
            frame_x1 = hi.x - (tw + imgui.get_style().item_inner_spacing.x if tw > 0 else 0.0)
            state["rects"][label] = [lo.x, lo.y, hi.x, hi.y, state["frame"], frame_x1]
        return res
    call.real = real
    return call


def _install():
    for name in WRAPPED:
        setattr(imgui, name, _wrap(name))
    state["installed"] = True


def _snapshot(viewer):
    e, s = viewer.engine, viewer.session
    task = viewer.hdr_task
    gi = e.gi_stats
    mats = s.materials or []
    nav = e.nav
    out = {
        "frame": state["frame"], "time": time.time(), "pid": os.getpid(),
        "rects": state["rects"],
        "grab_min_size": imgui.get_style().grab_min_size,
        "settings": s.settings.to_dict(),
        "material": mats[0].to_dict() if mats else None,
        "captures": [list(c.position) for c in s.capture_cameras],
        "nav": {"yaw": nav.yaw, "pitch": nav.pitch, "position": list(map(float, nav.position)),
                "floor_y": getattr(nav, "floor_y", None), "free": getattr(nav, "free", None)},
        "gi": {"refining": e.gi.refining, "progress": e.gi.progress,
               "mode": gi and gi.mode, "words": _words(e),
               "passes": getattr(e.gi, "passes", None),
               # every distinct "... (pass k of N) ..." the refinement said, frame by frame: a
               # pass can be over between two writes of this file
               "pass_words": state["pass_words"][-50:]},
        "job": None if task is None else {"running": task.running,
                                         "fraction": task.snapshot()[1],
                                         "stage": task.snapshot()[2]},
        "hdr_status": viewer.hdr_status,
        "hdr_alpha": (viewer.hdr_report or {}).get("alpha"),
        "has_hdr": e.cloud is not None and e.cloud.hdr is not None,
        "messages": [[m.level, m.text] for m in e.messages],
        "leftover": None if viewer.leftover is None else viewer.leftover.describe(),
        "autosaves": viewer.autosaver.saves,
        "session_path": None if s.path is None else str(s.path),
        "last_screenshot": viewer.last_screenshot,
        "pending_screenshot": viewer.pending_screenshot,
        "intervals": state["intervals"][-400:],
        "done": state["done"],
        "dialog": bool(viewer.dialog.request is not None),
        "typing": bool(imgui.get_io().want_text_input),    # a text field has the keyboard
    }
    return out


def _words(e):
    f = getattr(e.gi, "status_words", None)
    return f() if callable(f) else None


def _shoot(viewer, out, name):
    from app.io.images import write_png
    viewer.save_window_png(out / f"{name}.png")
    write_png(out / f"{name}.engine.png", viewer.engine.view.read_display())


def on_frame(viewer, frame):
    if not state["installed"]:
        _install()
    args = dict(a.split("=", 1) for a in viewer.script_args)
    out = Path(args["out"])
    state["frame"] = frame
    words = _words(viewer.engine)
    if words and "(pass " in words:
        key = words.split(")")[0] + ")"             # "refining 40% (pass 2 of 3)"
        key = key[key.index("(pass "):]
        if not state["pass_words"] or state["pass_words"][-1] != key:
            state["pass_words"].append(key)
    if viewer.frame_intervals:
        state["intervals"].append(viewer.frame_intervals[-1])
        del state["intervals"][:-2000]
    req_path = out / "request.json"
    if req_path.is_file():
        try:
            req = json.loads(req_path.read_text())
        except ValueError:
            req = None
        if req and req.get("id") not in state["done"]:
            if req.get("shot"):
                _shoot(viewer, out, req["shot"])
            state["done"].append(req["id"])
            state["last_write"] = 0.0
    now = time.monotonic()
    if now - state["last_write"] >= 0.05:
        state["last_write"] = now
        tmp = out / f"state.{os.getpid()}.tmp"
        tmp.write_text(json.dumps(_snapshot(viewer)))
        tmp.replace(out / "state.json")
