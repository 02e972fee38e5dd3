"""The demo opens with its HDR light (app/ui/demo_light.py): when it applies, the saved result
reused bit for bit, and recomputed when an input changes. The window's background version is
exercised by tests/ui/test_ui_e2e.py."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def engine_for(ctx, monkeypatch, tmp_path):
    from tests.support.viewer import small_session

    from app.ui.engine import ViewerEngine
    monkeypatch.setenv("SCANLIGHT_CACHE", str(tmp_path / "cache"))
    made = []

    def make(**settings):
        s = small_session(**{"hdr.face_size": 64, **settings})
        e = ViewerEngine(ctx, s, size=(48, 32), relighter=lambda ctx: None)
        made.append(e)
        return s, e
    yield make
    for e in made:
        e.view.release()


def test_only_the_untouched_demo_gets_it(engine_for):
    from app.ui import demo_light
    s, e = engine_for()
    assert demo_light.wants_demo_light(s, e)
    s.capture_cameras = []
    assert not demo_light.wants_demo_light(s, e)


def test_offscreen_computes_it_once_then_reuses_it(engine_for, tmp_path):
    from app.ui import demo_light
    s, e = engine_for()
    assert demo_light.expand_now(s, e) == demo_light.READY
    assert s.settings["view.cloud"] == "hdr" and e.cloud.hdr is not None
    first = e.cloud.hdr.colors.copy()
    assert first.max() > 1.0                      # light above the LDR clip: really HDR
    assert list((tmp_path / "cache").glob("demo-hdr-*.npz"))
    s2, e2 = engine_for()
    assert demo_light.expand_now(s2, e2) == demo_light.LOADED
    np.testing.assert_array_equal(e2.cloud.hdr.colors, first)
    s3, e3 = engine_for(**{"hdr.threshold_ldr": 0.8})       # another input: not that result
    assert demo_light.cached_result(demo_light.demo_request(s3, e3)) is None
