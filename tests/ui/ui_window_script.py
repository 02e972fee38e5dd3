"""UI script for tests/ui/test_ui_window.py (`scanlight view --script ui_window_script.py
--script-arg out=DIR --script-arg mode=MODE`).

Drives the real window: waits for the refinement to converge, takes window screenshots, changes
a BRDF parameter and the PBGI mode (to MODE) through the settings model, orbits with synthetic
mouse events, and writes what it saw to DIR/result.json.
"""

import json
import math
from pathlib import Path

state = {"step": 0, "since": 0, "result": {"shots": {}}}
args = {}          # the --script-arg KEY=VALUE pairs, read at the first frame


def converged(viewer, frame):
    e = viewer.engine
    return frame - state["since"] >= 3 and not e.gi.refining and not e.session.settings.pending()


def shoot(viewer, name):
    from app.io.images import write_png
    out = Path(args["out"])
    viewer.save_window_png(out / f"{name}.png")
    e = viewer.engine
    write_png(out / f"{name}.engine.png", e.view.read_display())
    alpha = (e.view.read_linear()[..., 3] > 0).astype("uint8") * 255
    write_png(out / f"{name}.asset.png", alpha)
    gi = e.gi_stats
    state["result"]["shots"][name] = {"mode": gi and gi.mode,
                                      "renderer": e.renderer_available,
                                      "renderer_class": f"{type(e.relighter).__module__}."
                                                        f"{type(e.relighter).__qualname__}",
                                      "microbuffer": gi and gi.microbuffer,
                                      "completed": gi and gi.completed,
                                      "messages": [m.text for m in e.messages]}


def press_once(label, res):
    """The next frame's imgui.button(label) answers True once, as a click would; the panel that
    holds it is opened."""
    from imgui_bundle import imgui

    from app.ui import panels
    real = imgui.button
    panels.OPEN_BY_DEFAULT = set(panels.OPEN_BY_DEFAULT) | {"HDR expansion"}

    def button(text, *a):
        if text == label:
            imgui.button = real
            res["pressed"] = label
            return True
        return real(text, *a)
    imgui.button = button


def drag(viewer, at, steps):
    """Press, ``steps`` motions of 8 px to the right, release: all between two frames."""
    x, y = at
    viewer.wnd.mouse_states.left = True
    viewer._on_press(x, y, 1)
    for i in range(1, steps + 1):
        viewer._on_drag(x + 8 * i, y, 8, 0)
    viewer.wnd.mouse_states.left = False
    viewer._on_release(x + 8 * steps, y, 1)


def yaw_change(e):
    return (e.nav.yaw - state["yaw"] + math.pi) % (2 * math.pi) - math.pi


def on_frame(viewer, frame):
    if not args:
        args.update(a.split("=", 1) for a in viewer.script_args)
    e, s = viewer.engine, viewer.session
    st, res = state["step"], state["result"]
    if frame > 4000:
        res["error"] = f"timed out at step {st}"
        st = 99
    if st == 0 and converged(viewer, frame):
        shoot(viewer, "a")
        s.set_material(0, {"base_color": [0.1, 0.25, 0.9], "roughness": 0.15})  # a BRDF slider
        state["since"], st = frame, 1
    elif st == 1 and converged(viewer, frame):
        shoot(viewer, "b")
        s.settings.set("pbgi.mode", args["mode"])
        state["since"], st = frame, 2
    elif st == 2 and converged(viewer, frame):
        shoot(viewer, "c")
        s.settings.set("view.show_gizmo", True)
        state["since"], st = frame, 3
    elif st == 3 and frame - state["since"] >= 2:
        shoot(viewer, "d")
        w, h = e.size
        viewer.input.move(w - 100, h // 2)   # hover the viewport first,
        st = 4                                                    # as a real mouse does
    elif st == 4:
        # a left drag in the viewport orbits the view (applied once the frame has settled who
        # owns the drag, app/ui/drag.py)
        state["yaw"] = e.nav.yaw
        w, h = e.size
        drag(viewer, (w - 100, h // 2), 5)
        st = 41
    elif st == 41:
        res["yaw_change"] = yaw_change(e)
        viewer.input.move(100, 300)         # hover the panel
        state["since"], st = frame, 5
    elif st == 5 and frame - state["since"] >= 3:   # imgui's queue hands one event per frame
        # ... and the same drag over the panel does not
        state["yaw"] = e.nav.yaw
        viewer.wnd.mouse_states.left = True
        viewer._on_press(100, 300, 1)
        res["panel_wants_mouse"] = bool(viewer._ui_wants_mouse())
        viewer._on_drag(108, 300, 8, 0)
        viewer.wnd.mouse_states.left = False
        viewer._on_release(108, 300, 1)
        st = 51
    elif st == 51 and frame - state["since"] >= 6:
        res["yaw_change_over_panel"] = yaw_change(e)
        # from the panel into the view and a drag, all between two frames: imgui's flags still
        # say "over the panel" at the press (they are computed in the next new_frame)
        state["yaw"] = e.nav.yaw
        res["panel_wants_mouse_before_quick_drag"] = bool(viewer._ui_wants_mouse())
        w, h = e.size
        viewer.input.move(w - 100, h // 2)
        drag(viewer, (w - 100, h // 2), 5)
        st = 52
    elif st == 52:
        res["yaw_change_quick_drag"] = yaw_change(e)
        res["frame_ms_median"] = sorted(e.frame_ms)[len(e.frame_ms) // 2]
        # the HDR expansion in the background, started by the HDR panel's own "Run expansion"
        # button (its click answered once): that frame used to close the window, because the
        # panel freed the photo thumbnail it had just queued for drawing
        s.settings.set("hdr.face_size", 64)
        press_once("Run expansion", res)
        state["job_frames"], state["job_ms"] = 0, []
        res["interval_ms_median_before_job"] = sorted(viewer.frame_intervals)[
            len(viewer.frame_intervals) // 2]
        st = 6
    elif st == 6:
        task = viewer.hdr_task
        if task is None and "pressed" not in res:
            pass                                        # the press happens in the next frame
        elif task is not None and task.running:
            e.nav.orbit(2, 0)                           # keep the viewer busy meanwhile
            state["job_frames"] += 1
            state["job_ms"].append(viewer.frame_intervals[-1])
            if "e" not in res["shots"] and task.snapshot()[1] > 0.2:
                shoot(viewer, "e")                      # progress shown while it runs
        else:
            res["job_frames"] = state["job_frames"]
            res["job_frame_ms_max"] = max(state["job_ms"] or [0.0])
            res["cloud_display"] = s.settings["view.cloud"]
            res["hdr_report_alpha"] = (viewer.hdr_report or {}).get("alpha")
            state["since"], st = frame, 7
    elif st == 7 and converged(viewer, frame):
        shoot(viewer, "f")
        st = 99
    if st == 99:
        res["frames"] = frame
        (Path(args["out"]) / "result.json").write_text(json.dumps(res, indent=1))
        viewer.quit()
        st = 100
    state["step"] = st
