"""Real input for the window tests: events injected into the X server through XTest.

The X server delivers them to the viewer's window like a user's mouse and keyboard, so pyglet,
moderngl-window, the window's handlers, imgui's input queue and the panels all run. Coordinates
are window pixels (top-left origin); ``origin`` is the window's position on the screen.
Needs python-xlib (a dev dependency) and a display with the XTEST extension (Xvfb has it).
"""

from __future__ import annotations

import time

from Xlib import X, XK, display as xdisplay
from Xlib.ext import xtest
from Xlib.protocol import event as xevent

BUTTONS = {"left": 1, "middle": 2, "right": 3}
NAMED_KEYS = {"ctrl": "Control_L", "shift": "Shift_L", "alt": "Alt_L", "enter": "Return",
              "esc": "Escape", "f12": "F12", "backspace": "BackSpace", "tab": "Tab"}
CHAR_KEYS = {".": "period", "_": "underscore", "-": "minus", "/": "slash", " ": "space"}


_DISPLAY = []


def _display():
    """One connection for the whole test process, never closed: Xvfb resets itself when its
    last client leaves, and a connection opened during that reset (the next viewer's) is
    dropped ("Display connection closed by server")."""
    if not _DISPLAY:
        _DISPLAY.append(xdisplay.Display())
    return _DISPLAY[0]


class XInput:
    def __init__(self, origin=(0, 0), pause_s: float = 0.02):
        self.d = _display()
        self.origin = origin
        self.pause_s = pause_s

    def close(self) -> None:
        """Nothing to release: the connection is shared (see ``_display``)."""

    def _sync(self, pause: float | None = None) -> None:
        self.d.sync()
        time.sleep(self.pause_s if pause is None else pause)

    def move(self, x, y, pause: float | None = None) -> None:
        ox, oy = self.origin
        xtest.fake_input(self.d, X.MotionNotify, x=int(ox + x), y=int(oy + y))
        self._sync(pause)

    def press(self, button: str = "left") -> None:
        xtest.fake_input(self.d, X.ButtonPress, BUTTONS[button])
        self._sync(0)

    def release(self, button: str = "left") -> None:
        xtest.fake_input(self.d, X.ButtonRelease, BUTTONS[button])
        self._sync(0)

    def click(self, x, y, hold_s: float = 0.05, button: str = "left", settle_s: float = 0.3,
              mods=()) -> None:
        """Hover (``settle_s``: imgui learns the hover from the next frames), then press for
        ``hold_s`` (50 ms: a quick click) and release, with modifier keys held around it."""
        self.move(x, y, settle_s)
        for m in mods:
            self.key_down(m)
        self.press(button)
        time.sleep(hold_s)
        self.release(button)
        for m in reversed(mods):
            self.key_up(m)
        self._sync()

    def drag(self, start, end, steps: int = 12, button: str = "left", step_s: float = 0.03,
             settle_s: float = 0.3, hold_s: float = 0.03) -> None:
        (x0, y0), (x1, y1) = start, end
        self.move(x0, y0, settle_s)
        self.press(button)
        time.sleep(step_s)
        for i in range(1, steps + 1):
            t = i / steps
            self.move(x0 + (x1 - x0) * t, y0 + (y1 - y0) * t, step_s)
        time.sleep(hold_s)         # a quick release: 30 ms after the last motion
        self.release(button)
        self._sync()

    def scroll(self, x, y, notches: int) -> None:
        """Mouse wheel at (x, y): X buttons 4 (up, ``notches`` > 0) and 5 (down)."""
        self.move(x, y, 0.05)
        button = 4 if notches > 0 else 5
        for _ in range(abs(int(notches))):
            xtest.fake_input(self.d, X.ButtonPress, button)
            xtest.fake_input(self.d, X.ButtonRelease, button)
            self._sync(0.03)

    def _keycode(self, name: str) -> int:
        sym = XK.string_to_keysym(NAMED_KEYS.get(name, CHAR_KEYS.get(name, name)))
        code = self.d.keysym_to_keycode(sym)
        if not code:
            raise ValueError(f"no key for {name!r}")
        return code

    def key_down(self, name: str) -> None:
        xtest.fake_input(self.d, X.KeyPress, self._keycode(name))
        self._sync(0)

    def key_up(self, name: str) -> None:
        xtest.fake_input(self.d, X.KeyRelease, self._keycode(name))
        self._sync(0)

    def key(self, name: str, mods=(), hold_s: float = 0.05) -> None:
        for m in mods:
            self.key_down(m)
        self.key_down(name)
        time.sleep(hold_s)
        self.key_up(name)
        for m in reversed(mods):
            self.key_up(m)
        self._sync()

    def type_text(self, text: str) -> None:
        for ch in text:
            self.key(ch, mods=("shift",) if ch.isupper() or ch == "_" else ())

    def find_window(self, title: str):
        """The top-level window named ``title`` (no window manager under Xvfb: direct children
        of the root)."""
        root = self.d.screen().root
        stack = list(root.query_tree().children)
        while stack:
            w = stack.pop()
            try:
                if w.get_wm_name() == title:
                    return w
                stack.extend(w.query_tree().children)
            except Exception:  # a window that went away meanwhile
                continue
        return None

    def window_origin(self, title: str):
        w = self.find_window(title)
        if w is None:
            return None
        pos = w.translate_coords(self.d.screen().root, 0, 0)
        return -pos.x, -pos.y

    def close_window(self, title: str) -> bool:
        """What a window manager's close button does: WM_DELETE_WINDOW to the window."""
        w = self.find_window(title)
        if w is None:
            return False
        proto = self.d.intern_atom("WM_PROTOCOLS")
        delete = self.d.intern_atom("WM_DELETE_WINDOW")
        ev = xevent.ClientMessage(window=w, client_type=proto, data=(32, [delete, X.CurrentTime,
                                                                          0, 0, 0]))
        w.send_event(ev)
        self._sync()
        return True
