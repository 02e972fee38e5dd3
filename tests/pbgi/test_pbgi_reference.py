"""Classic PBGI against the independent CPU reference (app.pbgi.reference: Monte Carlo over the
hemisphere, the cloud as emitting discs, exact nearest-hit visibility), on the same receivers."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support import scenes as S
from app.cloud import PointCloud
from app.pbgi.reference import reference_render
from app.pbgi.renderer import Relighter, RenderParams


def _compare(relighter, cloud, cam, mat, m, n_samples, seed=0):
    gb = S.reference_gbuffer(relighter, cam, mat)
    ref, err = reference_render(gb, cloud.positions, cloud.normals, cloud.colors,
                                n_samples=n_samples, seed=seed, return_stderr=True)
    res = relighter.render(cam, [mat], RenderParams(mode="classic", microbuffer=m))
    assert res.stats.completed
    got = res.image.reshape(-1, 4)[gb["pixel"], :3].astype(np.float64)
    return got, ref, err


@pytest.fixture(scope="module")
def room():
    cloud = S.box_room(0.1)
    r = Relighter()
    r.set_cloud(cloud)
    return r, cloud


@pytest.mark.slow
def test_classic_matches_reference_on_a_small_room(room):
    """A diffuse sphere in a closed room with coloured walls and a bright ceiling light.

    Tolerance: the image mean within 5% and every pixel within 15% + 4 reference standard
    errors. Why: PBGI replaces the room by the cut's node colours (cluster means) and its
    micro-buffer quantises directions (24 x 24), which moves the bright light's edges by up to
    a micro-pixel - a few % of a pixel's radiance, measured 1-3% on the mean; the reference
    itself is Monte Carlo (1024 cosine samples: ~5% standard error per pixel here).
    """
    r, cloud = room
    r.set_asset(S.sphere((0.0, 0.8, 0.0), 0.3, subdivisions=3))
    cam = S.look((0.25, 1.0, 0.9), (0.0, 0.8, 0.0), 10, 38)
    got, ref, err = _compare(r, cloud, cam, S.diffuse(0.8, 0.5), 24, 1024)
    assert len(got) > 40
    mean_ratio = got.mean(0) / ref.mean(0)
    assert np.all(np.abs(mean_ratio - 1) < 0.05), mean_ratio
    assert np.all(np.abs(got - ref) <= 0.15 * ref + 4 * err + 1e-3)


def test_glossy_metal_matches_reference(room):
    """The same with a rough gold-like metal (importance-sampled reference): the gather's BRDF
    lobe over the micro-buffer integrates like the reference's. Same tolerances."""
    r, cloud = room
    r.set_asset(S.sphere((0.0, 0.8, 0.0), 0.3, subdivisions=3))
    cam = S.look((0.25, 1.0, 0.9), (0.0, 0.8, 0.0), 8, 38)
    mat = S.Material(base_color=(1.0, 0.8, 0.4), metallic=1.0, roughness=0.6)
    gb = S.reference_gbuffer(r, cam, mat)
    ref, err = reference_render(gb, cloud.positions, cloud.normals, cloud.colors,
                                n_samples=1024, sampling="mixture", return_stderr=True)
    res = r.render(cam, [mat], RenderParams(mode="classic", microbuffer=24))
    got = res.image.reshape(-1, 4)[gb["pixel"], :3].astype(np.float64)
    assert np.all(np.abs(got.mean(0) / ref.mean(0) - 1) < 0.08), got.mean(0) / ref.mean(0)
    assert np.all(np.abs(got - ref) <= 0.2 * ref + 4 * err + 1e-3)


@pytest.mark.slow
def test_light_straddling_the_horizon_does_not_leak():
    """A vertical receiver (normal +x) right below the middle of a bright light panel: its
    tangent plane cuts the panel in half, and the light's nodes straddle the horizon. Only the
    half above the horizon may count.

    The panel's visible half gives >= 60% of what the receiver gets (the walls are dim), and
    the hidden half is its mirror image, so a leak of the hidden half would push PBGI /
    reference above 1.6; we require [0.8, 1.25] for M = 16, 24, 32 (measured 1.22, 1.09, 1.10)
    and [0.8, 1.45] at M = 8, whose rim pixels have two bands of ~20 degrees: 1.36 with the nodes
    across the horizon capped at 2 pi / 64 (microbuffer.HORIZON_OMEGA), 1.56 without the cap.
    Each value is the mean of 4 passes: the micro-buffer's frame turns per receiver and pass
    (lib/microbuffer.glsl: mb_frame), and how the rim's bands lie against the panel's edge
    moves the ratio - single passes at M = 8 measured 1.32-1.45 (the unturned frame, one
    orientation, 1.27), at M = 16 1.18-1.25.
    The visible half lies within 16 degrees of the horizon, where a Nusselt grid pixel spans up
    to 28 degrees of elevation: with one ray per pixel this case measured 1.73 at M = 16 (the
    over-estimate the issue describes) and 0.22 at M = 8; the micro-buffer's rim pixels are
    therefore cut into elevation bands (app/pbgi/microbuffer.py). What remains above 1 is the
    paper's node footprint: nodes accepted at 4 Omega overhang the panel's edge by up to their
    radius (~2 micro-pixels), and nothing close behind the panel hides the overhang.
    """
    base = S.box_room(0.1, light=20.0, panel_spacing=0.025, panel_drop=0.15)
    dim = base.colors.copy()
    light = dim[:, 0] > 5
    dim[~light] *= 0.2
    cloud = PointCloud(base.positions, base.normals, dim, hdr=True)
    radii = S.local_spacing(cloud.positions)
    r = Relighter()
    r.set_cloud(cloud)
    r.set_asset(S.quad((0.0, 1.0, 0.0), (1.0, 0.0, 0.0), 0.1))
    cam = S.look((0.6, 1.0, 0.0), (0.0, 1.0, 0.0), 4, 8)
    mat = S.diffuse(0.8, 0.5)
    gb = S.reference_gbuffer(r, cam, mat)
    assert len(gb["position"]) == 16
    ref = reference_render(gb, cloud.positions, cloud.normals, cloud.colors, disc_radius=radii,
                           n_samples=2048)
    no_light = dim.copy()
    no_light[light] = 0.0
    ref_dark = reference_render(gb, cloud.positions, cloud.normals, no_light, disc_radius=radii,
                                n_samples=256)
    assert 1.0 - ref_dark.mean() / ref.mean() > 0.6           # the light dominates
    ratios = {}
    for m in (8, 16, 24, 32):
        res = r.render_passes(cam, [mat], RenderParams(mode="classic", microbuffer=m), passes=4)
        assert res.stats.completed
        got = res.image.reshape(-1, 4)[gb["pixel"], :3].astype(np.float64)
        ratios[m] = got.mean() / ref.mean()
    assert all(0.8 < v < (1.45 if m == 8 else 1.25) for m, v in ratios.items()), ratios
