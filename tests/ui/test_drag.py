"""Drag ownership (app/ui/drag.py): a press is settled by the first frame in which imgui holds
its button, so imgui's flags of that frame (not the stale ones of the frame before) decide; the
view's travel comes from positions, so events lost or handed over out of order still leave the
view where the hand went."""

from app.ui.drag import MAX_PENDING_FRAMES, DragOwner, Motion


def _travel(steps):
    return (sum(s.dx for s in steps), sum(s.dy for s in steps))


def test_view_gets_the_motion_that_arrived_before_the_frame():
    d = DragOwner()
    d.press(0, Motion(100, 50))
    assert d.dragging and d.motion(Motion(108, 50)) == [] and d.motion(Motion(116, 51)) == []
    steps = d.settle(button_seen_down=True, ui_wants_mouse=False)
    assert [(s.dx, s.dy) for s in steps] == [(8, 0), (8, 1)]
    assert _travel(d.motion(Motion(119, 51))) == (3, 0)   # decided: motion goes straight on
    assert _travel(d.release(119, 51)) == (0, 0)
    assert not d.dragging and d.motion(Motion(200, 51)) == []


def test_lost_motion_is_made_up_by_the_next_position_and_the_release():
    d = DragOwner()
    d.press(0, Motion(900, 450))
    d.settle(True, False)
    assert _travel(d.motion(Motion(990, 450))) == (90, 0)  # nine events never arrived
    assert _travel(d.release(1000, 450)) == (10, 0)         # nor the last: the release says it


def test_the_release_step_keeps_the_drag_buttons_and_modifiers():
    d = DragOwner()
    d.press(1, Motion(10, 10, right=True, left=False))
    d.settle(True, False)
    d.motion(Motion(12, 10, shift=True, right=True, left=False))
    (step,) = d.release(20, 10)
    assert step.motion.right and step.motion.shift and not step.motion.left


def test_ui_keeps_a_drag_that_started_over_a_panel():
    d = DragOwner()
    d.press(0, Motion(100, 300))
    d.motion(Motion(108, 300))
    assert d.settle(True, ui_wants_mouse=True) == []
    assert d.motion(Motion(116, 300)) == [] and d.release(120, 300) == [] and not d.dragging


def test_a_click_released_before_the_frame_is_still_settled_then_ends():
    d = DragOwner()
    d.press(1, Motion(0, 0, right=True, left=False))
    d.motion(Motion(0, 5, right=True, left=False))
    assert d.release(0, 7) == []
    assert d.dragging                               # pending until imgui has seen the press
    assert _travel(d.settle(True, False)) == (0, 7)
    assert not d.dragging and d.motion(Motion(1, 1)) == []


def test_waits_for_imgui_to_see_the_press_but_not_forever():
    d = DragOwner()
    d.press(0, Motion(0, 0))
    d.motion(Motion(4, 0))
    for _ in range(MAX_PENDING_FRAMES - 1):
        assert d.settle(button_seen_down=False, ui_wants_mouse=False) == []
        assert d.dragging
    assert _travel(d.settle(False, False)) == (4, 0)


def test_nothing_pressed_nothing_moves():
    d = DragOwner()
    assert d.settle(True, False) == [] and d.release(5, 5) == [] and not d.dragging
