"""An anisotropic lobe in the lobe micro-buffer (lib/lobe.glsl: the slope stretch of GGX along
the material's tangent): the white furnace gives each pixel the BRDF's directional albedo for
its own view in its own tangent frame (numpy, Monte Carlo), with no pixel far above it - the
isotropic warp of an anisotropic lobe made single pixels 2.8x the light. And the node rectangle
of the stretched mapping (lobe_rect_stretched) against brute force over every micro-pixel's rays
(tests/shaders/lobe_rect_check.glsl): conservative, and tight."""

from __future__ import annotations

import numpy as np
import pytest

from app.material import Material
from app.pbgi import brdf
from app.pbgi.renderer import RenderParams
from tests.support import scenes as S
from tests.support.compute import run_ssbo

CAM = S.look((0.0, 0.2, 1.6), (0.0, 0.0, 0.0), 24, 45)


def _expected(furnace, mat, n: int = 160):
    """(pixel indices, directional albedo) for up to n receivers spread over the sphere."""
    g = S.reference_gbuffer(furnace, CAM, mat)
    N, T, V = g["normal"], g["tangent"], g["view"]
    B = np.cross(N, T)
    pick = np.linspace(0, len(N) - 1, min(n, len(N))).astype(int)
    v_local = np.stack([np.einsum("ij,ij->i", V, T), np.einsum("ij,ij->i", V, B),
                        np.einsum("ij,ij->i", V, N)], axis=1)[pick]
    ok = v_local[:, 2] > 0.05
    pick, v_local = pick[ok], v_local[ok]
    a = brdf.directional_albedo(g["params"][pick], v_local, n_samples=1 << 13)
    return g["pixel"][pick], a.mean(-1)


@pytest.mark.parametrize("mode", ["classic", "hybrid"])
@pytest.mark.parametrize("aniso, rough", [(1.0, 0.3), (0.6, 0.15), (1.0, 0.08)])
def test_white_furnace_anisotropic(furnace, mode, aniso, rough):
    mat = Material(base_color=(0.9, 0.9, 0.9), metallic=1.0, roughness=rough,
                   anisotropic=aniso)
    res = furnace.render(CAM, [mat], RenderParams(mode=mode, microbuffer=24))
    assert res.stats.completed and res.stats.lobe_receivers
    pix, expect = _expected(furnace, mat)
    got = res.image.reshape(-1, 4)[pix, :3].mean(-1)
    q = got / expect - 1
    assert abs(got.sum() / expect.sum() - 1) < 0.03, (got.sum() / expect.sum())
    assert np.abs(q).max() < 0.15, np.abs(q).max()
    every = res.image[..., :3][res.image[..., 3] > 0]
    assert every.max() <= 1.0, every.max()          # albedo <= 1 under radiance 1


# ------------------------------------------- the node rectangle (lobe_rect) against brute force

def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _rect_cases(n: int, seed: int, aniso: bool, b_range=(0.003, 0.6)):
    """Random receivers and nodes for tests/shaders/lobe_rect_check.glsl: views from grazing
    (N.V 0.03) to normal, roughness 0.01-0.5 at anisotropic 0.3-1 (or 0), 8-16 rings and
    sectors; a third of the nodes near the mirror direction (within a few alpha: some hold the
    lobe's axis), a third anywhere, a third near the receiver's horizon."""
    rng = np.random.default_rng(seed)
    N = _unit(rng.normal(size=(n, 3)))
    T = _unit(np.cross(N, rng.normal(size=(n, 3))))
    B = np.cross(N, T)
    cv, pv = rng.uniform(0.03, 1.0, n), rng.uniform(0, 2 * np.pi, n)
    sv = np.sqrt(1 - cv * cv)
    V = T * (sv * np.cos(pv))[:, None] + B * (sv * np.sin(pv))[:, None] + N * cv[:, None]
    r = rng.uniform(0.01, 0.5, n)
    aspect = np.sqrt(1 - 0.9 * (rng.uniform(0.3, 1.0, n) if aniso else np.zeros(n)))
    ax, ay = np.maximum(1e-3, r * r / aspect), np.maximum(1e-3, r * r * aspect)
    side = rng.choice([8, 12, 16], n)
    R = 2 * (V * N).sum(1, keepdims=True) * N - V
    kind = rng.integers(0, 3, n)[:, None]
    near = _unit(R + rng.normal(size=(n, 3)) * 3 * np.maximum(ax, ay)[:, None])
    horizon = _unit(_unit(np.cross(N, rng.normal(size=(n, 3))))
                    + N * rng.uniform(-0.2, 0.2, (n, 1)))
    l = np.where(kind == 0, near, np.where(kind == 1, _unit(rng.normal(size=(n, 3))), horizon))
    b = np.exp(rng.uniform(np.log(b_range[0]), np.log(b_range[1]), n))
    C = np.zeros((n, 4, 4), np.float32)
    for k, (vec, w) in enumerate([(N, side), (V, side), (T, ax), (B, ay)]):
        C[:, k, :3], C[:, k, 3] = vec, w
    nodes = np.zeros((n, 4), np.float32)
    nodes[:, :3], nodes[:, 3] = l, np.sin(b)
    return C, nodes


@pytest.fixture(scope="module")
def rect_check(ctx):
    from app.render.programs import load_compute
    from tests.support import TEST_SHADERS
    prog = load_compute(ctx, TEST_SHADERS / "lobe_rect_check.glsl")

    def run(C, nodes, samples: int = 5, shrink: float = 0.2, cone: bool = False):
        n = len(nodes)
        raw = run_ssbo(ctx, prog, [C, nodes], n * 32, (n + 15) // 16, u_count=n,
                       u_samples=samples, u_shrink=shrink)
        out = np.frombuffer(raw, np.uint32).reshape(n, 2, 4).copy()
        assert np.all(out[:, 1, 3] == 1), "some invocations did not complete"
        rect, hits, miss, miss_shrunk = out[:, 0].T
        if cone:                        # the micro-pixels hit, and lobe_cone_outside's cull
            return hits, out[:, 1, 2] == 1
        return rect, hits, miss, miss_shrunk, out[:, 1, 0]

    return run


def _rect_fields_valid(C, rect):
    """Every rectangle but "outside" has ring0 <= ring1 < rings and 1..sectors sectors."""
    side = C[:, 0, 3].astype(np.uint32)
    r = rect[rect != 0xFFFFFFFF]
    side = side[rect != 0xFFFFFFFF]
    r0, r1, s0, ns = r & 255, (r >> 8) & 255, (r >> 16) & 255, r >> 24
    return bool(np.all((r0 <= r1) & (r1 < side) & (s0 < side) & (ns >= 1) & (ns <= side)))


@pytest.mark.parametrize("aniso", [True, False], ids=["anisotropic", "isotropic"])
def test_lobe_rect_holds_every_micro_pixel_the_node_can_hit(rect_check, aniso):
    """Conservative: every micro-pixel with a ray (25 jittered positions per cell) in the node's
    cone is inside lobe_rect's rectangle, for 3000 random receivers and nodes; and the check has
    teeth: the same rectangles with 20% of their rings and sectors taken off miss some in a
    third of the nodes that hit anything (and so does the stretched bound with its slope radius
    or azimuth range cut by 20%, or the 12-gon inscribed instead of circumscribed: checked by
    hand when it was written)."""
    C, nodes = _rect_cases(3000, 7, aniso)
    rect, hits, miss, miss_shrunk, cells = rect_check(C, nodes)
    hit = hits > 0
    assert hit.sum() > 600 and hits.sum() > 20000, (hit.sum(), hits.sum())
    assert miss.sum() == 0, np.nonzero(miss)[0][:10]
    assert _rect_fields_valid(C, rect)
    assert (miss_shrunk[hit] > 0).mean() > 0.3, (miss_shrunk[hit] > 0).mean()


@pytest.mark.parametrize("aniso", [True, False], ids=["anisotropic", "isotropic"])
def test_the_lobe_cone_culls_no_node_a_ray_can_hit(rect_check, aniso):
    """lib/lobe.glsl's lobe_cone_outside, the lobe walk's first cull (every direction of the
    domain lies within 2 theta_max of the mirror direction): no node it culls has a micro-pixel
    whose ray lies in its cone, over nodes of every size the walk meets (tiny to over the
    horizon), and it has teeth: it culls a good share of the nodes that hit nothing (near
    mirrors: most of the room), which lobe_rect would reach only through its trigonometry. The
    walk's images are the same bit for bit with and without it (measured on the demo close-up,
    Classic and Hybrid, six materials; the near-mirror's lobe walk 290 -> 202 ms)."""
    for seed, b_range in [(7, (0.003, 0.6)), (3, (1e-5, 1e-3)), (5, (0.5, 1.5))]:
        hits, culled = rect_check(*_rect_cases(6000, seed, aniso, b_range), samples=6, cone=True)
        assert not np.any(culled & (hits > 0)), np.nonzero(culled & (hits > 0))[0][:10]
        assert (hits > 0).sum() > 50            # tiny nodes: few hit anything
        assert culled.sum() > 0.2 * (hits == 0).sum(), (culled.sum(), (hits == 0).sum())


def test_lobe_rect_anisotropic_tiny_and_huge_nodes(rect_check):
    """The same at the extremes of node size: 1e-5 - 1e-3 rad (where cos b is 1 in float32: the
    check tests |L x l| <= sin b) and 0.5 - 1.5 rad (near nodes, most of them over the horizon:
    the widened disc stands in)."""
    for seed, b_range, least in [(3, (1e-5, 1e-3), 100), (5, (0.5, 1.5), 100000)]:
        C, nodes = _rect_cases(12000, seed, True, b_range)
        ax, ay = C[:, 2, 3], C[:, 3, 3]
        keep = np.abs(ax - ay) > 1e-3 * np.sqrt(ax * ay)    # stretched (alpha 1e-3 both: not)
        C, nodes = np.ascontiguousarray(C[keep]), np.ascontiguousarray(nodes[keep])
        rect, hits, miss, _, _ = rect_check(C, nodes, samples=6)
        assert hits.sum() > least, hits.sum()
        assert miss.sum() == 0, (b_range, np.nonzero(miss)[0][:10])
        assert _rect_fields_valid(C, rect)


def test_lobe_rect_anisotropic_is_tight(rect_check):
    """The stretched rectangle (the K-gon around the node's cone through the slope stretch)
    holds at most 1.4 micro-pixels per micro-pixel the node hits, on nodes of 0.003-0.05 rad
    (the sizes the cut accepts): 1.19 here; the disc widened by the stretch's largest
    magnification, before it, held 1.68."""
    rect, hits, miss, miss_shrunk, cells = rect_check(*_rect_cases(4000, 11, True, (0.003, 0.05)))
    hit = hits > 0
    assert miss.sum() == 0
    ratio = cells[hit].sum() / hits.sum()
    assert ratio < 1.4, ratio


def test_lobe_rect_anisotropic_axis_and_outside(rect_check):
    """A node on the lobe's axis (the mirror direction) gets every sector from ring 0; one
    behind the receiver's view, away from the lobe, is outside the domain (0xFFFFFFFF)."""
    N, T, V = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), _unit(np.array([0.3, 0.4, 1.0]))
    R = 2 * V[2] * N - V
    C = np.zeros((2, 4, 4), np.float32)
    for k, (vec, w) in enumerate([(N, 12), (V, 12), (T, 0.2), (np.cross(N, T), 0.02)]):
        C[:, k, :3], C[:, k, 3] = vec, w
    nodes = np.array([[*R, 0.01], [*_unit(np.array([-0.3, -0.4, 0.1])), 0.01]], np.float32)
    rect, hits, miss, _, cells = rect_check(C, nodes)
    assert rect[0] & 255 == 0 and rect[0] >> 24 == 12 and hits[0] > 0 and miss[0] == 0
    assert rect[1] == 0xFFFFFFFF and hits[1] == 0


def test_each_pixel_and_pass_turns_its_lobe_frame(ctx):
    """The lobe micro-buffer's azimuth (lib/lobe.glsl: lobe_frame's phi0) is uniform over the
    pixels (Kolmogorov-Smirnov against U(0, 2 pi), p > 0.01), independent between
    neighbouring pixels (correlation of consecutive pixels' angles below 0.1) and drawn anew
    in every pass (no pixel keeps its angle from pass 0 to pass 1): the quantisation of a
    narrow lobe is noise that the passes average, not a grid (seed 001, Section 2.3)."""
    from scipy.stats import kstest
    from app.render.programs import load_compute
    from tests.support import TEST_SHADERS
    pixels, passes = 4096, 2
    n = pixels * passes
    prog = load_compute(ctx, TEST_SHADERS / "lobe_frame_check.glsl")
    phi = np.frombuffer(run_ssbo(ctx, prog, [], n * 4, (n + 63) // 64, u_pixels=pixels,
                                 u_count=n), np.float32).reshape(passes, pixels)
    assert np.all((phi >= 0) & (phi < 2 * np.pi))
    assert kstest(phi[0] / (2 * np.pi), "uniform").pvalue > 0.01
    assert abs(np.corrcoef(phi[0, :-1], phi[0, 1:])[0, 1]) < 0.1
    assert not np.any(np.isclose(phi[0], phi[1], atol=1e-6))


def test_the_lobe_cells_solid_angles_add_up_to_the_domain(ctx):
    """Each micro-pixel of a lobe buffer weighs its ray by its solid angle in half-vector space
    (lib/lobe.glsl: lobe_omega_h, the warp's Jacobian). Summed over the cells (rings x 64
    sectors, each cell's mean over the points its jittered ray can take) they are the domain's
    cap, 2 pi (1 - cos theta_max), within 0.5%: one
    lobe, a wide one, and a two-piece buffer (a narrow lobe over a wide one)."""
    from app.render.programs import load_compute
    from tests.support import TEST_SHADERS
    cases = np.array([[0.2, 0.2, 64, 0], [0.6, 0.6, 64, 0], [0.02, 0.5, 64, 0],
                      [0.05, 0.05, 48, 0]], np.float32)
    prog = load_compute(ctx, TEST_SHADERS / "lobe_solid_angle_check.glsl")
    out = np.frombuffer(run_ssbo(ctx, prog, [cases], len(cases) * 16, 1, u_count=len(cases)),
                        np.float32).reshape(-1, 4)
    assert np.all(out[:, 3] == 1)
    cap = 2 * np.pi * (1 - 1 / np.sqrt(1 + out[:, 1].astype(np.float64)))
    np.testing.assert_allclose(out[:, 0], cap, rtol=5e-3)
    assert out[2, 2] < cases[2, 2] and out[0, 2] == cases[0, 2]     # split / one piece
    assert cap.min() > 0.05 and cap.max() > 2.0                      # narrow to wide domains
