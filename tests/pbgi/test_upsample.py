"""`render --render-scale`: the GI at a fraction of the resolution, brought back by joint
bilateral upsampling with the viewer's weights (app/pbgi/upsample.py,
shaders/gi_upsample.glsl). The pass against its numpy twin (tests/support/upsample.py), scale 1
against render_passes, a smooth diffuse render at 1/2 against the full-resolution one."""

from __future__ import annotations

import numpy as np
import pytest

from app.errors import ScanlightError
from app.pbgi import upsample as U
from app.pbgi.renderer import Relighter, RenderParams
from app.render.programs import GENERATED_INCLUDES, _read_include
from tests.support import scenes as S
from tests.support import upsample as twin


def _synthetic(rng, lo=(9, 7), size=(30, 23)):
    """A low-resolution GI image with holes and a guide with a depth step, a normal crease, a
    hole and a one-pixel sliver whose low-resolution taps are all background."""
    (w, h), (W, H) = lo, size
    gi = np.zeros((h, w, 4), np.float32)
    gi[..., :3] = rng.uniform(0.0, 4.0, (h, w, 3))
    gi[..., 3] = rng.uniform(size=(h, w)) > 0.25
    gi[..., :3] *= gi[..., 3:]
    guide = np.zeros((H, W, 4), np.float32)
    yy, xx = np.mgrid[0:H, 0:W]
    n = np.stack([np.where(xx < W // 2, 0.0, 0.6), np.zeros_like(xx, float),
                  np.where(xx < W // 2, 1.0, 0.8)], -1)
    guide[..., :3] = n / np.linalg.norm(n, axis=-1, keepdims=True)
    guide[..., 3] = np.where(yy < H // 3, 2.0, 2.6) + 0.01 * xx
    guide[(yy - 12) ** 2 + (xx - 8) ** 2 < 9, 3] = 0.0           # a hole in the asset
    gi[:, 0, 3] = 0.0                                            # no GI on the left column
    guide[:, :2, 3] = 0.0
    guide[:, 0, 3] = 1.5                                         # a sliver the taps miss
    return gi, guide


def test_the_pass_is_its_numpy_twin(ctx):
    rng = np.random.default_rng(3)
    gi, guide = _synthetic(rng)
    rgb, unfilled = U.Upsampler(ctx).run(gi, guide)
    want, want_unfilled = twin.upsample(gi[::-1], guide[::-1])    # the twin: GL orientation
    want = want[::-1]
    on = guide[..., 3] > 0
    assert on.sum() > 300 and (~on).sum() > 30
    assert np.allclose(rgb[on], want[on][:, :3], rtol=1e-4, atol=1e-5)
    assert np.all(rgb[~on] == 0.0)
    assert unfilled == want_unfilled


def test_light_does_not_bleed_across_a_crease(ctx):
    """Two faces at 90 degrees and the same depth (only the normal tells them apart), one lit
    (1) and one dark (0) at half resolution: upsampled, no pixel of either takes more than 1%
    of the other's light - the point of the normal weight (Ritschel et al. 2009, Sec. 2.4). At
    the weight exp(-8 (1 - cos)) a tap across the crease counts e^-8; a softer weight (e^-2 at
    a sharpness of 2) bled about a tenth of the lit face into the dark one."""
    w, h = 16, 12
    gi = np.zeros((h, w, 4), np.float32)
    gi[:, : w // 2, :3] = 1.0
    gi[..., 3] = 1.0
    guide = np.zeros((2 * h, 2 * w, 4), np.float32)
    guide[:, :w, 2] = 1.0                       # left face: normal +z
    guide[:, w:, 0] = 1.0                       # right face: normal +x
    guide[..., 3] = 2.0
    rgb, unfilled = U.Upsampler(ctx).run(gi, guide)
    assert unfilled == 0
    assert rgb[:, :w].min() > 0.99 and rgb[:, w:].max() < 0.01


def test_the_viewer_and_render_share_the_weights():
    """Both shaders include lib/joint_bilateral.glsl, whose numbers are generated from
    app/pbgi/upsample.py; the viewer's numpy twin reads the same module."""
    from app.ui import composite
    text = _read_include("gen/joint_bilateral.glsl")
    for name in ("NORMAL_SHARPNESS", "DEPTH_TOLERANCE", "OFF_GUIDE_WEIGHT"):
        assert f"#define {name} {getattr(U, name)!r}" in text
        assert getattr(composite, name) == getattr(U, name)
    assert "gen/gi_upsample.glsl" in GENERATED_INCLUDES
    from app.render.programs import shaders_dir
    for shader in ("viewer_composite.glsl", "gi_upsample.glsl"):
        assert '#include "lib/joint_bilateral.glsl"' in (shaders_dir() / shader).read_text()


@pytest.fixture(scope="module")
def room(ctx):
    cloud = S.box_room(spacing=0.08)
    rl = Relighter(ctx)
    rl.set_cloud(cloud)
    rl.set_asset(S.sphere((0.0, 0.0, 0.0), 0.5, subdivisions=4))
    cam = S.look((0.0, 0.3, 1.7), (0.0, 0.0, 0.0), size=48, fov=45.0)
    return rl, cam


def test_scale_one_is_render_passes(room):
    rl, cam = room
    p = RenderParams(mode="hybrid", microbuffer=8)
    a = U.render_upsampled(rl, cam, [S.diffuse(0.6)], p, passes=2, scale=1.0)
    b = rl.render_passes(cam, [S.diffuse(0.6)], p, passes=2)
    assert np.array_equal(a.image, b.image)
    assert a.stats.render_scale == 1.0 and a.stats.ms_upsample == 0.0


def test_half_scale_diffuse_is_close_to_full_resolution(room):
    """Diffuse GI is smooth over the sphere: 1/2 scale upsampled has the full-resolution
    render's exact coverage, its mean over the asset within 2%, and a mean absolute difference
    within 5% (measured 4.3%: mostly the micro-buffers' per-pass noise at M = 16, since two full
    renders of 2 and 4 passes differ by 1.6%); a nearest-neighbour resize
    of the same low-resolution image, which knows nothing of the silhouette, is much worse at
    the edge."""
    rl, cam = room
    p = RenderParams(mode="classic", microbuffer=16)
    mat = [S.diffuse(0.6)]
    full = rl.render_passes(cam, mat, p, passes=2).image.astype(np.float64)
    half = U.render_upsampled(rl, cam, mat, p, passes=2, scale=0.5)
    img = half.image.astype(np.float64)
    assert np.isfinite(img).all()
    assert np.array_equal(img[..., 3], full[..., 3])
    on = full[..., 3] > 0.999
    err = np.abs(img[..., :3] - full[..., :3])[on].mean() / full[..., :3][on].mean()
    bias = abs(img[..., :3][on].mean() / full[..., :3][on].mean() - 1.0)
    assert err < 0.05 and bias < 0.02, (err, bias)
    s = half.stats
    assert (s.render_scale, s.out_width, s.out_height, s.width, s.height) == (0.5, 48, 48, 24, 24)
    assert s.upsample_unfilled == 0 and s.completed and s.ms_upsample > 0
    lo = rl.render_passes(U.scaled_camera(cam, 0.5), mat, p, passes=2).image
    nearest = np.repeat(np.repeat(lo, 2, 0), 2, 1).astype(np.float64)
    edge = on & (nearest[..., 3] < 0.999)
    assert edge.sum() > 10
    rel = lambda im: np.abs(im[..., :3] - full[..., :3])[edge].mean()  # noqa: E731
    assert rel(img) < 0.5 * rel(nearest)


@pytest.mark.parametrize("scale", [0.0, -0.5, 1.5, float("nan")])
def test_a_scale_outside_0_1_is_refused(room, scale):
    rl, cam = room
    with pytest.raises(ScanlightError, match="render scale"):
        U.render_upsampled(rl, cam, [S.diffuse()], RenderParams(mode="envmap"), 1, scale)


def test_the_gi_scale_follows_the_materials():
    """pbgi.rough_render_scale applies while every material's specular lobe is at least
    pbgi.rough_scale_from rough along its narrow axis (no roughness texture; a clearcoat does
    not count); any narrower lobe in the scene keeps render_scale for the whole image; the
    lower of the two wins."""
    from dataclasses import replace
    from app.material import Material
    from app.settings import Settings
    rough, glossy = S.diffuse(0.6, roughness=0.5), S.diffuse(0.6, roughness=0.3)
    coat = replace(rough, clearcoat=1.0, clearcoat_gloss=1.0)
    textured = replace(rough, metallic_roughness_texture=np.ones((2, 2, 3), np.float32))
    # anisotropic 1: aspect sqrt(0.1), the narrow axis's alpha that of roughness 0.5 x 0.562
    stretched = replace(rough, anisotropic=1.0)
    assert U.gi_scale(1.0, 0.5, [rough], 0.35) == 0.5
    assert U.gi_scale(1.0, 0.5, [rough, rough, coat], 0.35) == 0.5
    for scene in ([glossy], [textured], [rough, glossy], [stretched]):
        assert U.gi_scale(1.0, 0.5, scene, 0.35) == 1.0
    assert U.gi_scale(1.0, 0.5, [stretched], 0.28) == 0.5
    assert U.gi_scale(0.25, 0.5, [rough], 0.35) == 0.25     # render_scale is lower
    assert U.gi_scale(0.5, 1.0, [glossy], 0.35) == 0.5
    assert U.gi_scale(1.0, 0.5, [glossy], 0.2) == 0.5       # 0.3 counts as rough from 0.2
    s = Settings()                                          # the default preset, balanced
    assert s["pbgi.rough_scale_from"] == 0.35
    assert U.gi_scale_of(s, [Material()]) == 0.5
    assert U.gi_scale_of(s, [Material(roughness=0.35, metallic=1.0)]) == 0.5
    assert U.gi_scale_of(s, [glossy]) == 1.0
    s.set("pbgi.quality", "final")
    assert U.gi_scale_of(s, [Material()]) == 1.0


def test_rough_light_at_half_resolution_is_as_accurate(demo_relighter):
    """Why the default preset renders a scene of rough materials at half the GI resolution: on
    the demo close-up (128 x 128, Hybrid M 24, diffuse and rough metal 0.6) the upsampled image
    is nearly as close to Classic at M = 32 as the full-resolution one - per pixel within 1.2x
    of its error, 4x4-pooled within 1.3x - because PBGI's own error is of the order of what the
    upsampling loses on smooth light; it gathers a quarter of the receivers. Measured per pixel
    / pooled, half against full: diffuse 2.76 / 1.73% against 2.76 / 1.41%, rough metal 6.63 /
    4.05% against 5.72 / 3.57% (before the block levels took the far field's share of the
    hemisphere into account, app/pbgi/farfield.py: 2.95 / 1.99% against 3.18 / 1.89%, and 6.66 /
    4.09% against 5.82 / 3.66%: the full resolution gained more)."""
    from app.bench.image_metrics import relative_rmse
    from app.demo.room import default_views
    from app.material import Material
    r = demo_relighter
    cam = default_views(128, 128)["closeup"]
    p = RenderParams(mode="hybrid", microbuffer=24)
    for mat in (S.diffuse(0.6), Material(base_color=(0.9, 0.6, 0.3), metallic=1.0,
                                         roughness=0.6)):
        scale = U.gi_scale(1.0, 0.5, [mat], p.glossy_below)
        assert scale == 0.5
        ref = r.render(cam, [mat], RenderParams(mode="classic", microbuffer=32)).image
        mask = ref[..., 3] > 0.999
        full = U.render_upsampled(r, cam, [mat], p, 1, 1.0)
        half = U.render_upsampled(r, cam, [mat], p, 1, scale)
        assert half.stats.completed and half.stats.receivers < 0.3 * full.stats.receivers
        for pool, allow in ((1, 1.2), (4, 1.3)):
            e_full = relative_rmse(full.image, ref, mask, pool=pool)
            e_half = relative_rmse(half.image, ref, mask, pool=pool)
            assert e_half < allow * e_full, (mat.metallic, pool, e_half, e_full)
