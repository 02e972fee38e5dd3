"""app/ui/input.py against a real imgui (no window: imgui's own context, its event queue and a
slider): a press, a drag and the release all delivered between two frames still move the slider
to where the hand let go, and a click still registers. Needs a display for moderngl-window's key
and button constants (xvfb-run)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from imgui_bundle import imgui

from app.ui.input import ImguiInput

pytestmark = pytest.mark.window


@pytest.fixture()
def gui():
    from moderngl_window.context.pyglet.window import Window
    ctx = imgui.create_context()
    io = imgui.get_io()
    io.set_ini_filename("")                  # no imgui.ini left in the working folder
    io.display_size = imgui.ImVec2(400, 300)
    io.delta_time = 1 / 60
    io.fonts.build()
    mouse = SimpleNamespace(left=1, right=2, middle=3)
    mods = SimpleNamespace(ctrl=False, shift=False, alt=False)
    wnd = SimpleNamespace(mouse=mouse, keys=Window.keys, modifiers=mods)
    yield ImguiInput(wnd), mouse
    imgui.destroy_context(ctx)


GRAB_PADDING = 2.0      # imgui's slider: the grab's centre travels frame +- padding - grab / 2


def _at(x0, x1, fraction):
    """Where the mouse sets a float slider spanning x0..x1 to ``fraction`` of its range."""
    grab = imgui.get_style().grab_min_size
    return x0 + GRAB_PADDING + grab / 2 + fraction * ((x1 - x0) - 2 * GRAB_PADDING - grab)


def _frame(inp, state):
    imgui.new_frame()
    inp.frame_started()
    imgui.set_next_window_pos(imgui.ImVec2(0, 0))
    imgui.set_next_window_size(imgui.ImVec2(400, 100))
    imgui.begin("w")
    imgui.set_next_item_width(300)
    changed, v = imgui.slider_float("s", state["value"], 0.0, 1.0)
    if changed:
        state["value"] = v
    state["rect"] = (imgui.get_item_rect_min().x, imgui.get_item_rect_max().x,
                     (imgui.get_item_rect_min().y + imgui.get_item_rect_max().y) / 2)
    imgui.end()
    imgui.render()


def _slow(inp, mouse, state, xa, xb, y):
    """The same drag with a frame after each event: where the slider should land."""
    inp.button(xa, y, mouse.left, True)
    _frame(inp, state)
    inp.move(xb, y)
    _frame(inp, state)
    inp.button(xb, y, mouse.left, False)
    for _ in range(3):
        _frame(inp, state)
    return state["value"]


@pytest.mark.parametrize("motions", [0, 1, 5])
def test_a_whole_drag_between_two_frames_lands_where_it_was_let_go(gui, motions):
    """Press at 0.1, drag to 0.8 and release, all before the next frame: the slider ends where a
    drag with a frame after every event ends (it stayed at 0.1 when the release reached imgui
    in the frame that applied the last position)."""
    inp, mouse = gui
    state = {"value": 0.5}
    for _ in range(3):                               # a new window takes frames to be hoverable
        _frame(inp, state)
    x0, x1, y = state["rect"]
    xa, xb = _at(x0, x1, 0.1), _at(x0, x1, 0.8)
    want = _slow(inp, mouse, state, xa, xb, y)
    assert want == pytest.approx(0.8, abs=0.05)
    state["value"] = 0.5
    _frame(inp, state)
    inp.button(xa, y, mouse.left, True)              # all of these before the next frame
    for k in range(1, motions + 1):
        inp.move(xa + (xb - xa) * k / motions, y)
    inp.button(xb, y, mouse.left, False)
    for _ in range(6):
        _frame(inp, state)
    assert state["value"] == pytest.approx(want, abs=1e-6)
    assert not imgui.is_mouse_down(imgui.MouseButton_.left)


def test_a_quick_click_still_sets_the_slider(gui):
    """Press and release between two frames: the click lands, as a slow one does."""
    inp, mouse = gui
    state = {"value": 0.5}
    for _ in range(3):
        _frame(inp, state)
    x0, x1, y = state["rect"]
    x = _at(x0, x1, 0.25)
    want = _slow(inp, mouse, state, x, x, y)
    state["value"] = 0.5
    _frame(inp, state)
    inp.button(x, y, mouse.left, True)
    inp.button(x, y, mouse.left, False)
    for _ in range(4):
        _frame(inp, state)
    assert state["value"] == pytest.approx(want, abs=1e-6) and want == pytest.approx(0.25, abs=0.05)
    assert not imgui.is_mouse_down(imgui.MouseButton_.left)
