"""Mouse and keyboard for imgui through its event queue, so no click or shortcut is lost.

moderngl-window's imgui integration writes the button state (``io.mouse_down[i] = 1``) when an
event arrives. A short click (press and release within one frame) then overwrites itself before
imgui looks, and when a refinement frame takes longer than the click, the click vanishes. imgui's
own input queue (``io.add_mouse_*_event``, with ``config_input_trickle_event_queue`` on) keeps
every event in order and hands a press and its release to consecutive frames, so a button sees
its click however long the frame that received both events was.

The integration also forwards only navigation keys and no modifiers, so Ctrl+click on a slider
(type a value), Ctrl+A / C / V / X / Z in text fields and Shift-selection did nothing. Here
letters, digits, function keys and the modifier state go to imgui too (the modifiers before
every key and button event, as imgui's own backends do).

A release that arrives in the same frame as the motion before it would end a slider drag short:
imgui drops the active widget on the frame it sees the button up, before applying that frame's
mouse position. So such a release is held back (``frame_started``) until a frame has applied the
last position: imgui's trickling queue may itself defer that position by a frame (a position
after a button change in one frame waits for the next), so "one frame later" is not enough -
a press, a drag and its release all between two slow frames left the slider where it was
pressed. The release goes to the queue once imgui's mouse position is the last one sent (at
most MAX_HOLD_FRAMES frames), and a slider then lands where the hand let go.

Positions are in window pixels, top-left origin, as pyglet reports them through
moderngl-window.
"""

from __future__ import annotations

import math

from imgui_bundle import imgui

MAX_HOLD_FRAMES = 4     # a held release goes out after this many frames whatever the position

NAMED = {"TAB": "tab", "LEFT": "left_arrow", "RIGHT": "right_arrow", "UP": "up_arrow",
         "DOWN": "down_arrow", "PAGE_UP": "page_up", "PAGE_DOWN": "page_down", "HOME": "home",
         "END": "end", "DELETE": "delete", "INSERT": "insert", "SPACE": "space",
         "BACKSPACE": "backspace", "ENTER": "enter", "ESCAPE": "escape",
         "LEFT_CTRL": "left_ctrl", "LEFT_SHIFT": "left_shift", "RIGHT_SHIFT": "right_shift",
         "MINUS": "minus", "PERIOD": "period", "COMMA": "comma", "SLASH": "slash",
         "SEMICOLON": "semicolon", "EQUAL": "equal", "BACKSLASH": "backslash",
         "LEFT_BRACKET": "left_bracket", "RIGHT_BRACKET": "right_bracket"}


def _keymap(keys) -> dict:
    out = {}
    for name, imgui_name in NAMED.items():
        if hasattr(keys, name):
            out[getattr(keys, name)] = getattr(imgui.Key, imgui_name)
    for c in "ABCDEFGHIJKLMNOPQRSTUVWXYZ":
        out[getattr(keys, c)] = getattr(imgui.Key, c.lower())
    for d in range(10):
        out[getattr(keys, f"NUMBER_{d}")] = getattr(imgui.Key, f"_{d}")
    for f in range(1, 13):
        out[getattr(keys, f"F{f}")] = getattr(imgui.Key, f"f{f}")
    return out


class ImguiInput:
    """Forwards a moderngl-window's mouse and keyboard events to imgui's queue (``io`` of the
    current context)."""

    def __init__(self, wnd):
        self.wnd = wnd
        imgui.get_io().config_input_trickle_event_queue = True
        self._buttons = {wnd.mouse.left: imgui.MouseButton_.left,
                         wnd.mouse.right: imgui.MouseButton_.right,
                         wnd.mouse.middle: imgui.MouseButton_.middle}
        self._keys = _keymap(wnd.keys)
        self._moved = False          # a position event since imgui's last new_frame
        self._held_releases: list = []
        self._held_frames = 0        # frames the held releases have waited
        self._last_pos = None        # the last position sent to imgui

    def modifiers(self, mods=None) -> None:
        m = self.wnd.modifiers if mods is None else mods
        io = imgui.get_io()
        io.add_key_event(imgui.Key.mod_ctrl, bool(m.ctrl))
        io.add_key_event(imgui.Key.mod_shift, bool(m.shift))
        io.add_key_event(imgui.Key.mod_alt, bool(m.alt))

    def move(self, x, y) -> None:
        imgui.get_io().add_mouse_pos_event(float(x), float(y))
        self._last_pos = (float(x), float(y))
        self._moved = True

    def imgui_button(self, button) -> int | None:
        """imgui's index of a moderngl-window mouse button (None: one imgui does not track)."""
        which = self._buttons.get(button)
        return None if which is None else int(which)

    def button(self, x, y, button, down: bool) -> None:
        self.modifiers()
        which = self._buttons.get(button)
        if which is None:
            self.move(x, y)
            return
        if not down and (self._moved or self._held_releases):
            self.move(x, y)
            self._held_releases.append(int(which))   # after the frame that applies the move
            return
        self.move(x, y)
        imgui.get_io().add_mouse_button_event(int(which), bool(down))

    def frame_started(self) -> None:
        """Call right after ``imgui.new_frame()``: releases held back go to the queue for the
        next frame once this one has applied the last position (module docstring)."""
        self._moved = False
        if not self._held_releases:
            return
        p = imgui.get_io().mouse_pos        # imgui floors the positions it is given
        applied = self._last_pos is None or (p.x == math.floor(self._last_pos[0])
                                             and p.y == math.floor(self._last_pos[1]))
        if not applied and self._held_frames < MAX_HOLD_FRAMES:
            self._held_frames += 1
            return
        for which in self._held_releases:
            imgui.get_io().add_mouse_button_event(which, False)
        self._held_releases.clear()
        self._held_frames = 0

    @staticmethod
    def wheel(dx, dy) -> None:
        imgui.get_io().add_mouse_wheel_event(float(dx), float(dy))

    def key(self, key, action, mods) -> None:
        self.modifiers(mods)
        k = self._keys.get(key)
        if k is not None and action in (self.wnd.keys.ACTION_PRESS,
                                        self.wnd.keys.ACTION_RELEASE):
            imgui.get_io().add_key_event(k, action == self.wnd.keys.ACTION_PRESS)

    @staticmethod
    def char(text: str) -> None:
        imgui.get_io().add_input_character(ord(text))
