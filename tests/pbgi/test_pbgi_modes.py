"""Mipmapped and Hybrid PBGI against Classic, the G-buffer pyramid, the CPU reference, memory
bounds and the completed flags (app/pbgi/gmip.py, mipmapped.py, hybrid.py)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from tests.support import scenes as S
from app.pbgi.gmip import MipPyramid, build_topology, morton2, reference_pyramid, z_order
from app.pbgi.microbuffer import MicroBuffers
from app.pbgi.mipmapped import MipmappedCut, PairRefiner
from app.pbgi.modebase import AllocationError, Batch
from app.pbgi.modes import create_mode
from app.pbgi.reference import reference_render
from app.pbgi.renderer import Relighter, RenderParams

MODES = ("classic", "mipmapped", "hybrid")


def _receivers(r, cam):
    """The demo G-buffer's receivers in Z-order (as the renderer hands them to these modes)."""
    rec = r.gbuffer.render(cam, [S.diffuse(0.6)])["receivers"]
    pix = np.ascontiguousarray(rec[:, 3]).view(np.uint32)
    return rec[np.argsort(z_order(pix, cam.width), kind="stable")]


def _fill(r, finder, rec, m, width, **kw):
    """Run one cut finder on one batch; returns (micro-buffer entries, its CutFigures)."""
    ctx = r.ctx
    buf = ctx.buffer(rec.tobytes())
    mb = MicroBuffers(ctx)
    try:
        mb.prepare(m, len(rec))
        res = finder.fill(Batch(mb, buf, 0, len(rec), m, r.node_tex, r.hierarchy.cell_size,
                                width=width, **kw))
        return mb.read(len(rec)).copy(), res
    finally:
        mb.release()
        buf.release()


# -- the G-buffer pyramid ---------------------------------------------------------------------

def test_topology_is_a_sparse_z_order_quadtree():
    """Random pixels of a 37 x 29 image with holes: every coarse pixel's children are exactly
    the finer pixels whose Z code >> 2 is its code, empty regions have no pixel at any level,
    and every receiver slot appears once at level 0."""
    rng = np.random.default_rng(1)
    w, h = 37, 29
    pix = rng.choice(w * h, 500, replace=False)
    topo = build_topology(z_order(pix, w))
    link = topo.link
    assert sorted(link[topo.level_of(0), 0]) == list(range(500))
    for k in range(1, topo.levels):
        sl = topo.level_of(k)
        codes = topo.codes[k]
        finer = topo.codes[k - 1]
        assert np.all(np.diff(codes.astype(np.int64)) > 0)               # Z-ordered, unique
        for j, g in enumerate(range(sl.start, sl.stop)):
            first, cnt = int(link[g, 0]), int(link[g, 1])
            ch = np.arange(first, first + cnt) - topo.offsets[k - 1]
            assert 1 <= cnt <= 4
            assert np.all(finer[ch] >> np.uint64(2) == codes[j])
            assert np.all(link[first:first + cnt, 2] == g)
        # no more pixels than distinct parents of the non-empty finer pixels
        assert len(codes) == len(np.unique(finer >> np.uint64(2)))
    assert len(topo.top) == 1
    assert morton2(np.array([3]), np.array([5]))[0] == 0b100111   # x bits even, y bits odd


def test_pyramid_cones_and_spheres_match_the_bsh_operators_and_contain_every_receiver(
        demo_relighter):
    """GPU pyramid vs the numpy twin built with the BSH's own merge operators
    (hierarchy.merge_cones / merge_spheres), and the property the culls rely on: every
    receiver's normal lies in the cone and its position in the sphere of every pixel above it."""
    from app.demo.room import default_views
    r = demo_relighter
    cam = default_views(40, 32)["whole"]
    rec = _receivers(r, cam)
    buf = r.ctx.buffer(rec.tobytes())
    pyr = MipPyramid(r.ctx)
    try:
        pix = np.ascontiguousarray(rec[:, 3]).view(np.uint32)
        topo = pyr.build(buf, 0, z_order(pix, cam.width))
        gpu = pyr.read()
    finally:
        pyr.release()
        buf.release()
    ref = reference_pyramid(topo, rec[:, 0:3], rec[:, 4:7])
    assert np.abs(gpu["centre"] - ref["centre"]).max() < 1e-5
    assert np.abs(gpu["radius"] - ref["radius"]).max() < 2e-5
    assert np.abs(gpu["angle"] - ref["angle"]).max() < 1e-4
    assert np.abs(gpu["axis"] - ref["axis"]).max() < 1e-4
    assert gpu["angle"][-1] > 0.5                      # the sphere's normals really spread
    n = rec[:, 4:7].astype(np.float64)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    for g in range(topo.n_pixels):
        below = topo.receivers_below(g)
        ax = gpu["axis"][g] / np.linalg.norm(gpu["axis"][g])
        ang = np.arctan2(np.linalg.norm(np.cross(n[below], ax), axis=1), n[below] @ ax)
        assert ang.max() <= gpu["angle"][g] + 1e-6
        d = np.linalg.norm(rec[below, 0:3].astype(np.float64) - gpu["centre"][g], axis=1)
        assert d.max() <= gpu["radius"][g] + 1e-6


# -- the three modes find the same cut ------------------------------------------------------

@pytest.mark.parametrize("view,m", [("closeup", 16), ("whole", 24)])
def test_modes_fill_identical_microbuffers(demo_relighter, view, m):
    """Classic, Mipmapped and Hybrid on the demo scene: every micro-buffer entry (depth key and
    node) is identical. Tolerance: none - the parallel phase only culls what every receiver
    below would cull and only refines what every receiver would descend into, the rest is
    finished with Classic's own code, and the micro-buffer write breaks ties by node index, so
    the order nodes arrive in cannot matter. Also: every receiver's walk completed."""
    from app.demo.room import default_views
    r = demo_relighter
    cam = default_views(32, 32)[view]
    rec = _receivers(r, cam)
    modes = {name: create_mode(name, r.ctx, RenderParams(mode=name, omega_tr_factor=32.0,
                                                         parallax_tolerance=0.0))
             for name in MODES}
    out = {}
    try:
        for name, mode in modes.items():
            out[name], res = _fill(r, mode.cut, rec, m, cam.width)
            assert res.done.all(), name
            assert res.cut_short == 0, name
    finally:
        for mode in modes.values():
            mode.release()
    for name in ("mipmapped", "hybrid"):
        assert np.array_equal(out[name], out["classic"]), name
    filled = (out["classic"][..., 1] != 0xFFFFFFFF).mean()
    assert filled > 0.5                                # the room really is in the buffers


@pytest.mark.parametrize("view,m", [("closeup", 16), ("whole", 24)])
def test_cap_spans_and_bands_fill_the_rectangles_microbuffers_with_fewer_tests(
        demo_relighter, view, m):
    """The rasteriser tests only each node's cap (the ellipse of its sphere on the Nusselt disc,
    row by row) and the elevation bands it reaches, not its whole bounding rectangle
    (lib/microbuffer.glsl: mb_cap). Every entry a ray through it can hit is still tested: the
    micro-buffers equal, entry for entry, those of the rectangle rasteriser (MB_RECT_RASTER),
    with at most 80% of its tests (the demo close-up at M 16 measured 69%)."""
    from app.demo.room import default_views
    from app.pbgi.classic import ClassicCut
    r = demo_relighter
    cam = default_views(32, 32)[view]
    rec = _receivers(r, cam)
    spans, rect = ClassicCut(r.ctx), ClassicCut(r.ctx, defines={"MB_RECT_RASTER": 1})
    try:
        got, res = _fill(r, spans, rec, m, cam.width)
        ref, res_ref = _fill(r, rect, rec, m, cam.width)
    finally:
        spans.release()
        rect.release()
    assert res.done.all() and res_ref.done.all() and res.cut_short == 0
    assert np.array_equal(got, ref)
    assert (ref[..., 1] != 0xFFFFFFFF).mean() > 0.5
    assert res.tests.sum() <= 0.8 * res_ref.tests.sum()
    assert np.array_equal(res.visited, res_ref.visited)


def test_hybrid_shares_the_walk(demo_relighter):
    """What the exact Hybrid (no far-field sharing) is for: the per-receiver finishing walks visit fewer nodes than Classic's
    whole-tree walks, the difference being done once per pyramid pixel; a smaller Omega_tr
    moves more of the walk into the shared phase."""
    from app.demo.room import default_views
    r = demo_relighter
    cam = default_views(32, 32)["closeup"]
    rec = _receivers(r, cam)
    _, classic = _fill(r, r.mode_for(RenderParams(mode="classic")).cut, rec, 16, cam.width)
    walks = {}
    for factor in (32.0, 6.0):
        _, res = _fill(r, PairRefiner(r.ctx, omega_tr_factor=factor), rec, 16, cam.width)
        walks[factor] = res.pairs.walk_visited / len(rec)
        assert res.pairs.pairs_processed < len(rec) * classic.visited.mean()
    assert walks[6.0] < walks[32.0] < classic.visited.mean()


# -- bounded memory and completion ----------------------------------------------------------

def test_tiny_streams_and_budgets_still_complete_with_the_same_result(demo_relighter):
    """Stack and second stream far too small for the batch (a few thousand entries) and the
    finishing walk's slices cut down to 200 steps and one micro-buffer of tests: more passes,
    flushes and rounds, the same buffers, every receiver completed."""
    from app.demo.room import default_views
    r = demo_relighter
    cam = default_views(32, 32)["closeup"]
    rec = _receivers(r, cam)
    ref, _ = _fill(r, MipmappedCut(r.ctx), rec, 16, cam.width)
    from app.pbgi.microbuffer import entries
    tiny = MipmappedCut(r.ctx, steps=200, splat_budget=entries(16), max_stream_bytes=1)
    tiny.pairs_per_receiver = 1
    got, res = _fill(r, tiny, rec, 16, cam.width, budget_bytes=1)
    p = res.pairs
    assert p.stack_capacity == 4096 and p.stream2_capacity == 4096
    assert p.flushes > 3 and p.peak_stack_pairs <= 4096
    assert res.done.all()
    assert np.array_equal(got, ref)


def test_allocation_failure_is_reported_not_raised_as_a_crash(demo_relighter):
    """An allocator that refuses: the finder raises AllocationError (what the renderer catches
    to halve its tile), never a raw GL error."""
    calls = []

    def refuse(kind, *args):
        calls.append(kind)
        raise AllocationError("refused")

    f = PairRefiner(demo_relighter.ctx, 32.0, alloc=refuse)
    from app.demo.room import default_views
    cam = default_views(16, 16)["closeup"]
    rec = _receivers(demo_relighter, cam)
    with pytest.raises(AllocationError):
        _fill(demo_relighter, f, rec, 16, cam.width)
    assert calls


@pytest.mark.parametrize("mode", ["mipmapped", "hybrid"])
def test_render_modes_budget_and_halving(demo_relighter, mode, monkeypatch):
    """Through the renderer: a budget of 1 MB splits the frame into batches without changing
    the image; GL refusing the first allocation halves the batch (stats say so) and the image
    is still the same; stats carry the per-mode figures. Hybrid without far-field sharing
    (tests/pbgi/test_pbgi_farfield.py has the sharing's own)."""
    from app.demo.room import default_views
    r = demo_relighter
    cam = default_views(32, 32)["closeup"]
    mat = S.diffuse(0.6)
    exact = RenderParams(mode=mode, microbuffer=16, parallax_tolerance=0.0)
    base = r.render(cam, [mat], RenderParams(mode="classic", microbuffer=16)).image
    res = r.render(cam, [mat], exact)
    s = res.stats
    assert s.completed and s.mode == mode
    assert np.allclose(res.image, base, rtol=1e-5, atol=1e-7)
    for key in ("ms", "mb", "mb_extra", "nodes_visited", "pairs_processed", "tile_halvings"):
        assert key in s.to_dict(), key
    assert s.pairs.pairs_processed > 0 and s.share is None
    small = r.render(cam, [mat], replace(exact, memory_budget_mb=1.0))
    assert small.stats.batches > 1 and small.stats.completed
    assert small.stats.mb_extra + small.stats.mb_microbuffers <= 1.0 + 0.25
    assert np.allclose(small.image, base, rtol=1e-5, atol=1e-7)

    finder = r.mode_for(exact).cut                      # both: a PairRefiner
    real = finder._alloc
    refused = {"n": 0}

    def flaky(kind, *args):
        if refused["n"] < 2:
            refused["n"] += 1
            raise AllocationError("refused")
        return real(kind, *args)

    monkeypatch.setattr(finder, "_alloc", flaky)
    finder.release()
    halved = r.render(cam, [mat], exact)
    assert halved.stats.tile_halvings >= 1 and halved.stats.completed
    assert np.allclose(halved.image, base, rtol=1e-5, atol=1e-7)


# -- against the CPU reference ----------------------------------------------------------------

@pytest.mark.parametrize("mode", ["mipmapped", "hybrid"])
def test_modes_match_the_cpu_reference_on_a_small_room(mode):
    """A diffuse sphere in the small coloured room with a bright ceiling light, against the
    independent Monte Carlo reference (app.pbgi.reference). Same tolerance as Classic's test
    (tests/pbgi/test_pbgi_reference.py): mean within 5%, every pixel within 15% + 4 standard
    errors - PBGI's cluster colours and 24 x 24 direction quantisation against a 1024-sample
    Monte Carlo estimate; the modes themselves add nothing (they equal Classic exactly)."""
    cloud = S.box_room(0.1)
    r = Relighter()
    r.set_cloud(cloud)
    r.set_asset(S.sphere((0.0, 0.8, 0.0), 0.3, subdivisions=3))
    cam = S.look((0.25, 1.0, 0.9), (0.0, 0.8, 0.0), 10, 38)
    mat = S.diffuse(0.8, 0.5)
    gb = S.reference_gbuffer(r, cam, mat)
    ref, err = reference_render(gb, cloud.positions, cloud.normals, cloud.colors,
                                n_samples=1024, seed=0, return_stderr=True)
    res = r.render(cam, [mat], RenderParams(mode=mode, microbuffer=24))
    assert res.stats.completed
    got = res.image.reshape(-1, 4)[gb["pixel"], :3].astype(np.float64)
    assert np.all(np.abs(got.mean(0) / ref.mean(0) - 1) < 0.05)
    assert np.all(np.abs(got - ref) <= 0.15 * ref + 4 * err + 1e-3)


# -- the benchmark ------------------------------------------------------------------------------

def test_table3_records_and_markdown(capsys):
    import argparse

    from app.bench import table3
    ap = argparse.ArgumentParser()
    table3.add_arguments(ap)
    args = ap.parse_args(["--viewports", "16", "--microbuffers", "8", "--views", "closeup"])
    records = table3.run(args)
    assert sorted(r["case"]["mode"] for r in records) == sorted(MODES)
    for rec in records:
        assert rec["bench"] == "table3"
        assert set(rec["case"]) == {"mode", "viewport", "microbuffer", "view"}
        assert rec["metrics"]["ms"] > 0 and rec["metrics"]["completed"] == 1.0
        assert "mb" in rec["metrics"]
        diff = rec["metrics"]["diff_mean_pct"]                 # against Classic's own image
        assert diff == 0.0 if rec["case"]["mode"] != "hybrid" else diff < 20.0
    out = capsys.readouterr().out
    assert "classic / hybrid" in out and "| 16x16 |" in out and "closeup 8x8" in out
    assert "hybrid vs classic: mean / 99th-percentile per-pixel difference (%)" in out


def test_bench_classic_from_the_command_line(capsys):
    """`scanlight bench classic` as the README shows it: its list flags parsed as numbers (as
    strings they reached the shared range check and every run, flags or none, ended in a
    TypeError, exit 1)."""
    from app.cli import main
    assert main(["bench", "classic", "--viewports", "16", "--microbuffers", "8", "--views",
                 "closeup", "--points", "20000"]) == 0
    out = capsys.readouterr().out
    assert "classic" in out and "closeup" in out
    with pytest.raises(SystemExit) as e:              # argparse's own usage error
        main(["bench", "classic", "--microbuffers", "8,x"])
    assert e.value.code == 2 and "--microbuffers" in capsys.readouterr().err


def test_render_cli_modes_give_classic_s_image(tmp_path):
    """`scanlight render --mode mipmapped|hybrid --parallax-tolerance 0` writes the same EXR as
    --mode classic (the same cut), with the per-mode figures in the stats JSON; the default
    Hybrid (far-field sharing) is close to it in the mean of 8 passes (a single pass's mean over
    this image's few dozen receivers - GI at half resolution - moves by up to 3.4% from pass to
    pass at M 12 as the receivers' frames turn, lib/microbuffer.glsl: mb_frame). Its 24
    receivers form no block, and a receiver without a block turns its frame as in Classic
    (mb_frame_shared), so the two images agree to float rounding (when Hybrid kept the fixed
    frame for them: 0.6% apart in the mean of 8 passes, 2.8% in one pass). Bad factors are
    usage errors."""
    import json

    from app.cli import main
    from app.io.exr import read_exr
    from app.io.pointcloud import save_cloud
    save_cloud(S.box_room(0.1), tmp_path / "room.ply")
    (tmp_path / "obj.json").write_text(json.dumps({"mesh": "sphere", "translate": [0, 0.8, 0],
                                                   "scale": 0.6}))
    (tmp_path / "cam.json").write_text(json.dumps({"position": [0.3, 1.0, 0.9],
                                                   "look_at": [0, 0.8, 0], "fov_y_deg": 40,
                                                   "width": 16, "height": 12}))
    images = {}
    for mode in MODES:
        out, st = tmp_path / f"{mode}.exr", tmp_path / f"{mode}.json"
        assert main(["render", "--cloud", str(tmp_path / "room.ply"), "--object",
                     str(tmp_path / "obj.json"), "--camera", str(tmp_path / "cam.json"),
                     "--mode", mode, "--microbuffer", "12", "--omega-tr-factor", "16",
                     "--parallax-tolerance", "0", "--out", str(out), "--stats", str(st)]) == 0
        images[mode] = read_exr(out).rgb
        stats = json.loads(st.read_text())
        assert stats["mode"] == mode and stats["completed"] is True
        if mode != "classic":
            assert stats["pairs_processed"] > 0 and stats["tile_halvings"] == 0
    assert images["classic"].max() > 0
    for mode in ("mipmapped", "hybrid"):
        assert np.allclose(images[mode], images["classic"], rtol=1e-5, atol=1e-7), mode
    passes8 = {}
    for mode in ("classic", "hybrid"):
        out = tmp_path / f"{mode}_passes.exr"
        assert main(["render", "--cloud", str(tmp_path / "room.ply"), "--object",
                     str(tmp_path / "obj.json"), "--camera", str(tmp_path / "cam.json"),
                     "--mode", mode, "--microbuffer", "12", "--passes", "8",
                     "--out", str(out)]) == 0
        passes8[mode] = read_exr(out).rgb
    assert np.allclose(passes8["hybrid"], passes8["classic"], rtol=1e-4, atol=1e-6)
    with pytest.raises(SystemExit):
        main(["render", "--omega-tr-factor", "x"])
    assert main(["render", "--cloud", str(tmp_path / "room.ply"), "--object",
                 str(tmp_path / "obj.json"), "--camera", str(tmp_path / "cam.json"),
                 "--mode", "hybrid", "--parallax-tolerance", "-1", "--out",
                 str(tmp_path / "x.exr")]) == 2
    assert main(["render", "--cloud", str(tmp_path / "room.ply"), "--object",
                 str(tmp_path / "obj.json"), "--camera", str(tmp_path / "cam.json"),
                 "--mode", "hybrid", "--omega-tr-factor", "0", "--out",
                 str(tmp_path / "x.exr")]) == 2


@pytest.mark.parametrize("mode", MODES)
def test_walks_only_walks_the_same_nodes_and_rasterises_none(demo_relighter, mode):
    """Relighter.walks_only (bench profile's walk / raster split, gpu_layout.WALK_ONLY): the
    same walks - the same node visits per receiver, the cosine walk's and the glossy lobe's -
    but no micro-buffer entry is tested and no lobe ray is cast, so the asset gathers no light
    at all; switched back, the Relighter renders the image it rendered before, bit for bit."""
    from app.demo.room import default_views
    from app.material import Material
    r = demo_relighter
    cam = default_views(24, 24)["closeup"]
    gold = Material(base_color=(1.0, 0.78, 0.34), roughness=0.25, metallic=1.0)
    params = RenderParams(mode=mode, microbuffer=8)
    before = r.render(cam, [gold], params)
    try:
        r.walks_only = True
        walks = r.render(cam, [gold], params)
    finally:
        r.walks_only = False
    after = r.render(cam, [gold], params)
    s, w = before.stats, walks.stats
    assert s.nodes_visited > 0 and w.nodes_visited == pytest.approx(s.nodes_visited, rel=1e-9)
    assert s.lobe_visited > 0 and w.lobe_visited == pytest.approx(s.lobe_visited, rel=1e-9)
    assert s.splat_tests > 0 and s.lobe_tests > 0
    assert not w.splat_tests and w.lobe_tests == 0
    covered = before.image[..., 3] > 0
    assert covered.sum() > 50 and before.image[covered, :3].max() > 0
    assert np.all(walks.image[covered, :3] == 0)
    assert np.array_equal(after.image, before.image)


def test_profile_splits_each_frame_into_its_parts(capsys):
    """bench profile: one record per mode and material; the parts are each render's own timers
    (non-negative, within the frame's ms); only the glossy material fills lobe buffers, and not
    in the environment map, which walks nothing; the markdown names every row."""
    import argparse

    from app.bench import profile
    ap = argparse.ArgumentParser()
    profile.add_arguments(ap)
    args = ap.parse_args(["--viewport", "16", "--microbuffer", "8", "--repeat", "1",
                          "--points", "20000"])
    records = profile.run(args)
    assert {(r["case"]["mode"], r["case"]["material"]) for r in records} == \
        {(m, k) for m in profile.MODES for k in profile.MATERIALS}
    for rec in records:
        m = rec["metrics"]
        parts = m["gbuffer_ms"] + m["cut_ms"] + m["lobe_ms"] + m["gather_ms"]
        assert min(m["gbuffer_ms"], m["cut_ms"], m["lobe_ms"], m["gather_ms"]) >= 0
        assert parts <= m["ms"] * 1.001 and m["receivers"] > 0 and m["gather_ms"] > 0
        assert (m["lobe_ms"] > 0) == (rec["case"]["material"] == "glossy"
                                      and rec["case"]["mode"] != "envmap"), rec
        assert (m["lobe_tests_per_receiver"] > 0) == (m["lobe_ms"] > 0), rec
        assert (m["lobe_visits_per_receiver"] > 0) == (m["lobe_ms"] > 0), rec
        if rec["case"]["mode"] == "envmap":
            assert m["visits_per_receiver"] == 0 and m["floor_ms"] == 0
        if rec["case"]["mode"] == "classic":
            assert m["visits_per_receiver"] > 1 and m["tests_per_receiver"] > 1
            assert m["floor_ms"] == pytest.approx(m["visits_per_receiver"] * m["receivers"]
                                                  / profile.FLOOR_VISITS_PER_S * 1e3)
        if rec["case"]["mode"] == "hybrid":
            assert "far_ms" in m and "near_ms" in m
            assert 0 < m["merge_ms"] <= m["far_ms"]
            # the blocks were chosen before the cut's timer: in the sharing, not in "other"
            assert 0 < m["choose_ms"] <= m["share_ms"]
            assert parts + m["choose_ms"] + m["other_ms"] == pytest.approx(m["ms"], rel=1e-6)
            assert m["walk_ms"] == pytest.approx(m["far_walk_ms"] + m["near_walk_ms"])
            assert m["raster_ms"] == pytest.approx(m["far_raster_ms"] + m["near_raster_ms"])
        else:
            assert m["share_ms"] == pytest.approx(0, abs=1e-9)
        # the walk / raster split: the walks-only Relighter walked the same nodes; walk,
        # raster and (Hybrid) sharing make up the cut
        assert min(m["walk_ms"], m["raster_ms"], m["share_ms"], m["lobe_walk_ms"],
                   m["lobe_cast_ms"]) >= 0
        assert m["walk_ms"] + m["raster_ms"] + m["share_ms"] >= m["cut_ms"] * 0.999
        assert m["lobe_cast_ms"] <= m["lobe_ms"]
        assert m["walk_visits_per_receiver"] == pytest.approx(m["visits_per_receiver"],
                                                              rel=1e-9)
        assert m["walk_lobe_visits_per_receiver"] == pytest.approx(
            m["lobe_visits_per_receiver"], rel=1e-9)
    out = capsys.readouterr().out
    assert out.count("| classic |") == 2 and "walk / floor" in out and "[choice " in out
    # the floor is llvmpipe's rate: another renderer (a GPU) has none, and the table says so
    classic = next(r for r in records if r["case"]["mode"] == "classic")
    stats = SimpleNamespace(**{k: 0.0 for k in ("ms", "ms_gbuffer", "ms_cut", "ms_lobe",
                                                "ms_gather", "lobe_visited", "lobe_tests")},
                            share=None, receivers=classic["metrics"]["receivers"],
                            nodes_visited=classic["metrics"]["visits_per_receiver"],
                            splat_tests=1.0)
    gpu = profile.parts(stats, stats, floor=False)
    assert gpu["floor_ms"] != gpu["floor_ms"] and gpu["walk_over_floor"] != gpu["walk_over_floor"]
    assert profile.parts(stats, stats)["floor_ms"] == pytest.approx(
        classic["metrics"]["floor_ms"])
    row = profile.markdown([{"case": classic["case"], "metrics": {**classic["metrics"], **gpu}}])
    assert row.splitlines()[-1].endswith("| - | - |")


def test_profile_records_the_lobe_tuning_it_ran():
    """--lobe-tuning: auto is the GL renderer's own (software here), and the other is forced;
    the records say which ran, and the forced one walks the same nodes."""
    import argparse

    from app.bench import profile
    from app.pbgi.lobe import lobe_walk_tuning, tuning_name
    from app.render.context import get_context
    ap = argparse.ArgumentParser()
    profile.add_arguments(ap)
    base = ["--viewport", "16", "--microbuffer", "8", "--repeat", "1", "--points", "20000",
            "--modes", "classic", "--materials", "glossy"]
    auto = profile.run(ap.parse_args(base))
    own = tuning_name(lobe_walk_tuning(get_context().info["GL_RENDERER"]))
    other = "gpu" if own == "software" else "software"
    forced = profile.run(ap.parse_args(base + ["--lobe-tuning", other]))
    assert auto[0]["case"]["lobe_tuning"] == own and forced[0]["case"]["lobe_tuning"] == other
    assert forced[0]["metrics"]["lobe_visits_per_receiver"] == pytest.approx(
        auto[0]["metrics"]["lobe_visits_per_receiver"], rel=1e-6)
    with pytest.raises(SystemExit):
        ap.parse_args(base + ["--lobe-tuning", "fast"])
