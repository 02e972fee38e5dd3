"""Progressive refinement (app/ui/refine.py): the scheduling arithmetic (budgets, cell sizes,
preview scales) with an analytic sphere and a fake clock, so the timings are exact; and the
tiling with the real PBGI renderer."""

from __future__ import annotations

import numpy as np
import pytest

from app.camera import Camera
from app.ui.refine import (ProgressiveGI, scaled_camera, screen_rect, strip_tiles,
                           time_left_words)

CENTRE, RADIUS = np.array([0.0, 0.6, 0.0]), 0.4


def sphere_image(cam: Camera, tile) -> np.ndarray:
    """Analytic render of a sphere: colour = normal * 0.5 + 0.5, alpha = hit (per pixel, so
    the result cannot depend on the tiling)."""
    x0, y0, w, h = tile
    o, d = cam.pixel_rays()
    d = d[y0:y0 + h, x0:x0 + w].reshape(-1, 3)
    oc = o - CENTRE
    b = d @ oc
    disc = b * b - (oc @ oc - RADIUS ** 2)
    hit = disc > 0
    t = -b - np.sqrt(np.maximum(disc, 0))
    n = (o + t[:, None] * d - CENTRE) / RADIUS
    img = np.zeros((h * w, 4), np.float32)
    img[hit, :3] = n[hit] * 0.5 + 0.5
    img[hit, 3] = 1
    return img.reshape(h, w, 4)


class Clock:
    """Fake time: each render 'costs' ms_per_px per pixel."""

    def __init__(self, ms_per_px: float):
        self.t, self.ms_per_px, self.calls = 0.0, ms_per_px, []

    def __call__(self):
        return self.t

    def render(self, cam, tile, pass_index=0, layer=None):
        self.calls.append((cam.width, tile))
        self.t += self.ms_per_px * tile[2] * tile[3] / 1e3
        return sphere_image(cam, tile)


CAM = Camera((0.3, 1.0, 1.8), CENTRE, fov_y_deg=50, width=120, height=90)


def test_strip_tiles_cover_the_rectangle_once():
    rect = (7, 5, 75, 50)
    cover = np.zeros((90, 120), int)
    bands = strip_tiles(rect, 16)
    for band in bands:
        for x, y, w, h in band:
            cover[y:y + h, x:x + w] += 1
    assert cover[5:55, 7:82].min() == 1 and cover.sum() == 75 * 50
    mids = [b[0][1] for b in bands]
    assert abs(mids[0] + 8 - 30) <= 16   # the middle band comes first


def test_screen_rect_contains_the_silhouette():
    full = sphere_image(CAM, (0, 0, CAM.width, CAM.height))
    ys, xs = np.nonzero(full[..., 3])
    x, y, w, h = screen_rect(CAM, CENTRE - RADIUS, CENTRE + RADIUS)
    assert x <= xs.min() and xs.max() < x + w and y <= ys.min() and ys.max() < y + h
    behind = Camera((0, 0.6, 0), (0, 0.6, -1), width=40, height=30)   # eye inside the box
    assert screen_rect(behind, CENTRE - RADIUS, CENTRE + RADIUS) == (0, 0, 40, 30)
    away = Camera((0, 0.6, 3), (0, 0.6, 6), width=40, height=30)      # box behind the eye
    assert screen_rect(away, CENTRE - RADIUS, CENTRE + RADIUS) == (0, 0, 40, 30)


def test_converged_layer_equals_a_direct_render():
    clock = Clock(0.01)
    gi = ProgressiveGI(clock.render, clock)
    rect = screen_rect(CAM, CENTRE - RADIUS, CENTRE + RADIUS)
    gi.restart(CAM, rect, 0.25, budget_ms=5)
    assert gi.refining and gi.progress == 0.0
    gi.finish()
    assert not gi.refining and gi.progress == 1.0
    direct = sphere_image(CAM, (0, 0, CAM.width, CAM.height))
    np.testing.assert_array_equal(gi.full, direct)          # tiling changes nothing
    small = scaled_camera(CAM, 1 / 16)          # the first preview, before any cost is known
    assert gi.preview_camera.width == small.width
    assert gi.preview.shape[:2] == (small.height, small.width)
    np.testing.assert_array_equal(gi.preview[..., 3] > 0, sphere_image(
        small, (0, 0, small.width, small.height))[..., 3] > 0)


def test_tiles_of_the_real_renderer_add_up_to_a_direct_render(ctx, demo):
    """The real PBGI renderer, refined in many small tiles, gives its own one-call image: same
    coverage to the pixel, radiance within 1% of the asset's brightest pixel (tiles rasterise
    the G-buffer through a sub-window of the projection, which moves positions by float
    rounding; measured 0.4% here)."""
    from app.pbgi.renderer import Relighter, RenderParams
    from app.ui.engine import default_session
    from app.ui.scene import Asset
    s = default_session()
    mesh = Asset(s.asset).placed(s.transform)
    r = Relighter(ctx)
    r.set_cloud(demo.ldr)
    r.set_asset(mesh)
    lo, hi = mesh.bounds()
    c = (np.asarray(lo) + np.asarray(hi)) / 2
    cam = Camera(c + np.array([0.4, 0.3, 1.2]), c, fov_y_deg=50, width=64, height=48)
    params = RenderParams(mode="classic", microbuffer=8)
    direct = r.render(cam, None, params).image
    tiles = []

    def render(camera, tile, pass_index, layer):
        tiles.append(tile)
        return r.render(camera, None, params, tile=tile, pass_index=pass_index,
                        layer=layer).image
    gi = ProgressiveGI(render)
    gi.restart(cam, screen_rect(cam, lo, hi), 0.25, budget_ms=1)
    while gi.refining:                    # a tiny frame budget: the smallest cells, one a frame
        gi.step(1)
    r.release()
    assert len(tiles) > 4 and (direct[..., 3] > 0).sum() > 500
    np.testing.assert_array_equal(gi.full[..., 3], direct[..., 3])
    np.testing.assert_allclose(gi.full[..., :3], direct[..., :3],
                               atol=0.01 * direct[..., :3].max())


@pytest.mark.parametrize("glossy", [False, True])
def test_hybrid_tiles_of_a_pass_add_up_to_one_render_of_the_layer(demo_relighter, glossy):
    """Each tile is a render call of its own. Told its layer, the renderer shares the layer's
    G-buffer, Hybrid's far-field blocks (chosen over the whole layer, each walked once) and the
    lobes' seeds (pixels of the image) between the tiles of a pass: the tiles add up to one
    render of the layer, in every pass (each moves the block grid), and a tile's edge differs
    from the rest no more than in that render. Without the layer each tile chose its own blocks,
    which ended at its edges: a line (demo close-up 96 x 96, M 16, cells of 16, diffuse: across
    / inside the cell edges 1.74 against 1.15; tests/support/block_steps.py)."""
    from app.demo.room import default_views
    from app.material import Material
    from app.pbgi.renderer import RenderParams
    from tests.support import scenes as S
    from tests.support.block_steps import block_steps
    from scipy.ndimage import binary_erosion
    cam, cell, rect = default_views(96, 96)["closeup"], 16, (0, 0, 96, 96)
    params = RenderParams(mode="hybrid", microbuffer=16)
    mat = (Material(base_color=(0.2, 0.4, 0.8), roughness=0.3) if glossy   # plastic: both
           else S.diffuse(0.6))                                          # buffers
    calls = []

    def layer_of(share: bool, passes: int, interrupt: bool = False) -> np.ndarray:
        def render(camera, tile, p, layer):
            calls.append(layer)
            return demo_relighter.render(camera, [mat], params, tile=tile, pass_index=p,
                                         layer=layer if share else None,
                                         passes=passes).image
        gi = ProgressiveGI(render)
        gi.cell_size = lambda budget_ms: cell
        if interrupt:                       # a few tiles, then the same view again
            gi.restart(cam, rect, 0.25, budget_ms=1e9, passes=passes)
            for _ in range(3):
                gi.step(1)
        gi.restart(cam, rect, 0.25, budget_ms=1e9, passes=passes)
        gi.finish()
        return gi.full

    def direct(passes: int) -> np.ndarray:
        """The mean of one render of the layer per pass, over the passes that hit."""
        imgs = [demo_relighter.render(cam, [mat], params, pass_index=p, passes=passes).image
                for p in range(passes)]
        hits = sum(im[..., 3] for im in imgs)
        out = np.zeros_like(imgs[0])
        seen = hits > 0
        sums = sum(im[..., :3] * im[..., 3:] for im in imgs)
        out[..., :3][seen] = sums[seen] / hits[seen][:, None]
        out[..., 3] = seen
        return out

    def close(a, b):
        np.testing.assert_array_equal(a[..., 3] > 0.5, b[..., 3] > 0.5)
        np.testing.assert_allclose(a[..., :3], b[..., :3], rtol=0, atol=1e-5 * b[..., :3].max())
    one = direct(1)
    tiles = layer_of(True, 1)
    close(tiles, one)
    assert calls[0] is None and calls[1] == rect        # the preview has no layer; tiles do
    close(layer_of(True, 2), direct(2))     # pass 1 moves the block grid
    close(layer_of(True, 1, interrupt=True), one)   # a pass begun again starts its blocks anew
    mask = binary_erosion(one[..., 3] > 0.5, iterations=2)
    single = block_steps(one, mask, block=cell)["ratio"]
    assert block_steps(tiles, mask, block=cell)["ratio"] == pytest.approx(single, rel=1e-4)
    if not glossy:                          # the control: tiles without their layer
        assert block_steps(layer_of(False, 1), mask, block=cell)["ratio"] > 1.3 * single


@pytest.mark.parametrize("ms_per_px,side", [
    (0.05, 16),         # llvmpipe-like: 40 ms / 0.05 ms = 800 px -> side 28 -> 16
    (0.002, 128),       # a GPU (H100, Hybrid M 24): 20,000 px -> side 141 -> 128
    (1e-5, 256),        # nearly free: the cap
    (10.0, 8),          # dearer than a budget per cell: the floor
])
def test_cells_grow_with_a_cheap_pixel_up_to_the_cap(ms_per_px, side):
    """A GPU's cheap pixels get cells up to 256 px (a 64 px cell cannot fill one), a CPU's keep
    the small cells; half of an 80 ms budget per cell, a power of two, rounded down."""
    gi = ProgressiveGI(lambda *a, **k: None)
    gi.ms_per_px = ms_per_px
    assert gi.cell_size(80) == side


def test_steps_respect_the_budget_and_tiles_wait_for_idle():
    clock = Clock(0.05)                       # 0.05 ms per pixel
    gi = ProgressiveGI(clock.render, clock)
    rect = screen_rect(CAM, CENTRE - RADIUS, CENTRE + RADIUS)
    gi.restart(CAM, rect, 0.25, budget_ms=20)
    gi.step(20, allow_tiles=False)            # interacting: preview only (first one at 1/16)
    assert [c[0] for c in clock.calls] == [8] and gi.progress == 0.0 and gi.refining
    gi.step(20, allow_tiles=False)
    assert len(clock.calls) == 1              # still nothing more while interacting
    # Cells were sized from the measured cost to at most half a budget, rounded down to a power
    # of two: 10 ms / 0.05 ms/px = 200 px -> side 14.1 -> 8 x 8.
    assert gi.cell_size(20) == 8
    last = 0.0
    while gi.refining:
        t0 = clock.t
        n = len(clock.calls)
        gi.step(20)
        spent = (clock.t - t0) * 1e3
        # the budget is respected: a frame starts another cell only when it still fits
        assert spent <= 20 + 1e-9
        assert len(clock.calls) > n           # every frame advances
        assert gi.progress >= last
        last = gi.progress
    assert gi.progress == 1.0


def test_preview_scale_is_predicted_from_the_cost_per_pixel():
    """One render call cannot be interrupted: once the cost per pixel is known, the preview of a
    large asset rectangle is sized to about one frame budget before it is rendered (above the
    1/16 floor: here the fit is about 1/14)."""
    clock = Clock(0.02)
    gi = ProgressiveGI(clock.render, clock)
    big = Camera(CAM.position, CAM.look_at, fov_y_deg=50, width=1200, height=900)
    rect = screen_rect(big, CENTRE - RADIUS, CENTRE + RADIUS)
    gi.restart(big, rect, 0.25, budget_ms=40)
    gi.step(40, allow_tiles=False)             # first preview at 1/16 teaches the cost
    for _ in range(3):
        gi.restart(big, rect, 0.25, budget_ms=40)
        t0 = clock.t
        gi.step(40, allow_tiles=False)
        assert (clock.t - t0) * 1e3 <= 40 * 1.3   # one budget (+ rounding up of sizes)


def test_slow_previews_lower_the_preview_scale():
    clock = Clock(2.0)                        # very slow renderer
    gi = ProgressiveGI(clock.render, clock)
    rect = screen_rect(CAM, CENTRE - RADIUS, CENTRE + RADIUS)
    gi.restart(CAM, rect, 0.25)
    gi.step(10, allow_tiles=False)
    assert gi.effective_scale < 0.25
    clock.ms_per_px = 1e-6                    # fast again: climbs back, never above the setting
    for _ in range(10):
        gi.restart(CAM, rect, 0.25)
        gi.step(10, allow_tiles=False)
    assert gi.effective_scale == 0.25


def test_restart_resets_only_the_old_and_new_rectangles():
    clock = Clock(0.0)
    gi = ProgressiveGI(clock.render, clock)
    rect = screen_rect(CAM, CENTRE - RADIUS, CENTRE + RADIUS)
    gi.restart(CAM, rect, 0.5)
    gi.finish()
    gi.take_dirty()
    moved = (rect[0] + 10, rect[1], rect[2], rect[3])
    gi.restart(CAM, moved, 0.5)
    preview, reset, rects = gi.take_dirty()
    assert not reset and rects == [rect, moved]
    x, y, w, h = moved
    assert (gi.full[y:y + h, x:x + w, 3] == -1).all()        # pending, not stale
    assert (gi.full[rect[1]:rect[1] + rect[3], rect[0]:rect[0] + 10, 3] == 0).all()


# The words of the overlay, on constructed timelines. RECT_20 is 20 bands of six 8 x 8 cells:
# at 0.05 ms/px and a 20 ms budget every frame renders exactly one band (6 cells, 19.2 ms), so
# frame k ends with k/20 done, and a frame of FRAME seconds (GI included) makes the wall time
# after k frames k * FRAME and the estimated total 20 * FRAME.
BIG = Camera(CAM.position, CAM.look_at, fov_y_deg=50, width=480, height=360)
RECT_20 = (0, 0, 48, 160)
TILES_S = 6 * 64 * 0.05e-3


def _previewed(clock: Clock) -> ProgressiveGI:
    gi = ProgressiveGI(clock.render, clock)
    gi.restart(BIG, RECT_20, 0.25, budget_ms=20)
    gi.step(20, allow_tiles=False)
    return gi


def _frame(gi: ProgressiveGI, clock: Clock, seconds: float) -> str:
    """One frame of ``seconds``: the rest of the frame, then its GI step."""
    clock.t += seconds - TILES_S
    gi.step(20)
    return gi.status_words()


def test_the_overlay_says_the_refinement_and_the_time_left_in_words():
    """Frames of 0.8 s (the GI step is only 19.2 ms of each: the estimate is wall-clock, not
    render time): 20 frames in all, so after frame k, 16 - 0.8 k seconds are left."""
    clock = Clock(0.05)
    gi = _previewed(clock)
    assert gi.status_words() == "preview at 1/16 resolution"
    words = [_frame(gi, clock, 0.8) for _ in range(20)]
    assert words == [
        "refining 5%, about 15 s left",      # 15.2 s
        "refining 10%, about 15 s left",     # 14.4: 5 s steps above 10 s, no flicker
        "refining 15%, about 15 s left",
        "refining 20%, about 15 s left",     # 12.8
        "refining 25%, about 10 s left",     # 12.0
        "refining 30%, about 10 s left",
        "refining 35%, about 10 s left",
        "refining 40%, about 10 s left",     # 9.6: whole seconds below 10 s
        "refining 45%, about 9 s left",
        "refining 50%, about 8 s left",
        "refining 55%, about 7 s left",
        "refining 60%, about 6 s left",
        "refining 65%, about 6 s left",      # 5.6
        "refining 70%, about 5 s left",
        "refining 75%, about 4 s left",
        "refining 80%, about 3 s left",
        "refining 85%, about 2 s left",
        "refining 90%, about 2 s left",      # 1.6
        "refining 95%, less than 1 s left",  # 0.8
        "converged",
    ]


def test_the_estimate_waits_for_enough_data():
    """Fast frames: 5% of the cells after the first one, but only 0.12 s of wall time."""
    clock = Clock(0.05)
    gi = _previewed(clock)
    words = [_frame(gi, clock, 0.12) for _ in range(6)]
    assert words[:4] == ["refining 5%, estimating the time left",
                         "refining 10%, estimating the time left",
                         "refining 15%, estimating the time left",
                         "refining 20%, estimating the time left"]
    assert words[4:] == ["refining 25%, about 2 s left",        # 0.6 s in: 1.8 s left
                         "refining 30%, about 2 s left"]        # 1.68 s


def test_interaction_pauses_and_a_restart_start_the_estimate_again():
    clock = Clock(0.05)
    gi = _previewed(clock)
    for _ in range(10):
        words = _frame(gi, clock, 0.8)
    assert words == "refining 50%, about 8 s left"
    for _ in range(3):                  # the user drags a slider: tiles wait, time is not counted
        clock.t += 5.0
        gi.step(20, allow_tiles=False)
        assert gi.status_words() == "refining 50%, about 8 s left"
    assert _frame(gi, clock, 0.8) == "refining 55%, about 7 s left"
    # A new view: a new preview, and an estimate owing nothing to the old one (frames now 2 s).
    gi.restart(BIG, RECT_20, 0.25, budget_ms=20)
    assert gi.seconds_left() is None
    gi.step(20, allow_tiles=False)
    assert gi.status_words() == f"preview at 1/{1 / gi.shown_scale:.0f} resolution"
    assert _frame(gi, clock, 2.0) == "refining 5%, about 40 s left"      # 38 s
    assert _frame(gi, clock, 2.0) == "refining 10%, about 35 s left"     # 36 s


def test_the_estimate_is_smoothed_when_the_frames_slow_down():
    """Ten frames of 0.5 s, then frames of 1.5 s: each frame's estimate of the total moves the
    smoothed one by 30% of the way (refine.ETA_SMOOTHING)."""
    clock = Clock(0.05)
    gi = _previewed(clock)
    for _ in range(10):
        words = _frame(gi, clock, 0.5)
    assert words == "refining 50%, about 5 s left"              # total 10 s
    assert _frame(gi, clock, 1.5) == "refining 55%, about 4 s left"
    total = 10 + 0.3 * (6.5 / 0.55 - 10)
    assert gi.seconds_left() == pytest.approx(total - 6.5)      # 4.05 s (unsmoothed: 5.3 s)
    assert _frame(gi, clock, 1.5) == "refining 60%, about 3 s left"
    total += 0.3 * (8.0 / 0.6 - total)
    assert gi.seconds_left() == pytest.approx(total - 8.0)


def test_a_slow_machine_hears_minutes():
    clock = Clock(0.05)
    gi = _previewed(clock)
    assert _frame(gi, clock, 30.0) == "refining 5%, about 10 min left"   # 570 s


@pytest.mark.parametrize("seconds, words", [
    (None, "estimating the time left"), (0.0, "less than 1 s left"), (0.99, "less than 1 s left"),
    (1.0, "about 1 s left"), (6.4, "about 6 s left"), (9.6, "about 10 s left"),
    (12.4, "about 10 s left"), (47.0, "about 45 s left"), (87.4, "about 85 s left"),
    (88.0, "about 2 min left"), (150.0, "about 3 min left"), (5399.0, "about 90 min left"),
    (7200.0, "about 2 h left")])
def test_time_left_words_are_rounded_coarsely(seconds, words):
    assert time_left_words(seconds) == words


def test_idle_passes_average_the_jittered_renders_of_the_asset():
    """With passes, the complete layer is re-rendered pass by pass (pass_index 1, 2, ...) and
    each texel shows the mean radiance of the passes that saw the asset (unpremultiplied:
    a texel the asset covered in one pass of three shows that pass's radiance)."""
    calls = []

    def render(camera, tile, pass_index=0, layer=None):
        calls.append(pass_index)
        img = sphere_image(camera, tile)
        img[..., :3] = float(pass_index + 1)          # pass k renders radiance k + 1
        if pass_index == 2:                         # the asset grows by a column in pass 2
            img[:, -1:, 3] = 1.0
        return img
    gi = ProgressiveGI(render)
    rect = screen_rect(CAM, CENTRE - RADIUS, CENTRE + RADIUS)
    gi.restart(CAM, rect, 0.25, budget_ms=5, passes=3)
    gi.step(5)
    assert gi.pass_index == 0
    while gi.refining:
        gi.step(1e9)
    assert gi.pass_index == 2 and gi.progress == 1.0 and gi.status_words() == "converged"
    assert set(calls) == {0, 1, 2}
    inside = sphere_image(CAM, (0, 0, CAM.width, CAM.height))[..., 3] > 0
    np.testing.assert_allclose(gi.full[inside][:, :3], 2.0)          # (1 + 2 + 3) / 3
    x, y, w, h = rect
    grown = (gi.full[..., 3] > 0.5) & ~inside
    assert grown.any()
    np.testing.assert_allclose(gi.full[grown][:, :3], 3.0)           # seen by pass 2 only


def test_passes_restart_from_pass_zero_when_the_view_changes():
    gi = ProgressiveGI(lambda camera, tile, pass_index=0, layer=None: sphere_image(camera, tile))
    rect = screen_rect(CAM, CENTRE - RADIUS, CENTRE + RADIUS)
    gi.restart(CAM, rect, 0.25, budget_ms=5, passes=4)
    while gi.pass_index < 2:
        gi.step(1e9)
    assert gi.pass_index == 2 and "(pass 3 of 4)" in gi.status_words()
    gi.restart(CAM, rect, 0.25, budget_ms=5, passes=4)
    assert gi.pass_index == 0 and gi.progress == 0.0 and gi.refining


def _parted_render(boundary_moves: bool):
    """The analytic sphere with its gather in parts: 'diffuse' = the texel's colour, material 0
    left of the centre column and 1 right of it; with ``boundary_moves`` pass 1 moves the
    boundary one column (a jittered sample crossing it)."""
    from app.pbgi.gather_parts import empty

    def render(cam, tile, pass_index=0, layer=None):
        img = sphere_image(cam, tile)
        x0, y0, w, h = tile
        parts = empty((h, w))
        parts["diffuse"] = img[..., :3]
        edge = cam.width // 2 + (1 if boundary_moves and pass_index % 2 else 0)
        parts["material"] = (np.arange(x0, x0 + w) >= edge)[None, :].repeat(h, 0)
        return img, parts
    return render


@pytest.mark.parametrize("passes", [1, 3])
def test_recolour_relights_every_refined_texel_and_the_preview(passes):
    """After ``recolour({1}, f)`` the texels of material 1 show f of their parts' mean over the
    passes (here 2 x the colour), material 0's are untouched, and the refinement is where it
    was; a boundary the passes' samples crossed cannot be recoloured (nothing changes)."""
    gi = ProgressiveGI(_parted_render(False))
    gi.restart(CAM, screen_rect(CAM, CENTRE - RADIUS, CENTRE + RADIUS), 0.25, passes=passes)
    gi.finish()
    assert gi.recolourable and not gi.refining
    before, preview = gi.full.copy(), gi.preview.copy()
    assert gi.recolour({1}, lambda rec, i: 2.0 * rec["diffuse"])
    assert not gi.refining and gi.preview_dirty
    right = np.zeros(before.shape[:2], bool)
    right[:, CAM.width // 2:] = True
    hit = before[..., 3] > 0.5
    np.testing.assert_allclose(gi.full[..., :3][hit & right], 2 * before[..., :3][hit & right],
                               rtol=1e-6)
    np.testing.assert_array_equal(gi.full[hit & ~right], before[hit & ~right])
    assert (gi.preview[..., :3] != preview[..., :3]).any()
    assert gi.full[..., 3].tolist() == before[..., 3].tolist()

    crossed = ProgressiveGI(_parted_render(True))
    crossed.restart(CAM, screen_rect(CAM, CENTRE - RADIUS, CENTRE + RADIUS), 0.25, passes=2)
    crossed.finish()
    before = crossed.full.copy()
    assert not crossed.recolour({1}, lambda rec, i: 2.0 * rec["diffuse"])
    np.testing.assert_array_equal(crossed.full, before)
    plain = ProgressiveGI(lambda c, t, p=0, layer=None: sphere_image(c, t))
    assert plain.recolour({0}, None) is False


def test_a_recolour_between_passes_keeps_the_running_mean_right():
    """An edit that recombines while the passes still run: the texels refined so far are
    relit, their running sums too, so the passes after the edit (rendered with the new
    material) average with them. Pass k renders k + 1 times the colour; material 1 is edited to
    twice its light after the first pass: its texels end at 2 x (1 + 2 + 3) / 3 = 4 x the
    colour, material 0's at 2 x."""
    from app.pbgi.gather_parts import empty
    scale = {0: 1.0, 1: 1.0}

    def render(cam, tile, pass_index=0, layer=None):
        img = sphere_image(cam, tile)
        x0, y0, w, h = tile
        parts = empty((h, w))
        parts["diffuse"] = img[..., :3] * (pass_index + 1)
        right = (np.arange(x0, x0 + w) >= cam.width // 2)[None, :].repeat(h, 0)
        parts["material"] = right
        img[..., :3] = parts["diffuse"] * np.where(right, scale[1], scale[0])[..., None]
        return img, parts

    gi = ProgressiveGI(render)
    gi.restart(CAM, screen_rect(CAM, CENTRE - RADIUS, CENTRE + RADIUS), 0.25, passes=3)
    while gi.pass_index < 1:
        gi.step(1e9)
    base = sphere_image(CAM, (0, 0, CAM.width, CAM.height))
    assert gi.recolour({1}, lambda rec, i: 2.0 * rec["diffuse"])
    scale[1] = 2.0
    gi.finish()
    hit = base[..., 3] > 0.5
    right = np.zeros(hit.shape, bool)
    right[:, CAM.width // 2:] = True
    np.testing.assert_allclose(gi.full[..., :3][hit & right], 4.0 * base[..., :3][hit & right],
                               rtol=1e-5)
    np.testing.assert_allclose(gi.full[..., :3][hit & ~right], 2.0 * base[..., :3][hit & ~right],
                               rtol=1e-5)
