"""The viewer engine offscreen (headless EGL): compositing, change sets, errors, screenshots,
sessions and the HDR expansion job, with the real PBGI renderer kept cheap (small viewports,
micro-buffer 8; tests/support/viewer.py), its calls counted by a spy that leaves them untouched."""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
import pytest

from tests.support.viewer import small_session

from app.pbgi.renderer import Relighter
from app.render.splat import near_far
from app.ui import composite
from app.ui.engine import ViewerEngine


def make_engine(ctx, size=(96, 72), session=None, relighter=Relighter):
    """The engine with the renderer injected as the window does (the real one by default)."""
    return ViewerEngine(ctx, session or small_session(), size=size, relighter=relighter)


def twin(e: ViewerEngine) -> np.ndarray:
    inp = e.view.read_inputs()
    near, far = near_far(e.camera(), *e.view.splat.bounds)
    from app.ui.viewport import BACKGROUND
    return composite.composite(inp["room"], inp["room_depth"], inp["gbuf"], inp["preview"],
                               inp["full"], near, far, BACKGROUND)[::-1]


def test_gpu_composite_matches_numpy_twin(ctx, renders):
    """Preview-only (interacting) and converged states: same linear image and asset mask."""
    e = make_engine(ctx, (80, 60))
    e.frame(interacting=True)
    gpu = e.view.read_linear()
    assert e.gi.progress == 0.0 and gpu[..., 3].sum() > 100        # the asset is there already
    ref = twin(e)
    np.testing.assert_array_equal(gpu[..., 3], ref[..., 3])
    np.testing.assert_allclose(gpu, ref, atol=1e-5)
    e.finish_refinement()
    gpu = e.view.read_linear()
    np.testing.assert_allclose(gpu, twin(e), atol=1e-5)


def test_the_first_preview_shows_a_small_asset_at_a_low_gi_scale(ctx, renders):
    """A small window at the default preset's GI scale for rough light (1/2): the first,
    cheapest preview (1/16 of the layer) would have no pixel on the asset; it keeps at least
    refine.MIN_PREVIEW_ASSET_PX across the asset's rectangle, so the asset is drawn from the
    first interactive frame."""
    e = make_engine(ctx, (80, 60), session=small_session(**{"pbgi.rough_render_scale": 0.5}))
    e.frame(interacting=True)
    assert (e.gi.camera.width, e.gi.camera.height) == (40, 30)
    assert e.gi.progress == 0.0 and e.view.read_linear()[..., 3].sum() > 100
    e.release()


def test_refinement_frames_composite_only_their_tiles_and_miss_nothing(ctx, renders):
    """A refinement frame composites only the screen rectangles its new tiles can change (the
    upsampling's taps included; one per band of rows, so tiles in two strips far apart do not
    composite the rows between them); frame after frame the picture is the whole composite's,
    bit for bit, at a layer scale below 1 too, and with a budget that takes several strips a
    frame."""
    from tests.support.viewer import small_session
    many = 0
    for scale, budget in ((1.0, 5.0), (0.5, 5.0), (1.0, 60.0)):
        e = make_engine(ctx, (96, 72), session=small_session(**{"pbgi.render_scale": scale,
                                                                "pbgi.differential": False}))
        e.frame()
        calls = []
        real = e.view.composite
        e.view.composite = lambda *a, **k: (calls.append(k.get("asset_rect")), real(*a, **k))[1]
        while e.gi.refining:
            n = len(calls)
            e.frame(budget_ms=budget)
            many += len(calls) - n > 1
            tiled = e.view.read_linear()
            real(e.camera(), e.session.settings["view.exposure"],
                 e.session.settings["view.tonemap"], raw_room=False, unavailable=False,
                 asset_rect=screen_rect_of(e))        # the whole asset, over the same state
            np.testing.assert_array_equal(tiled, e.view.read_linear())
        full = screen_rect_of(e)
        assert any(r is not None and r[2] * r[3] < full[2] * full[3] for r in calls), calls
        e.release()
    assert many > 0                                    # some frame composited several bands


def screen_rect_of(e):
    from app.ui.refine import screen_rect
    return screen_rect(e.camera(), *e.mesh.bounds())


def test_bilateral_upsampling_keeps_colours_on_their_side_of_a_depth_edge():
    """Two surfaces at different depths, GI known only at 1/4 resolution: each full-resolution
    pixel takes its colour from the low-resolution samples of its own surface."""
    H, W = 16, 16
    gbuf = np.zeros((H, W, 4), np.float32)
    gbuf[..., 2] = 1.0
    gbuf[:, :8, 3] = 1.0            # near surface on the left half
    gbuf[:, 8:, 3] = 3.0            # far surface on the right half
    lo = np.zeros((4, 4, 4), np.float32)
    lo[..., 3] = 1.0
    lo[:, :2, :3] = (1.0, 0.0, 0.0)  # red samples belong to the near (left) surface
    lo[:, 2:, :3] = (0.0, 0.0, 1.0)
    acc, w, pending = composite.upsample(lo, gbuf, (H, W))
    rgb = acc / w[..., None]
    assert not pending.any()
    assert (rgb[:, :8, 0] > 0.999).all() and (rgb[:, 8:, 2] > 0.999).all()
    # plain bilinear would mix the two across the edge: column 7 maps to x = 1.375 in the low
    # resolution image, 62.5% red and 37.5% blue
    plain_red = 1.0 - ((7 + 0.5) * 4 / 16 - 0.5 - 1)
    assert plain_red == pytest.approx(0.625) and (rgb[:, 7, 2] < 1e-3).all()


def test_changes_redo_only_what_depends_on_them(ctx, renders):
    """Counted on the real renderer: display settings redo no GI; a BRDF slider re-gathers the
    asset (and changes its pixels, not the room's); a camera move while interacting renders
    only the reduced-resolution preview. (The asset's shadow and bounce on the scan do depend
    on its materials: off here, tested in test_the_assets_shadow_lands_on_the_scan.)"""
    e = make_engine(ctx)
    e.session.settings.set("pbgi.differential", False)
    e.frame()
    e.finish_refinement()
    before = e.view.read_linear()
    asset = before[..., 3] > 0
    assert asset.sum() > 200 and all(c.microbuffer == 8 and c.mode == e.session.mode
                                     for c in renders)
    s = e.session.settings
    n = len(renders)
    s.set("view.exposure", 1.0)                                   # display only
    info = e.frame()
    assert len(renders) == n and not info["room"]
    s.set("view.exposure", 0.0)
    e.session.set_material(0, {"roughness": 0.9, "base_color": [0.9, 0.1, 0.1]})
    info = e.frame()                                              # re-gather, room untouched
    assert len(renders) > n and not info["room"] and info["gi"]
    e.finish_refinement()
    after = e.view.read_linear()
    np.testing.assert_array_equal(after[~asset], before[~asset])
    red = after[asset][:, 0] / np.maximum(after[asset][:, 1], 1e-6)
    was = before[asset][:, 0] / np.maximum(before[asset][:, 1], 1e-6)
    assert np.median(red) > 2 * np.median(was)                      # the asset turned red
    s.set("pbgi.mode", "envmap")
    e.frame()
    assert e.gi_stats.mode == "envmap" and renders[-1].mode == "envmap"
    e.finish_refinement()
    n = len(renders)
    e.nav.orbit(10, 0)                                             # camera: everything
    info = e.frame(interacting=True)
    assert info["room"] and len(renders) == n + 1                  # preview only while moving
    full = e.gi.camera
    assert renders[-1].size[0] < full.width and e.gi.refining     # reduced resolution, pending


def test_a_colour_edit_recombines_the_converged_picture(ctx, renders):
    """Base colour and metallic of the converged demo sphere: no render call, the picture stays
    converged and is what a new viewer with the edited material converges to (within 1% of the
    mean per pixel on average - measured 0: the tiles, and with them Hybrid's blocks, fall where
    each run's timing puts them, here the same); a roughness edit gathers again, and says why."""
    def converged(engine):
        engine.frame()
        engine.finish_refinement()
        return engine.view.read_linear()

    e = make_engine(ctx)
    e.session.settings.set("pbgi.differential", False)
    before = converged(e)
    asset = before[..., 3] > 0
    n = len(renders)
    e.session.set_material(0, {"base_color": [0.2, 0.5, 0.9], "metallic": 1.0})
    info = e.frame()
    assert e.material_edit == "recombined" and len(renders) == n and not e.gi.refining
    assert not info["room"]
    after = e.view.read_linear()
    np.testing.assert_array_equal(after[~asset], before[~asset])
    fresh = make_engine(ctx, session=e.session)
    ref = converged(fresh)
    np.testing.assert_array_equal(ref[..., 3], after[..., 3])
    diff = np.abs(after[asset][:, :3] - ref[asset][:, :3]).mean() / ref[asset][:, :3].mean()
    assert diff < 0.01, diff
    blue = after[asset][:, 2] / np.maximum(after[asset][:, 0], 1e-6)
    assert np.median(blue) > 2.0                                  # it did turn blue
    e.session.set_material(0, {"roughness": 0.3})
    e.frame()
    assert "roughness" in e.material_edit and e.gi.refining and len(renders) > n
    fresh.release()


def test_the_layer_scale_follows_the_materials(ctx, renders):
    """At the default preset the demo sphere's rough material refines its GI layer at
    pbgi.rough_render_scale (half the window: app/pbgi/upsample.py's gi_scale); an edit that
    brings a narrow lobe in (roughness below pbgi.rough_scale_from) gathers again, saying why,
    at render_scale (the whole window), and back (a clearcoat over the rough base keeps the
    half); the final preset keeps the whole window for rough light too."""
    from app.params import QUALITY_PRESETS
    rough = QUALITY_PRESETS["balanced"]["pbgi.rough_render_scale"]
    e = make_engine(ctx, (96, 72), session=small_session(**{"pbgi.differential": False,
                                                            "pbgi.rough_render_scale": rough}))
    e.frame()
    assert rough == 0.5 and (e.gi.camera.width, e.gi.camera.height) == (48, 36)
    e.finish_refinement()
    assert {c.size for c in renders[-3:]} == {(48, 36)}
    e.session.set_material(0, {"roughness": 0.3})
    e.frame()
    assert "roughness" in e.material_edit and e.gi.refining
    assert (e.gi.camera.width, e.gi.camera.height) == (96, 72)
    e.session.set_material(0, {"clearcoat": 0.5, "roughness": 0.6})   # a clearcoat: still rough
    e.frame()
    assert e.material_edit != "recombined"
    assert (e.gi.camera.width, e.gi.camera.height) == (48, 36)
    e.session.settings.set("pbgi.quality", "final")
    e.frame()
    assert (e.gi.camera.width, e.gi.camera.height) == (96, 72)
    e.release()


def test_the_idle_passes_follow_the_materials(ctx, renders):
    """A rough scene refines pbgi.rough_idle_passes passes (2 at the default preset), a narrow
    lobe pbgi.idle_passes (4): the edit that brings it in gathers again and says why; the lower
    of the two applies, and the final preset keeps 4 for rough light too."""
    from app.params import QUALITY_PRESETS
    assert QUALITY_PRESETS["balanced"]["pbgi.rough_idle_passes"] == 2
    e = make_engine(ctx, (48, 36), session=small_session(**{"pbgi.differential": False}))
    e.frame()
    assert e.gi.passes == 2
    e.finish_refinement()
    assert e.gi.pass_index == 1 and not e.gi.refining
    e.session.set_material(0, {"roughness": 0.3})
    e.frame()
    assert e.gi.passes == 4 and e.material_edit != "recombined"
    e.session.set_material(0, {"roughness": 0.6})
    e.frame()
    assert e.gi.passes == 2
    e.finish_refinement()
    e.session.set_material(0, {"base_color": (0.2, 0.4, 0.6)})      # still rough: recoloured
    e.frame()
    assert e.material_edit == "recombined" and e.gi.passes == 2
    e.session.settings.set("pbgi.quality", "final")
    e.frame()
    assert e.gi.passes == 4
    e.finish_refinement()
    n = len(renders)
    e.session.settings.set("pbgi.idle_passes", 8)       # final's rough passes stay 4: nothing
    e.frame()
    assert e.gi.passes == 4 and not e.gi.refining and len(renders) == n
    e.session.settings.set("pbgi.idle_passes", 1)       # the scene's count changes: gathered
    e.frame()                                           # again, one pass
    assert e.gi.passes == 1 and len(renders) > n


def test_each_change_key_has_its_handler(ctx, renders):
    """Table parameters reach the handler of their Param.redo (a new parameter needs no engine
    edit); document keys have their own handlers, connected in the order of the work; keys
    that only matter to the next job redo nothing. The renderer injected as an instance is the
    one the engine uses."""
    from app.params import PARAMS
    relighter = Relighter(ctx=ctx)
    e = make_engine(ctx, relighter=relighter)
    assert e.relighter is relighter
    redo = {"gi": e._redo_gi, "room": e._redo_room, "display": e._redo_composite,
            "passes": e._on_idle_passes}
    for p in PARAMS:
        handlers = e.changes.handlers_for(p.key)
        assert (redo[p.redo] in handlers) if p.redo in redo else not handlers, p.key
    order = [h.__name__ for _, h in e.changes]
    assert order[:6] == ["_on_room_files", "_on_cloud_colors", "_on_asset", "_on_fov",
                         "_on_camera", "_on_materials"]
    assert e.changes.handlers_for("materials") == [e._on_materials]
    assert e.changes.handlers_for("capture_cameras") == []
    e.frame()
    e.finish_refinement()
    n = len(renders)
    s = e.session.settings
    s.set("hdr.bins", 64)
    s.set("pbgi.frame_budget_ms", 120.0)
    s.set("view.fly_speed", 3.0)
    assert e.apply_changes() == {"hdr.bins", "pbgi.frame_budget_ms", "view.fly_speed"}
    info = e.frame()
    assert len(renders) == n and not info["room"] and not info["gi"]


def test_moving_the_asset_redraws_its_g_buffer(ctx, renders):
    """A new placement (gizmo, transform fields) without a camera move: the picture shows the
    asset where it now is, as a viewer opened on the moved asset would. (Its shadow on the
    scan moves too and redraws the splats: off here, see test_the_assets_shadow_lands_on_the_scan.)"""
    from dataclasses import replace
    e = make_engine(ctx)
    e.session.settings.set("pbgi.differential", False)
    e.frame()
    e.finish_refinement()
    moved = replace(e.session.transform,
                    translate=tuple(np.add(e.session.transform.translate, (0.3, 0.0, 0.0))))
    e.session.set_transform(moved)
    info = e.frame()
    e.finish_refinement()
    assert not info["room"]                                     # the splats are not redrawn
    s = small_session()
    s.set_transform(moved)
    fresh = make_engine(ctx, session=s)
    fresh.session.settings.set("pbgi.differential", False)
    fresh.frame()
    fresh.finish_refinement()
    np.testing.assert_array_equal(e.view.read_linear()[..., 3] > 0,
                                  fresh.view.read_linear()[..., 3] > 0)


def test_stats_skip_tiles_outside_the_silhouette(ctx, renders):
    """The PBGI panel shows the last gather that had receivers, not the zeros of an empty
    corner tile; a new mode shows at once even from an empty tile."""
    e = make_engine(ctx)
    e.frame()
    e.finish_refinement()
    shown = e.gi_stats
    assert shown.receivers > 0 and shown.nodes_visited > 0
    e._render_gi(e.gi.camera, (0, 0, 4, 4))                       # the corner: only room
    assert renders[-1].receivers == 0 and e.gi_stats is shown
    e.session.settings.set("pbgi.mode", "envmap")
    e._render_gi(e.gi.camera, (0, 0, 4, 4))
    assert e.gi_stats.mode == "envmap" and e.gi_stats.receivers == 0


def test_screenshot_png_is_the_tone_mapped_exr(ctx, renders, tmp_path):
    from tests.support.images import read_png

    from app.io.exr import read_exr
    from app.render.tonemap import tonemap_to_srgb8
    e = make_engine(ctx)
    e.session.settings.set("view.exposure", 0.5)
    e.frame()
    files = e.screenshot(tmp_path / "shot.png")
    assert not e.gi.refining                                        # screenshots are converged
    png, lin = read_png(files[0]), read_exr(files[1]).rgb
    assert png.shape == (72, 96, 3) and lin.shape == (72, 96, 3)
    expect = tonemap_to_srgb8(lin, 0.5)
    assert np.abs(png.astype(int) - expect.astype(int)).max() <= 1


def test_missing_renderer_shows_a_placeholder_not_a_crash(ctx):
    """A renderer that cannot start (here: its module is missing) is a message in the window,
    the asset shows the hatch with a label, and the viewer keeps running."""
    import importlib

    def missing_renderer(ctx):
        return importlib.import_module("app.pbgi.no_such_renderer").Relighter(ctx=ctx)
    e = make_engine(ctx, (160, 120), relighter=missing_renderer)
    for _ in range(3):
        e.frame()
    assert not e.renderer_available and "no_such_renderer" in e.relighter_error
    assert any("renderer failed to start" in m.text and "no_such_renderer" in m.text
               for m in e.messages)
    lin = e.view.read_linear()
    asset = lin[..., 3] > 0
    assert asset.sum() > 200
    levels = np.unique(lin[asset][:, 0])
    np.testing.assert_allclose(levels, [0.10, 0.16], rtol=1e-6)       # the hatch pattern
    shown = e.view.read_display().astype(int)
    assert (shown[asset] > 240).all(axis=-1).sum() > 20               # white label text


def test_bad_files_and_failing_renderer_become_messages(ctx, renders, monkeypatch, tmp_path):
    e = make_engine(ctx)
    e.frame()
    # the real renderer refusing its input (no material) is a message, and the loop goes on
    e.session.set_materials([])
    e.frame()
    e.frame()
    assert e.gi_failed and any(m.text.startswith("relighting: ") and "material" in m.text
                               for m in e.messages)
    e.reset_materials()
    n = len(renders)
    e.frame()
    e.finish_refinement()
    assert not e.gi_failed and e.gi_stats.completed
    assert sum(c.receivers for c in renders[n:]) > 100               # relit again

    def boom(*a, **k):      # an unexpected bug inside the renderer (fault injection)
        raise RuntimeError("GPU on fire")
    monkeypatch.setattr(e.relighter, "render", boom)
    e.session.set_material(0, {"roughness": 0.9})          # gathers again (metallic would not)
    e.frame()
    e.frame()
    assert e.gi_failed and any("GPU on fire" in m.text for m in e.messages)
    monkeypatch.undo()

    e.session.set_file("cloud", str(tmp_path / "missing.ply"))
    e.frame()
    assert any("missing.ply" in m.text for m in e.messages)
    assert len(e.cloud.ldr) > 1000                                    # the old room stays
    bad = tmp_path / "broken.glb"
    bad.write_bytes(b"glTF garbage")
    e.session.set_file("asset", str(bad))
    e.frame()
    assert any("broken.glb" in m.text for m in e.messages)
    assert e.mesh is not None                                         # the old asset stays


def test_a_scene_without_a_room_keeps_running(ctx, renders, tmp_path):
    """The first cloud fails to open: an empty room; the real renderer refuses to relight
    without a cloud, which is a message, and the asset shows as the placeholder hatch."""
    s = small_session()
    s.cloud = str(tmp_path / "missing.ply")
    e = make_engine(ctx, session=s)
    e.frame()
    e.frame()
    assert any("missing.ply" in m.text for m in e.messages)
    assert e.gi_failed and any(m.text.startswith("relighting: ") and "cloud" in m.text
                               for m in e.messages)
    lin = e.view.read_linear()
    asset = lin[..., 3] > 0
    assert asset.sum() > 200
    np.testing.assert_allclose(np.unique(lin[asset][:, 0]), [0.10, 0.16], rtol=1e-6)


def test_session_round_trip_renders_the_same_image(ctx, renders, tmp_path):
    from app.settings import load_session
    e = make_engine(ctx)
    e.nav.orbit(40, 10)
    e.session.set_material(0, {"base_color": [0.2, 0.5, 0.9], "roughness": 0.2})
    e.session.settings.set("view.exposure", -0.5)
    e.frame()
    e.finish_refinement()
    first = e.view.read_display()
    e.session.camera = e.camera()
    e.session.save(tmp_path / "s.json")
    e2 = make_engine(ctx, session=load_session(tmp_path / "s.json"))
    e2.frame()
    e2.finish_refinement()
    np.testing.assert_array_equal(e2.view.read_display(), first)


def _expansion_request(e, face=64):
    from app.hdr.job import ExpandRequest
    e.session.settings.set("hdr.face_size", face)
    return ExpandRequest.from_settings(e.cloud.ldr, e.photo,
                                       [c.position for c in e.session.capture_cameras],
                                       e.session.settings)


def test_expansion_switches_the_room_to_hdr(ctx, renders):
    """The expanded cloud is shown and relights the asset: the lights no longer clip at 1, so
    the relit asset gets brighter (the real renderer gathers the new node colours)."""
    from app.ui.hdr_task import ExpansionTask
    e = make_engine(ctx)
    e.frame()
    e.finish_refinement()
    ldr = e.view.read_linear()
    task = ExpansionTask(_expansion_request(e), synchronous=True)
    assert task.state == "done", task.error
    n = len(renders)
    e.set_hdr_cloud(task.result.cloud)
    assert e.session.settings["view.cloud"] == "hdr"
    e.frame()
    e.finish_refinement()
    assert len(renders) > n
    hdr = e.view.read_linear()
    room, asset = hdr[..., 3] == 0, hdr[..., 3] > 0
    assert hdr[room][:, :3].max() > 1.5 and ldr[room][:, :3].max() <= 1.0 + 1e-6
    assert hdr[asset][:, :3].mean() > 1.5 * ldr[asset][:, :3].mean()        # measured: 2.2x
    e.session.settings.set("view.cloud", "difference")
    e.frame()
    diff = e.view.read_linear()[room][:, :3]
    unchanged = np.all(np.abs(diff - (0.01, 0.01, 0.02)) < 1e-6, axis=1)
    assert diff.max() <= 1.0 and 0.5 < unchanged.mean() < 1.0      # most points kept LDR


def test_difference_colours_follow_the_stops():
    from app.ui.scene import DIFF_STOPS, difference_colors
    ldr = np.full((4, 3), 0.5, np.float32)
    hdr = ldr * np.array([1.0, 2 ** (DIFF_STOPS / 2), 2 ** DIFF_STOPS, 2 ** 20])[:, None]
    c = difference_colors(ldr, hdr)
    np.testing.assert_allclose(c[0], (0.01, 0.01, 0.02), atol=1e-6)   # unchanged: black
    np.testing.assert_allclose(c[1], (0.1, 0.7, 0.2), atol=1e-3)      # half way: green
    np.testing.assert_allclose(c[2:], 1.0, atol=1e-3)                 # >= DIFF_STOPS: white


def _provenance_cloud(ldr, seed=3):
    """A stand-in expansion of ``ldr``: random labels, registered points with q in {0, 0.5, 1,
    NaN}, PatchMatch points with SSD scores, the others NaN (app/hdr/result.py PROVENANCE)."""
    from app.cloud import PointCloud
    from app.hdr.result import PROJECTED, PROVENANCE, PROVENANCE_ATTR, REGISTERED, SCORE_ATTR
    rng = np.random.default_rng(seed)
    labels = rng.choice(sorted(PROVENANCE), len(ldr)).astype(np.uint8)
    scores = np.full(len(ldr), np.nan, np.float32)
    reg = labels == REGISTERED
    scores[reg] = rng.choice([0.0, 0.5, 1.0, np.nan], int(reg.sum()))
    scores[labels == PROJECTED] = rng.uniform(0, 3, int((labels == PROJECTED).sum()))
    return PointCloud(ldr.positions, ldr.normals, ldr.colors * 3.0, True,
                      attributes={PROVENANCE_ATTR: labels, SCORE_ATTR: scores})


def _palette_colours(labels, scores):
    """The provenance view's colours computed here from the palette alone: each label's sRGB
    colour, a registered point's scaled by Q_FLOOR + (1 - Q_FLOOR) q (NaN q: full), linearised."""
    from app.color import srgb_to_linear
    from app.hdr.result import REGISTERED
    from app.ui.provenance import PALETTE, Q_FLOOR
    srgb = np.zeros((len(labels), 3))
    for label, rgb in PALETTE.items():
        srgb[labels == label] = np.array(rgb) / 255.0
    reg = labels == REGISTERED
    q = np.where(np.isnan(scores[reg]), 1.0, scores[reg])
    srgb[reg] *= (Q_FLOOR + (1 - Q_FLOOR) * q)[:, None]
    return srgb_to_linear(srgb)


def test_provenance_view_colours_points_by_label_and_lights_with_hdr(ctx, renders):
    """The provenance view: each point in its label's palette colour (registered ones dimmed by
    a low q), shown raw (the splats' linear colours reach the picture unchanged), no asset
    shadow on the false colours; the asset stays lit by the HDR cloud. A cloud without
    provenance shows every point in the NO_PROVENANCE grey."""
    from app.color import srgb_to_linear, to_uint8_srgb
    from app.hdr.result import PROVENANCE_ATTR, SCORE_ATTR
    from app.ui.provenance import NO_PROVENANCE
    from app.ui.viewport import BACKGROUND
    e = make_engine(ctx)
    hdr = _provenance_cloud(e.cloud.ldr)
    e.set_hdr_cloud(hdr)
    e.session.settings.set("view.cloud", "provenance")
    e.session.settings.set("view.exposure", 2.0)      # false colours ignore it
    e.frame()
    e.finish_refinement()
    labels, scores = hdr.attributes[PROVENANCE_ATTR], hdr.attributes[SCORE_ATTR]
    want = _palette_colours(labels, scores)
    np.testing.assert_allclose(e.cloud.colors("provenance"), want, rtol=1e-6, atol=1e-7)
    assert e._lit_cloud is hdr and e._diff_shown_key is None
    img = e.view.read_linear()
    room = (img[..., 3] == 0) & np.any(np.abs(img[..., :3] - BACKGROUND[:3]) > 1e-6, axis=-1)
    px = img[room][:, :3]
    palette = np.unique(want, axis=0)   # 5 labels + registered at q = 0 and 0.5 (NaN: as q = 1)
    assert len(palette) == 7 and room.sum() > 1000
    nearest = np.abs(px[:, None, :] - palette[None]).max(axis=-1).min(axis=1)
    assert nearest.max() < 1e-5                       # every room pixel is a palette colour
    shown = e.view.read_display()[room].astype(int)   # raw: sRGB-encoded, no exposure
    assert np.abs(shown - to_uint8_srgb(px)).max() <= 1
    e.set_hdr_cloud(replace(hdr, attributes={}))      # e.g. an HDR file from before provenance
    e.session.settings.set("view.cloud", "provenance")
    e.frame()
    grey = srgb_to_linear(np.array(NO_PROVENANCE) / 255.0)
    np.testing.assert_allclose(e.cloud.colors("provenance"),
                               np.broadcast_to(grey, (len(hdr), 3)), atol=1e-7)
    img = e.view.read_linear()
    np.testing.assert_allclose(img[room][:, :3], np.broadcast_to(grey, px.shape), atol=1e-5)


def test_frame_loop_keeps_running_during_an_expansion(ctx, renders):
    """Frames while the expansion job runs in its worker thread, against frames without it.

    Bound: no frame longer than 4x the median frame without the job plus 250 ms. The job and the
    viewer share 2 cores, so frames may take a few times longer, but a frame blocked by the job
    (GIL held through a long pure-Python step, or the job on the main thread) would take seconds.
    Also: at least 10 frames ran while the job made progress.
    """
    from app.ui.hdr_task import ExpansionTask
    e = make_engine(ctx, (96, 72))
    base = []
    for _ in range(12):
        e.nav.orbit(3, 0)
        base.append(e.frame()["ms"])
    task = ExpansionTask(_expansion_request(e), synchronous=False)
    during, fractions = [], []
    t0 = time.perf_counter()
    while task.running and time.perf_counter() - t0 < 120:
        e.nav.orbit(3, 0)
        during.append(e.frame()["ms"])
        task.poll()
        fractions.append(task.snapshot()[1])
    assert task.state == "done", task.error
    bound = 4 * float(np.median(base)) + 250.0
    assert len(during) >= 10
    assert fractions[-1] > fractions[0]
    assert max(during) <= bound, (max(during), bound, np.median(base))


def test_opening_files_by_kind(ctx, renders, tmp_path, demo):
    """What drag-and-drop and the file dialogs do: the engine reloads only what changed."""
    import json

    from app.errors import ScanlightError
    from app.io.pointcloud import save_cloud
    from app.ui.files import open_into
    e = make_engine(ctx)
    e.frame()
    small = demo.ldr.subset(np.arange(0, len(demo.ldr), 20))
    save_cloud(small, tmp_path / "scan.ply")
    assert open_into(e.session, tmp_path / "scan.ply") == "cloud"
    e.frame()
    assert len(e.cloud.ldr) == len(small) and not e.messages
    (tmp_path / "obj.json").write_text(json.dumps({"mesh": "sphere", "translate": [0, 1, 0],
                                                   "scale": 0.5}))
    assert open_into(e.session, tmp_path / "obj.json") == "object"
    e.frame()
    lo, hi = e.mesh.bounds()
    np.testing.assert_allclose((lo + hi) / 2, (0, 1, 0), atol=1e-3)
    np.testing.assert_allclose(hi - lo, 0.5, atol=1e-3)
    e.session.save(tmp_path / "s.json")
    assert open_into(e.session, tmp_path / "s.json") == "session"
    with pytest.raises(ScanlightError, match="don't know how to open"):
        open_into(e.session, tmp_path / "notes.txt")


def test_capture_preview_sees_the_room_in_six_directions(ctx, renders):
    e = make_engine(ctx)
    img = e.capture_preview((0.5, 1.4, 0.8), face=16)
    assert img.shape == (48, 64, 3)
    cells = {(r, c): img[r * 16:(r + 1) * 16, c * 16:(c + 1) * 16] for r in range(3)
             for c in range(4)}
    used = {(1, 0), (1, 1), (1, 2), (1, 3), (0, 1), (2, 1)}
    for key, cell in cells.items():
        if key in used:
            assert cell.mean() > 20, key            # inside a closed room every face sees walls
        else:
            assert cell.max() == 0, key
    # up (+Y) sees the bright ceiling light more than down (-Y) sees the floor
    assert cells[(0, 1)].max() >= cells[(2, 1)].max()


def test_the_assets_shadow_lands_on_the_scan(ctx):
    """Once the picture is refined the scan's points near the asset get its shadow: the splats
    under the demo sphere darken (the room's pixels elsewhere do not change), a moved asset
    drops the old shadow at once, and switching the differential off restores the scan."""
    e = make_engine(ctx, (96, 72))
    s = e.session.settings
    s.set("pbgi.differential", False)
    e.frame()
    e.finish_refinement()
    plain = e.view.read_linear()
    s.set("pbgi.differential", True)
    e.frame()
    e.finish_refinement()
    assert e._diff_shown_key is not None and e.differential_progress == 1.0
    shadowed = e.view.read_linear()
    room = (plain[..., 3] == 0) & (shadowed[..., 3] == 0)    # alpha = asset
    lum = lambda img: img[..., :3].mean(axis=-1)    # noqa: E731
    darker = room & (lum(shadowed) < 0.9 * lum(plain))
    assert darker.sum() > 20                        # a shadow, on the room's pixels
    brighter = room & (lum(shadowed) > 1.1 * lum(plain) + 1e-3)
    assert brighter.sum() < 0.2 * darker.sum()
    t = e.session.transform
    e.session.set_transform(replace(t, translate=(t.translate[0] + 0.5, t.translate[1],
                                                  t.translate[2])))
    e.frame(interacting=True)
    assert e._diff_shown_key is None                # the old shadow is gone with the move
    s.set("pbgi.differential", False)
    e.finish_refinement()
    assert e._diff_shown_key is None


def test_a_moving_camera_gets_the_cheap_backdrop_then_the_full_one(ctx, renders):
    """While the camera moves the room is drawn with the FAST splat pass (opaque camera-facing
    sprites, SplatRenderer.render(fast=True)); the first still frame redraws it in full, and so
    does finish_refinement."""
    e = make_engine(ctx, (80, 60))
    e.frame()
    e.nav.orbit(10, 0)
    info = e.frame(interacting=True)
    assert info["room"] and info["room_fast"]
    cam = e.camera()
    room = e.view.read_inputs()["room"][::-1]
    np.testing.assert_allclose(room, e.view.splat.render(cam, fast=True), atol=1e-6)
    info = e.frame()                                   # the camera stopped
    assert info["room"] and not info["room_fast"]
    room = e.view.read_inputs()["room"][::-1]
    np.testing.assert_allclose(room, e.view.splat.render(cam), atol=1e-6)
    assert not e.frame()["room"]                       # and stays until the camera moves
    e.nav.orbit(10, 0)
    e.frame(interacting=True)
    e.finish_refinement()
    room = e.view.read_inputs()["room"][::-1]
    np.testing.assert_allclose(room, e.view.splat.render(e.camera()), atol=1e-6)
