"""The micro-buffer (table, storage, batching) and the Classic cut finder's slicing across
dispatches (llvmpipe's silent loop limit)."""

from __future__ import annotations

import numpy as np

from app.pbgi import layout
import pytest

from tests.support import scenes as S
from tests.support.frames import turned_frame
from app.pbgi.classic import LOOP_LIMIT, ClassicCut
from app.pbgi.microbuffer import (EMPTY, batch_size, entries, micro_pixel_table, omega_micro,
                                  rect_entries)
from app.pbgi.renderer import RenderParams


@pytest.mark.parametrize("m", [8, 16, 24, 32])
def test_table_weights_sum_to_the_hemisphere(m):
    t = micro_pixel_table(m)
    assert t["weight"].sum() == pytest.approx(np.pi, rel=1e-6)       # cosine-weighted: pi
    assert t["solid_angle"].sum() == pytest.approx(2 * np.pi, rel=1e-6)
    filled = t["weight"] > 0
    assert np.allclose(np.linalg.norm(t["dir"], axis=1), 1.0, atol=1e-9)
    assert (t["dir"][filled, 2] > 0).all()                           # strictly above the horizon
    assert (t["solid_angle"][filled] >= t["weight"][filled]).all()   # cos <= 1
    assert np.array_equal(t["pixel"][:m * m], np.arange(m * m))       # band 0 = grid pixel
    assert t["entries"] == entries(m) < 1.6 * m * m


def test_rim_pixels_are_split_into_thin_elevation_bands():
    """No entry spans much more elevation than HORIZON_SPLIT / M (one ray per entry)."""
    m = 16
    t = micro_pixel_table(m)
    assert t["extra_count"].max() >= 2 and t["extra_count"][(m // 2) * m + m // 2] == 0
    rng = np.random.default_rng(1)
    xy = rng.random((400_000, 2)) * 2 - 1
    r = np.hypot(xy[:, 0], xy[:, 1])
    xy, r = xy[r < 1], r[r < 1]
    pix = np.minimum(((xy + 1) / 2 * m).astype(int), m - 1)
    k = pix[:, 1] * m + pix[:, 0]
    # the entry of each sample: bands of equal elevation between the pixel's extremes
    elev = np.arccos(r)
    lo = np.full(m * m, np.inf)
    hi = np.zeros(m * m)
    np.minimum.at(lo, k, elev)
    np.maximum.at(hi, k, elev)
    nb = 1 + t["extra_count"]
    assert ((hi - lo)[nb == 1] <= 4.0 / m * 1.1).mean() > 0.97
    assert ((hi - lo) / nb)[np.isfinite(lo)].max() <= 4.0 / m * 1.1


def test_rect_entries_counts_every_band():
    t = micro_pixel_table(24)
    for x0, y0, x1, y1 in ((0, 0, 23, 23), (0, 3, 5, 7), (10, 10, 12, 12), (20, 0, 23, 2)):
        px, py = t["pixel"] % 24, t["pixel"] // 24
        inside = (px >= x0) & (px <= x1) & (py >= y0) & (py <= y1)
        assert rect_entries(t, x0, y0, x1, y1) == inside.sum()


def test_table_matches_monte_carlo():
    """Independent check of each grid pixel's clipped area, solid angle and centroid (the sums
    over its bands)."""
    m = 8
    rng = np.random.default_rng(0)
    xy = rng.random((2_000_000, 2)) * 2 - 1
    r2 = (xy ** 2).sum(1)
    inside = r2 < 1
    px = np.minimum(((xy + 1) / 2 * m).astype(int), m - 1)
    k = px[:, 1] * m + px[:, 0]
    area = np.bincount(k[inside], minlength=m * m) * 4.0 / len(xy)
    omega = np.bincount(k[inside], 1 / np.sqrt(1 - r2[inside]), minlength=m * m) * 4.0 / len(xy)
    cx = np.bincount(k[inside], xy[inside, 0], minlength=m * m) * 4.0 / len(xy)
    t = micro_pixel_table(m)
    w = np.bincount(t["pixel"], t["weight"], minlength=m * m)
    om = np.bincount(t["pixel"], t["solid_angle"], minlength=m * m)
    # the area-weighted mean of the bands' centroids is the pixel's centroid
    cxt = np.bincount(t["pixel"], t["weight"] * _centroid_x(t), minlength=m * m)
    assert np.allclose(w, area, atol=2e-3)
    assert np.allclose(om, omega, atol=2e-2 * omega.max())
    big = area > 0.02
    assert np.allclose((cxt / np.maximum(w, 1e-12))[big], (cx / np.maximum(area, 1e-12))[big],
                       atol=3e-3)


def test_flux_weights_any_normal_like_monte_carlo():
    """The entries' direction flux (integral of w d omega over each region), which weights a
    micro-buffer kept in another normal's frame (Hybrid's far-field sharing): its z part is the
    cosine weight, per grid pixel it matches a Monte Carlo estimate over the disc (d omega =
    dA / z), and for a normal n tilted by 0.1 rad, sum max(n . flux, 0) is the clamped cosine
    integrated over the frame's hemisphere (Monte Carlo, 0.2%)."""
    m = 8
    t = micro_pixel_table(m)
    f = t["flux"]
    assert np.allclose(f[:, 2], t["weight"])
    rng = np.random.default_rng(1)
    xy = rng.random((2_000_000, 2)) * 2 - 1
    r2 = (xy ** 2).sum(1)
    inside = r2 < 0.9999
    xy, z = xy[inside], np.sqrt(1 - r2[inside])
    px = np.minimum(((xy + 1) / 2 * m).astype(int), m - 1)
    k = px[:, 1] * m + px[:, 0]
    scale = 4.0 / len(r2)
    for j in (0, 1):
        mc = np.bincount(k, xy[:, j] / z, minlength=m * m) * scale
        got = np.bincount(t["pixel"], f[:, j], minlength=m * m)
        assert np.allclose(got, mc, atol=5e-3)        # MC noise: 1 / z grows at the rim
    n = np.array([np.sin(0.1), 0.0, np.cos(0.1)])
    w = np.concatenate([xy, z[:, None]], axis=1)
    mc = (np.maximum(w @ n, 0.0) / z).sum() * scale
    assert np.maximum(f @ n, 0.0).sum() == pytest.approx(mc, rel=2e-3)


def _centroid_x(t):
    """x of each entry's centroid in the projection plane: the direction's x (Phi keeps x)."""
    return t["dir"][:, 0]


def test_batch_size_follows_the_budget():
    per = entries(24) * 8
    assert batch_size(24, 100 * per, 16384, 10_000, minimum=1) == 100
    assert batch_size(24, 1e12, 16384, 10_000) == 10_000          # all receivers in one batch
    assert batch_size(24, 1e12, 4096, 10_000) == 4096             # one image row each
    assert batch_size(24, 1.0, 16384, 10_000, minimum=64) == 64   # a tiny budget still progresses


def test_llvmpipe_loop_limit_is_what_we_budget_for(ctx):
    """Documents the trap the Classic walk is sliced for: all loops of one invocation together
    stop silently after LOOP_LIMIT iterations (on other drivers the count simply completes)."""
    cs = ctx.compute_shader("""#version 430
        layout(local_size_x = 8) in;
        layout(std430, binding = 0) buffer O { uint o[]; };
        uniform uint n;
        void main() { uint a = 0u, b = 0u;
            for (uint k = 0u; k < n; ++k) a++;
            for (uint k = 0u; k < n; ++k) b++;
            o[2u * gl_GlobalInvocationID.x] = a; o[2u * gl_GlobalInvocationID.x + 1u] = b; }""")
    buf = ctx.buffer(reserve=8 * 8)
    buf.bind_to_storage_buffer(0)
    cs["n"] = 40000
    cs.run(1)
    a, b = np.frombuffer(buf.read(), np.uint32)[:2]
    assert a == 40000
    if "llvmpipe" in ctx.info["GL_RENDERER"]:
        assert LOOP_LIMIT - 2 <= int(a) + int(b) <= LOOP_LIMIT   # b stopped silently
    assert ClassicCut(ctx).steps + ClassicCut(ctx).splat_budget < LOOP_LIMIT


@pytest.fixture(scope="module")
def room():
    return S.sphere_in_box_room(0.1)


CAM = S.look((0.3, 1.0, 0.9), (0.0, 0.8, 0.0), 12, 40)


def test_sliced_walk_fills_the_same_microbuffers(room):
    """A walk cut into many tiny dispatches (37 nodes, 3 accepted nodes per dispatch) resumes
    exactly where it stopped: every micro-pixel ends up identical to a few large dispatches."""
    m = 16
    mat = S.diffuse()
    res = room.render(CAM, [mat], RenderParams(mode="classic", microbuffer=m))
    full = room.microbuffers.read(res.stats.receivers).copy()
    assert res.stats.completed and res.stats.rounds <= 3
    mode = room.mode_for(RenderParams(mode="classic", microbuffer=m))
    default, mode.cut = mode.cut, ClassicCut(room.ctx, steps=37, splat_budget=entries(m),
                                             list_cap=3)
    try:
        room.forget_microbuffers()
        res2 = room.render(CAM, [mat], RenderParams(mode="classic", microbuffer=m))
        sliced = room.microbuffers.read(res2.stats.receivers)
    finally:
        mode.cut.release()
        mode.cut = default
        room.forget_microbuffers()
    assert res2.stats.rounds > 20 and res2.stats.completed
    assert np.array_equal(full, sliced)
    assert np.array_equal(res.image, res2.image)


def test_microbuffer_entries_are_visible_nodes(room):
    """Each filled micro-pixel holds a node whose bounding sphere its direction ray really hits
    (numpy ray-sphere test), in front of the receiver, not entirely below its horizon; a closed
    room leaves (almost) no micro-pixel empty. The nodes are the joined tree's: the room's and
    the asset's surfels (app/pbgi/scene_tree.py). The directions are in each receiver's own
    turned frame (tests/support/frames.py, a numpy twin of lib/microbuffer.glsl's mb_frame):
    with the unturned frame every one of the 30 checked receivers fails the ray-sphere test."""
    m = 16
    params = RenderParams(mode="classic", microbuffer=m)
    room.convex_shortcut = False   # the sphere is convex: walk its surfels anyway (joined tree)
    try:
        res = room.render(CAM, [S.diffuse()], params)
    finally:
        room.convex_shortcut = True
    n = res.stats.receivers
    mb = room.microbuffers.read(n)
    rec = room.last_receivers                      # in micro-buffer row order
    nodes = layout.decode(room.scene_nodes([S.diffuse()], params).records)
    table = micro_pixel_table(m)
    filled_weight = 0.0
    for i in range(0, n, max(1, n // 25)):
        p, nrm = rec[i, 0:3].astype(float), rec[i, 4:7].astype(float)
        pixel = int(rec[i, 3:4].astype(np.float32).view(np.uint32)[0])
        t, b = turned_frame(nrm, pixel, seed_tile=(0, 0, CAM.width, CAM.width))
        w = table["dir"] @ np.stack([t, b, nrm])
        node = mb[i, :, 1]
        ok = (node != EMPTY) & (table["weight"] > 0)
        filled_weight += table["weight"][ok].sum() / np.pi
        c = nodes["center"][node[ok]].astype(float) - p
        r = nodes["radius"][node[ok]].astype(float)
        tc = np.einsum("ij,ij->i", w[ok], c)
        miss2 = np.einsum("ij,ij->i", c, c) - tc ** 2
        assert (miss2 <= r ** 2 * (1 + 1e-3) + 1e-9).all()     # the ray hits the sphere
        assert (tc + r > 0).all()                              # in front
        assert (c @ nrm > -r * (1 + 1e-4)).all()               # not entirely below the horizon
        omega = 2 * np.pi * (1 - np.sqrt(np.maximum(1 - r ** 2 / np.einsum("ij,ij->i", c, c), 0)))
        assert ((omega <= 4 * omega_micro(m) * 1.001) | nodes["is_leaf"][node[ok]]).all()
    assert filled_weight / len(range(0, n, max(1, n // 25))) > 0.99


def test_the_back_face_cull_is_conservative_and_tight(ctx):
    """cut_back_facing (tests/shaders/back_facing_check.glsl) against the geometry it stands
    for: a node seen in direction l within angle b, its normals within alpha of the cone's
    axis, shows only back faces exactly when every (direction, normal) pair has a positive dot,
    i.e. when angle(l, axis) + alpha + b < 90 degrees (the smallest dot is the cosine of that
    sum). A cull outside it drops light the receiver sees (conservative); one missing well
    inside it walks a node for nothing (tight: within 1e-3 rad)."""
    from app.render.programs import load_compute
    from tests.support import TEST_SHADERS
    from tests.support.compute import run_ssbo
    rng = np.random.default_rng(5)
    n = 20000
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    alpha = rng.uniform(0.0, 1.2, n)
    b = rng.uniform(0.0, 1.2, n)
    theta = rng.uniform(0.0, np.pi, n)          # angle(l, axis), dense near the boundary too
    side = np.cross(axis, rng.normal(size=(n, 3)))
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    l = np.cos(theta)[:, None] * axis + np.sin(theta)[:, None] * side
    cases = np.zeros((n, 2, 4), np.float32)
    cases[:, 0, :3], cases[:, 0, 3] = axis, np.cos(alpha)
    cases[:, 1, :3], cases[:, 1, 3] = l, np.sin(b)
    prog = load_compute(ctx, TEST_SHADERS / "back_facing_check.glsl")
    out = np.frombuffer(run_ssbo(ctx, prog, [cases], n * 4, (n + 15) // 16, u_count=n),
                        np.uint32)
    assert np.all(out >= 2), "some invocations did not complete"
    culled = (out & 1) == 1
    reach = theta + alpha + b                    # the widest angle between a direction and a normal
    assert not np.any(culled & (reach > np.pi / 2 + 1e-3)), "a node with front faces was culled"
    assert not np.any(~culled & (reach < np.pi / 2 - 1e-3)), "a back-facing node was kept"
    assert 0.1 < culled.mean() < 0.9


def test_the_horizon_cap_binds_only_where_the_rim_bands_are_coarse():
    """A node straddling the horizon is accepted up to the stop rule's 4 Omega, capped at
    2 pi / 64 (microbuffer.HORIZON_OMEGA): Omega itself at M = 8, the stop rule untouched from
    M = 16 up (test_pbgi_reference.py measures both ends)."""
    from app.pbgi.microbuffer import HORIZON_OMEGA, omega_horizon
    assert HORIZON_OMEGA == pytest.approx(2 * np.pi / 64)
    assert omega_horizon(8, 4.0) == pytest.approx(omega_micro(8))
    for m in (16, 24, 32):
        assert omega_horizon(m, 4.0) == pytest.approx(4.0 * omega_micro(m))
    assert omega_horizon(16, 8.0) == pytest.approx(HORIZON_OMEGA)
    assert omega_horizon(8, 0.5) == pytest.approx(0.5 * omega_micro(8))
