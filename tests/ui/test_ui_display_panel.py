"""The Display panel in a headless imgui context (the ``ui`` fixture of test_ui_panels.py): the
exposure slider snaps to 1/3 stops while Shift is held, and the false-colour and difference views
draw their legends."""

from __future__ import annotations

import pytest

imgui_bundle = pytest.importorskip("imgui_bundle")
from imgui_bundle import imgui  # noqa: E402

from tests.ui.test_ui_panels import _draw, _record_text, ui  # noqa: E402,F401  (fixture)


def _drag_exposure_to(monkeypatch, value: float):
    """The exposure slider reports a drag to ``value`` (what imgui returns for a mouse drag)."""
    real = imgui.slider_float

    def slider(label, v, *a):
        if label.endswith("##view.exposure"):
            return True, value
        return real(label, v, *a)
    monkeypatch.setattr(imgui, "slider_float", slider)


@pytest.mark.parametrize("shift, expect", [(False, 0.3), (True, 1 / 3)])
def test_exposure_snaps_while_shift_is_held(ui, monkeypatch, shift, expect):
    from app.ui import panels
    monkeypatch.setattr(panels, "OPEN_BY_DEFAULT", {"Display"})
    _drag_exposure_to(monkeypatch, 0.3)
    imgui.get_io().add_key_event(imgui.Key.mod_shift, shift)
    _draw(ui, 2)
    assert ui.session.settings["view.exposure"] == pytest.approx(expect, abs=1e-12)
    assert not ui.engine.messages, [m.text for m in ui.engine.messages]


def test_false_colour_and_difference_legends(ui, monkeypatch):
    from app.render.tonemap import false_colour_legend
    from app.ui import panels
    from app.ui.scene import difference_legend
    monkeypatch.setattr(panels, "OPEN_BY_DEFAULT", {"Display", "HDR expansion"})
    ui.engine.cloud.hdr = ui.engine.cloud.ldr          # as after an expansion
    seen = _record_text(monkeypatch)
    _draw(ui, 2)
    texts = [t for _, t in seen]
    assert not any(t == "-1 .. +1 EV" for t in texts)  # legends only with their views
    assert not any(t == "+6 EV or more" for t in texts)
    ui.session.settings.set("view.false_colour", True)
    ui.session.settings.set("view.cloud", "difference")
    seen.clear()
    _draw(ui, 2)
    texts = [t for _, t in seen]
    frames = 2
    assert [t for t, _ in false_colour_legend()] * frames == [
        t for t in texts if t.endswith(" EV") and (".." in t or t[0] in "<>")]
    assert [t for t, _ in difference_legend()] * frames == [
        t for t in texts if t.startswith("+") and ".." not in t]
    assert not ui.engine.messages, [m.text for m in ui.engine.messages]
