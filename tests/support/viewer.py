"""The real PBGI renderer in the viewer's tests, kept cheap, and a call counter on it.

The viewer tests run the renderer the viewer ships (app.pbgi.renderer, on llvmpipe here); they
stay fast by keeping the GI small: small viewports (the asset covers a few thousand pixels at
most) and a small micro-buffer, set through the settings model as a user would.
"""

from __future__ import annotations

from dataclasses import dataclass


SMALL_MICROBUFFER = 8      # the settings' minimum: the cheapest real gather


def small_session(microbuffer: int = SMALL_MICROBUFFER, **settings):
    """The demo session with a small micro-buffer and the GI layer at the window's resolution
    for rough materials too (and any other settings given): the tests' windows are small, and
    what they check of the layer - its pixels, tiles and metrics - was sized for a whole one.
    The per-scene scale of the default preset has its own test (test_ui_engine.py)."""
    from app.ui.engine import default_session
    s = default_session()
    s.settings.update({"pbgi.microbuffer": microbuffer, "pbgi.rough_render_scale": 1.0,
                       **settings})
    s.settings.take_changes()
    return s


@dataclass
class RenderCall:
    size: tuple[int, int]               # camera (width, height)
    tile: tuple[int, int, int, int]     # (x0, y0, w, h)
    mode: str
    microbuffer: int
    receivers: int
    reused_microbuffers: bool
    completed: bool                     # the renderer's own "every pass finished" flag


def spy_renders(monkeypatch) -> list[RenderCall]:
    """Record every call of the real Relighter.render (what it computes is untouched)."""
    from app.pbgi.renderer import Relighter
    real = Relighter.render
    calls: list[RenderCall] = []

    def render(self, camera, materials=None, params=None, tile=None, pass_index=0, **kw):
        res = real(self, camera, materials, params, tile, pass_index, **kw)
        t = tuple(int(v) for v in (tile if tile is not None
                                   else (0, 0, camera.width, camera.height)))
        st = res.stats
        calls.append(RenderCall((camera.width, camera.height), t, st.mode, st.microbuffer,
                                st.receivers, st.reused_microbuffers, st.completed))
        return res
    monkeypatch.setattr(Relighter, "render", render)
    return calls
