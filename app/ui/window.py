"""The look-dev window: moderngl-window (pyglet) + imgui-bundle around a ViewerEngine.

The whole window is the viewport; the panels are imgui windows over its left edge and the
stats over its top-right corner, so the asset (framed at the centre) is never hidden.

Navigation (Blender first, Maya's Alt combinations too):
    middle drag / left drag          orbit about the pivot
    Shift + drag, right drag         pan                 Ctrl + drag    zoom
    wheel                            zoom                F              frame the asset
    Alt + left / middle / right      orbit / pan / zoom (Maya)
    Shift + F (or the button)        fly mode: W A S D move, Q / E down / up, drag to look,
                                     wheel = speed, Esc or Shift + F leaves
    G / R / S                        asset gizmo: move / rotate / scale
    F12                              screenshot (PNG + EXR, once the refinement is complete)

Automation: ``script`` is an ``on_frame(viewer, frame_index)`` function called after every frame
(``scanlight view --script FILE``, app/ui/app.py); it sees this object, its engine and session,
and ``script_args``.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from app.errors import ScanlightError
from app.pbgi.renderer import Relighter
from app.settings import Session, save_last_session
from app.ui import restore_prompt
from app.ui.autosave import Autosaver, leftovers, recover
from app.ui.drag import DragOwner, Motion
from app.ui.engine import ViewerEngine
from app.ui.input import ImguiInput
from app.ui.panels.hdr import PHOTO
from app.ui.textures import PanelTextures
from app.ui.widgets import apply_style

log = logging.getLogger(__name__)


class ViewerWindow:
    """``relighter`` is a factory ``f(ctx=...)`` (the window makes one relighter per session it
    opens); ``script`` an ``on_frame(viewer, frame_index)`` hook with its ``script_args``;
    ``native_dialogs`` False keeps the file dialogs inside the window (None: the desktop's when
    it has one, app/ui/filedialog.py)."""

    def __init__(self, session: Session, size=(1280, 800), script=None, title="Scanlight", *,
                 relighter=Relighter, script_args=(), native_dialogs: bool | None = None):
        import moderngl_window as mglw
        from imgui_bundle import imgui
        from moderngl_window.conf import settings
        from moderngl_window.integrations.imgui_bundle import ModernglWindowRenderer

        from app.render.context import set_window_context
        from app.ui.filedialog import FileDialog

        settings.WINDOW.update({"class": "moderngl_window.context.pyglet.Window",
                                "gl_version": (4, 3), "size": tuple(size), "title": title,
                                "vsync": False, "resizable": True, "aspect_ratio": None,
                                "samples": 0})
        self.wnd = mglw.create_window_from_settings()
        self.wnd.exit_key = None
        self.ctx = self.wnd.ctx
        set_window_context(self.ctx)
        imgui.create_context()
        imgui.get_io().set_ini_filename("")
        apply_style()
        self.imgui = ModernglWindowRenderer(self.wnd)
        self.input = ImguiInput(self.wnd)
        self.relighter_factory = relighter
        self.engine = ViewerEngine(self.ctx, session, size=self.wnd.buffer_size,
                                   relighter=relighter)
        self.session = session
        self.dialog = FileDialog(native=native_dialogs)
        self.script = script
        self.script_args = list(script_args)
        self.frame_index = 0
        self.quit_requested = False
        self.fly = False
        self.gizmo_op = "translate"
        self.selected_capture = 0 if session.capture_cameras else -1
        self.textures = PanelTextures(self.ctx, self.imgui)
        self.hdr_task = None
        self.hdr_report: dict | None = None
        self.hdr_status = ""          # the last job's outcome, in the HDR panel's progress bar
        self.demo_request = None      # the running job is the demo's own expansion
        self.check_demo_light = True  # look once the engine has loaded (app/ui/demo_light.py)
        self.pending_screenshot: str | None = None
        self.last_screenshot: list[str] = []
        self._keys_down: set = set()
        self.drag = DragOwner()        # the view's or the panels' drag (app/ui/drag.py)
        self._last_time = time.perf_counter()
        self.frame_intervals: list[float] = []   # ms between frames: what the user feels
        self.autosaver = Autosaver()
        found = leftovers()
        self.leftover = found[0] if found else None   # offered by app/ui/restore_prompt.py
        self._install_events()

    # -- events ----------------------------------------------------------------------------------
    def _install_events(self) -> None:
        w = self.wnd
        w.resize_func = self._on_resize
        w.key_event_func = self._on_key
        w.mouse_position_event_func = lambda x, y, dx, dy: self.input.move(x, y)
        w.mouse_drag_event_func = self._on_drag
        w.mouse_press_event_func = self._on_press
        w.mouse_release_event_func = self._on_release
        w.mouse_scroll_event_func = self._on_scroll
        w.unicode_char_entered_func = self.input.char
        w.files_dropped_event_func = self._on_drop
        w.close_func = self._on_close

    def _ui_wants_mouse(self) -> bool:
        from imgui_bundle import imgui, imguizmo
        gz = imguizmo.im_guizmo
        return imgui.get_io().want_capture_mouse or gz.is_using() or gz.is_over()

    def _on_resize(self, width, height) -> None:
        self.imgui.resize(width, height)

    def _on_press(self, x, y, button) -> None:
        self.input.button(x, y, button, True)
        which = self.input.imgui_button(button)
        if which is not None:     # the view's drag or the UI's: settled by the next frame
            self.drag.press(which, self._motion(x, y))

    def _on_release(self, x, y, button) -> None:
        self.input.button(x, y, button, False)
        if self.input.imgui_button(button) is not None:
            self._move_view(self.drag.release(x, y))

    def _motion(self, x, y) -> Motion:
        st, mods = self.wnd.mouse_states, self.wnd.modifiers
        return Motion(float(x), float(y), bool(mods.alt), bool(mods.ctrl), bool(mods.shift),
                      bool(st.left), bool(st.middle), bool(st.right))

    def _on_scroll(self, dx, dy) -> None:
        self.input.wheel(dx, dy)
        if self._ui_wants_mouse():
            return
        s = self.session.settings
        if self.fly:
            s.set("view.fly_speed", s["view.fly_speed"] * (1.25 ** dy))
        else:
            self.engine.nav.zoom(dy)

    def _on_drag(self, x, y, dx, dy) -> None:
        self.input.move(x, y)          # the travel comes from positions (app/ui/drag.py)
        self._move_view(self.drag.motion(self._motion(x, y)))

    def _settle_drag(self) -> None:
        """Once per frame, after imgui and the gizmo have seen this frame's input."""
        from imgui_bundle import imgui
        d = self.drag
        if d.pending:
            down = d.button is not None and imgui.is_mouse_down(d.button)
            self._move_view(d.settle(down, self._ui_wants_mouse()))

    def _move_view(self, steps) -> None:
        for step in steps:
            self._move_view_by(step.dx, step.dy, step.motion)

    def _move_view_by(self, dx: float, dy: float, m: Motion) -> None:
        nav = self.engine.nav
        if self.fly:
            nav.look(dx, dy)
            return
        if m.alt:  # Maya
            if m.left:
                nav.orbit(dx, dy)
            elif m.middle:
                nav.pan(dx, dy, self.engine.size[1])
            elif m.right:
                nav.dolly_drag(dy)
            return
        if m.ctrl:
            nav.dolly_drag(dy)
        elif m.shift or m.right:
            nav.pan(dx, dy, self.engine.size[1])
        else:
            nav.orbit(dx, dy)

    def _on_key(self, key, action, modifiers) -> None:
        from imgui_bundle import imgui
        self.input.key(key, action, modifiers)
        keys = self.wnd.keys
        if action == keys.ACTION_RELEASE:
            self._keys_down.discard(key)
            return
        if action != keys.ACTION_PRESS:
            return
        self._keys_down.add(key)
        if imgui.get_io().want_capture_keyboard:
            return
        if key == keys.F and modifiers.shift:
            self.set_fly(not self.fly)
        elif key == keys.ESCAPE and self.fly:
            self.set_fly(False)
        elif self.fly:
            return
        elif key == keys.F:
            self.engine.frame_asset()
        elif key == keys.G:
            self.gizmo_op = "translate"
        elif key == keys.R:
            self.gizmo_op = "rotate"
        elif key == keys.S and modifiers.ctrl:
            self.save_session_dialog()
        elif key == keys.S:
            self.gizmo_op = "scale"
        elif key == keys.F12:
            self.request_screenshot()

    def set_fly(self, on: bool) -> None:
        self.fly = bool(on)
        self._keys_down.clear()

    def _fly_step(self, dt: float) -> bool:
        if not self.fly:
            return False
        k = self.wnd.keys
        held = self._keys_down
        f = (k.W in held) - (k.S in held)
        r = (k.D in held) - (k.A in held)
        u = (k.E in held) - (k.Q in held)
        if not (f or r or u):
            return False
        step = self.session.settings["view.fly_speed"] * min(dt, 0.25)
        self.engine.nav.fly(f * step, r * step, u * step)
        return True

    def _on_drop(self, x, y, paths) -> None:
        for p in paths:
            self.engine.guard(f"opening {Path(p).name}", self.open_path, str(p))

    def _on_close(self) -> None:
        self.quit_requested = True

    # -- files -----------------------------------------------------------------------------------
    def open_path(self, path: str) -> None:
        """Open a dropped or chosen file by its kind: cloud, asset (standing on the scan's
        floor: app/io/placement.py), photo, session or object."""
        from app.ui.files import open_into
        if open_into(self.session, path, room=self.engine.room) == "session":
            self.load_session(path)
        else:
            self.textures.drop(PHOTO)

    def load_session(self, path) -> None:
        from app.settings import load_session
        new = load_session(path)
        self.replace_session(new)

    def replace_session(self, new: Session) -> None:
        if self.hdr_task is not None and self.hdr_task.running:
            self.hdr_task.cancel()
        old_engine = self.engine
        self.session = new
        self.engine = ViewerEngine(self.ctx, new, size=self.wnd.buffer_size,
                                   relighter=self.relighter_factory)
        old_engine.release()
        self.selected_capture = 0 if new.capture_cameras else -1
        self.textures.clear()
        self.hdr_report, self.hdr_status = None, ""
        self.check_demo_light = True

    def save_session(self, path) -> None:
        s = self.session
        s.camera = self.engine.camera()
        if self.engine.cloud is not None and self.engine.cloud.hdr is not None and not s.hdr_cloud:
            from app.io.pointcloud import save_cloud
            hdr_path = Path(path).with_suffix(".hdr.ply")
            save_cloud(self.engine.cloud.hdr, hdr_path)
            s.hdr_cloud = str(hdr_path.resolve())
        s.save(path)
        self.engine.error(f"session saved to {path}", "info")

    def save_session_dialog(self) -> None:
        self.dialog.open("Save session", (".json",),
                         lambda p: self.engine.guard("saving the session", self.save_session, p),
                         save=True, default_name="session.json")

    def restore_leftover(self, left) -> None:
        """Open the autosave ``left`` (moved to the recovered folder first, app/ui/autosave.py)."""
        path = recover(left)
        self.load_session(path)
        self.engine.error(f"restored the autosaved session (kept as {path})", "info")

    def _autosave(self) -> None:
        e = self.engine
        hdr = e.cloud.hdr if e.cloud is not None else None
        before = self.autosaver.error
        self.autosaver.tick(self.session, e.camera(), hdr)
        if self.autosaver.error and self.autosaver.error != before:
            e.error(self.autosaver.error, "warning")

    # -- screenshots -----------------------------------------------------------------------------
    def request_screenshot(self, path: str | None = None) -> None:
        """Saved once the refinement has finished (the window keeps running meanwhile)."""
        self.pending_screenshot = path or str(Path.cwd() /
                                              time.strftime("scanlight-%Y%m%d-%H%M%S.png"))

    def read_window(self) -> np.ndarray:
        """The window's current framebuffer (panels included), (H, W, 3) uint8, top row first."""
        w, h = self.wnd.buffer_size
        data = self.wnd.fbo.read(viewport=(0, 0, w, h), components=3, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1].copy()

    def save_window_png(self, path) -> None:
        from app.ui.shots import save_png
        save_png(path, self.read_window(), self.session)

    def quit(self) -> None:
        self.quit_requested = True

    # -- HDR expansion ---------------------------------------------------------------------------
    def start_expansion(self, synchronous: bool = False) -> None:
        from app.hdr.job import ExpandRequest
        from app.ui.hdr_task import ExpansionTask
        e, s = self.engine, self.session
        if e.photo is None:
            raise ScanlightError(None, "open an HDR photo first (Scene panel, or drop an .exr)")
        if not s.capture_cameras:
            raise ScanlightError(None, "add a capture camera first (Capture cameras panel)")
        req = ExpandRequest.from_settings(e.cloud.ldr, e.photo,
                                          [c.position for c in s.capture_cameras], s.settings)
        self.hdr_task = ExpansionTask(req, synchronous=synchronous)
        self.hdr_report = None

    def start_demo_light(self) -> None:
        """The untouched demo gets its HDR light at once: the cached expansion, else the demo's
        expansion as a background job (app/ui/demo_light.py)."""
        from app.ui import demo_light
        from app.ui.hdr_task import ExpansionTask
        e, s = self.engine, self.session
        if self.hdr_task is not None or not demo_light.wants_demo_light(s, e):
            return
        req = demo_light.demo_request(s, e)
        hit = e.guard("reading the demo's saved HDR light", demo_light.cached_result, req)
        if hit is not None:
            self._apply_expansion(hit)
            self.hdr_status = "demo: saved result"
            e.error(demo_light.LOADED, "info")
            return
        self.hdr_task = ExpansionTask(req)
        self.demo_request = req
        e.error(demo_light.STARTED, "info")

    def _apply_expansion(self, result) -> None:
        self.hdr_report = result.report
        self.engine.set_hdr_cloud(result.cloud, None)
        self.textures.drop(PHOTO)

    def poll_expansion(self) -> None:
        from app.ui import demo_light
        t = self.hdr_task
        if t is None:
            return
        t.poll()
        if t.running:
            return
        self.hdr_task = None
        demo = t.request is self.demo_request
        self.demo_request = None
        if t.state == "done":
            self._apply_expansion(t.result)
            self.hdr_status = f"done in {t.seconds:.1f} s"
            if demo:
                self.engine.guard("saving the demo's HDR light", demo_light.remember,
                                  t.request, t.result)
                self.engine.error(demo_light.READY, "info")
            else:
                self.engine.error(f"HDR expansion done in {t.seconds:.1f} s "
                                  f"(alpha = {t.result.report.get('alpha')})", "info")
        elif t.state == "failed":
            self.hdr_status = "failed (see the message)"
            self.engine.error(f"HDR expansion failed: {t.error}")
        else:
            self.hdr_status = "cancelled"
            self.engine.error("HDR expansion cancelled", "info")

    # -- frame -----------------------------------------------------------------------------------
    def interacting(self) -> bool:
        from imgui_bundle import imgui, imguizmo
        return (self.drag.dragging or bool(self.fly and self._keys_down)
                or imgui.is_any_item_active() or imguizmo.im_guizmo.is_using())

    def render_frame(self) -> None:
        from imgui_bundle import imgui, imguizmo

        from app.ui import overlay, panels
        now = time.perf_counter()
        dt, self._last_time = now - self._last_time, now
        if self.frame_index:
            self.frame_intervals.append(dt * 1e3)
            del self.frame_intervals[:-240]
        self.engine.resize(*self.wnd.buffer_size)
        moving = self._fly_step(dt)
        self.poll_expansion()
        self.engine.guard("drawing the viewport", self.engine.frame,
                          interacting=moving or self.interacting())
        if self.check_demo_light:
            self.check_demo_light = False
            self.engine.guard("starting the demo's HDR light", self.start_demo_light)
        self.wnd.use()
        self.engine.guard("showing the viewport", self.engine.view.blit, self.wnd.fbo)
        io = imgui.get_io()
        io.delta_time = max(dt, 1e-4)
        imgui.new_frame()
        self.input.frame_started()
        imguizmo.im_guizmo.begin_frame()
        self.engine.guard("viewport overlay", overlay.draw, self)
        self._settle_drag()
        panels.draw(self)
        self.dialog.draw()
        restore_prompt.draw(self)
        imgui.render()
        self.wnd.use()
        self.imgui.render(imgui.get_draw_data())
        self.textures.end_frame()          # textures dropped during the frame, now unused
        if self.pending_screenshot and not self.engine.gi.refining:
            path, self.pending_screenshot = self.pending_screenshot, None
            files = self.engine.guard("saving the screenshot", self.engine.screenshot, path)
            if files:
                self.last_screenshot = files
                self.engine.error("screenshot saved: " + ", ".join(files), "info")
        if self.leftover is None:     # never over a session the user may still restore
            self._autosave()
        if self.script is not None:
            self.script(self, self.frame_index)
        self.frame_index += 1

    def run(self, frames: int = 0, screenshot: str | None = None) -> int:
        """The frame loop; ``frames`` > 0 stops after that many frames (tests, batch)."""
        clean = False
        try:
            while not self.wnd.is_closing and not self.quit_requested:
                self.render_frame()
                self.wnd.swap_buffers()
                if frames and self.frame_index >= frames:
                    break
            if screenshot:
                files = self.engine.screenshot(screenshot)
                print("screenshot: " + ", ".join(files))
            clean = True
        finally:
            self.engine.guard("saving the last session", self._save_last)
            if clean:   # a crash keeps the autosave for the next start's restore prompt
                self.engine.guard("removing the autosave", self.autosaver.close)
            if self.hdr_task is not None and self.hdr_task.running:
                self.hdr_task.cancel()
            self.wnd.destroy()
        return 0

    def _save_last(self) -> None:
        """Keep the session for ``view --last``. A config folder that cannot be written
        (read-only, a file) is one warning naming the file, as the autosave's failure: no bug,
        and the window is closing, so a message only in it would never be seen."""
        self.session.camera = self.engine.camera()
        try:
            save_last_session(self.session)
        except ScanlightError as exc:
            log.warning("the last session was not saved: %s", exc)
            self.engine.error(f"the last session was not saved: {exc}", "warning")
