"""The render-mode interface (app/pbgi/modebase.py), its closed registry (app/pbgi/modes.py) and
the typed render statistics (app/pbgi/stats.py)."""

from __future__ import annotations

import inspect
import json
from dataclasses import replace

import numpy as np
import pytest

from tests.support import scenes as S
from app.errors import ScanlightError
from app.params import RENDER_MODES
from app.pbgi.farfield import FarFieldShare
from app.pbgi.mipmapped import PairRefiner
from app.pbgi.modebase import CutFinder, MicroBufferMode, RenderMode
from app.pbgi.modes import MODES, create_mode
from app.pbgi.renderer import RenderParams
from app.pbgi.stats import PairFigures, RenderStats, ShareFigures

CAM = S.look((0.0, 0.2, 1.6), (0.0, 0.0, 0.0), 16, 45)


def test_registry_names_exactly_the_parameter_table_s_modes():
    assert tuple(MODES) == RENDER_MODES
    for name, cls in MODES.items():
        assert issubclass(cls, RenderMode) and cls.name == name
        assert not inspect.isabstract(cls), name          # every member declared


def test_every_mode_is_created_by_name(ctx):
    for name in MODES:
        mode = create_mode(name, ctx, RenderParams(mode=name))
        try:
            assert isinstance(mode, MODES[name]) and mode.fits(RenderParams(mode=name))
            if isinstance(mode, MicroBufferMode):
                assert isinstance(mode.cut, CutFinder) and not inspect.isabstract(type(mode.cut))
                assert isinstance(mode.cut.clears_microbuffers, bool)
        finally:
            mode.release()
    with pytest.raises(ScanlightError, match="unknown render mode"):
        create_mode("bogus", ctx, RenderParams())
    with pytest.raises(ScanlightError):                  # parameters are checked
        create_mode("hybrid", ctx, RenderParams(mode="hybrid", parallax_tolerance=-1.0))


def test_a_mode_is_re_created_only_when_a_construction_parameter_changes(furnace):
    classic = furnace.mode_for(RenderParams(mode="classic", microbuffer=8))
    assert furnace.mode_for(RenderParams(mode="classic", microbuffer=16, memory_budget_mb=2.0)) is classic
    shared = furnace.mode_for(RenderParams(mode="hybrid"))
    assert isinstance(shared.cut, FarFieldShare)
    assert furnace.mode_for(RenderParams(mode="hybrid", microbuffer=8)) is shared
    exact = furnace.mode_for(RenderParams(mode="hybrid", parallax_tolerance=0.0))
    assert exact is not shared and isinstance(exact.cut, PairRefiner)
    assert furnace.mode_for(RenderParams(mode="hybrid", parallax_tolerance=0.0,
                                         omega_tr_factor=8.0)) is not exact
    assert furnace.mode_for(RenderParams(mode="classic", microbuffer=8)) is classic


@pytest.mark.parametrize("mode", ["classic", "mipmapped", "hybrid"])
def test_the_node_stop_factor_reaches_the_cut(furnace, demo_relighter, mode):
    """pbgi.stop_factor: a new cut finder with the factor, and 1 Omega refines further than the
    paper's 4 Omega (more nodes visited per receiver) - in the demo room, where the cut is deep."""
    four = furnace.mode_for(RenderParams(mode=mode, stop_factor=4.0))
    one = furnace.mode_for(RenderParams(mode=mode, stop_factor=1.0))
    assert one is not four and one.stop_factor == 1.0
    from app.demo.room import default_views
    cam = default_views(24, 24)["closeup"]
    visits, images = {}, {}
    for f in (4.0, 1.0):
        demo_relighter.forget_microbuffers()
        res = demo_relighter.render(cam, None, RenderParams(mode=mode, microbuffer=8,
                                                            stop_factor=f))
        assert res.stats.completed
        visits[f], images[f] = res.stats.nodes_visited, res.image
    assert np.abs(images[1.0] - images[4.0]).max() > 0        # another cut: the factor arrived
    if mode == "classic":
        assert visits[1.0] > 1.2 * visits[4.0], visits


@pytest.mark.parametrize("mode", RENDER_MODES)
def test_render_stats_are_typed_and_write_the_stats_json_keys(furnace, mode):
    """RenderResult.stats is a RenderStats; its JSON has the common keys, the micro-buffer
    modes' batching keys, each engine's own figures, and nothing that does not apply."""
    params = RenderParams(mode=mode, microbuffer=8)
    res = furnace.render(CAM, None, params)
    s = res.stats
    assert isinstance(s, RenderStats) and s.mode == mode and s.completed
    d = json.loads(json.dumps(s.to_dict()))
    assert {"mode", "microbuffer", "width", "height", "tile", "receivers", "ms", "mb",
            "ms_gather", "nodes_visited", "completed", "batches"} <= set(d)
    assert d["tile"] == [0, 0, 16, 16]
    micro = mode != "envmap"
    assert ("mb_extra" in d) == micro and ("tile_halvings" in d) == micro
    assert ("envmap_face" in d) == (not micro)
    assert ("pairs_processed" in d) == (mode == "mipmapped")
    assert ("share_blocks" in d) == (mode == "hybrid")          # default: far-field sharing
    if mode == "hybrid":
        exact = furnace.render(CAM, None, replace(params, parallax_tolerance=0.0)).stats
        assert exact.pairs is not None and exact.share is None


def test_figures_sum_over_batches_and_keep_the_largest_peak():
    a = PairFigures(flushes=1, pairs_processed=10, ms_refine=1.5, peak_stack_pairs=5,
                    mb_extra_used=2.0)
    b = PairFigures(flushes=2, pairs_processed=4, ms_refine=0.5, peak_stack_pairs=3,
                    mb_extra_used=3.0)
    t = PairFigures.total([a, b])
    assert (t.flushes, t.pairs_processed, t.ms_refine) == (3, 14, 2.0)
    assert (t.peak_stack_pairs, t.mb_extra_used) == (5, 3.0)
    assert ShareFigures.total([None, None]) is None
    s = ShareFigures.total([ShareFigures(share_blocks=2, share_block_max=4),
                            ShareFigures(share_blocks=3, share_block_max=9)])
    assert (s.share_blocks, s.share_block_max) == (5, 9)
