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


def test_the_saved_result_keeps_its_provenance(tmp_path, monkeypatch):
    """The cache (app/demo/cache.py) gives back the labels and scores, and the HDR cloud carries
    them as its provenance attributes; a file saved before scores were kept is a miss (the
    expansion reruns) rather than a provenance without its scores."""
    from app.cloud import PointCloud
    from app.demo import cache
    from app.hdr.job import ExpandRequest
    from app.hdr.result import PROVENANCE_ATTR, SCORE_ATTR, Expansion
    monkeypatch.setenv("SCANLIGHT_CACHE", str(tmp_path))
    rng = np.random.default_rng(5)
    n = 50
    ldr = PointCloud(rng.uniform(-1, 1, (n, 3)), np.tile([0.0, 1.0, 0.0], (n, 1)),
                     rng.uniform(0, 1, (n, 3)))
    req = ExpandRequest(ldr, np.zeros((4, 4, 3), np.float32), [(0.0, 1.0, 0.0)])
    labels = rng.integers(0, 5, n).astype(np.uint8)
    scores = np.where(labels == 4, rng.uniform(0, 1, n), np.nan).astype(np.float32)
    hdr = PointCloud(ldr.positions, ldr.normals, ldr.colors * 4, True)
    cache.store_demo_expansion(req, Expansion(hdr, {"counts": {}}, labels, [], scores))
    back = cache.load_demo_expansion(req)
    np.testing.assert_array_equal(back.labels, labels)
    np.testing.assert_array_equal(back.scores, scores)
    np.testing.assert_array_equal(back.cloud.attributes[PROVENANCE_ATTR], labels)
    np.testing.assert_array_equal(back.cloud.attributes[SCORE_ATTR], scores)
    cache.store_demo_expansion(req, Expansion(hdr, {}, labels, [], None))   # none: NaN kept
    assert np.isnan(cache.load_demo_expansion(req).scores).all()
    path = cache._expansion_path(req)
    with np.load(path) as z:
        old = {k: z[k] for k in z.files if k != "scores"}
    np.savez(path, **old)                            # as an earlier version wrote it
    assert cache.load_demo_expansion(req) is None
