"""The asset in the room against the path tracer (the committed Mitsuba references of
app/bench/asset_scenes.py, max_depth 3: one inter-reflection): a non-convex asset's self-shadows
and inter-reflection, a convex one unchanged (rendered without its surfels: it cannot shadow or light itself), its shadow on the demo room's floor; and the scan's
albedo estimate against the demo room's true albedo.

Tolerances (4x4-pooled relative RMSE over the asset; the references' own noise floor is 0.1-1.5%):
measured on the tuning room (apartment) and the held-out one (city) at M = 24, 4096 surfels
(stratified inside each triangle, leaves 1.25x: app/pbgi/scene_tree.py, LEAF_DISC), one bounce,
Classic and Hybrid - diffuse blocks 2.4-5.0% (asserted at 5.5%; the issue's target is 8%),
rough metal blocks 3.8-6.8% (the 10% target; 11.1-14.0% with the leaves' gaps and a diffuse
bounce for the metal, app/pbgi/asset_scene.py: the glossy bounce), the sphere 0.7-1.3% (5%),
and always below half of the error without the asset in the tree (23-47%).

Smooth metals (the mirror bounce, asset_scene.py: mirror_params): gold 0.25 blocks 15.1% and
30.9% (asserted at 35%), silver 0.05 19.6% and 40.6% (45%) - the city's sun, reflected twice,
is where the distant-light mirror model is furthest off - and each at least 1.2x below the
plane alone (19.2 / 39.1% and 49.9 / 66.8%, the bounce before it); without the asset in the
tree they are 96 / 45% and 64 / 48%, so the 2x rule above does not apply to them in the city.
"""

from __future__ import annotations

import numpy as np
import pytest

from app.bench import asset_scenes as A
from app.bench.glossy import evaluate
from app.pbgi import asset_scene
from app.pbgi.renderer import Relighter, RenderParams

TARGET = {("blocks", "diffuse"): 0.055, ("blocks", "rough_metal"): 0.10,
          ("blocks", "glossy_metal"): 0.35, ("blocks", "mirror_metal"): 0.45,
          ("sphere", "diffuse"): 0.05}
SMOOTH = ("glossy_metal", "mirror_metal")     # the mirror bounce's kinds


@pytest.fixture(scope="module", params=["city", "apartment"])
def room(request):
    return request.param


@pytest.mark.parametrize("asset", A.ASSETS)
def test_asset_against_the_path_tracer(room, asset, monkeypatch):
    index = A.load_index()["references"]
    cloud, mesh, cam = A.asset_scene(room, asset)
    r = Relighter()
    r.set_cloud(cloud)
    r.set_asset(mesh)
    try:
        for kind in A.KINDS:
            name = A.reference_name(room, asset, kind)
            if name not in index:
                continue
            ref = A.load_image(name)
            for mode in ("classic", "hybrid"):
                on = r.render(cam, [A.material(kind)], RenderParams(mode=mode, microbuffer=24))
                assert on.stats.completed
                if asset == "sphere":   # convex: rendered without its surfels (walks_asset)
                    assert on.stats.asset_convex_skipped and on.stats.asset_surfels == 0
                else:
                    assert on.stats.asset_surfels > 0
                err = evaluate(on.image, ref)["rel_rmse_4x4"]
                assert err <= TARGET[(asset, kind)], (room, asset, kind, mode, err)
                if asset == "blocks" and kind in SMOOTH:
                    with monkeypatch.context() as mp:     # the plane alone: no mirror weight
                        mp.setattr(asset_scene, "MIRROR_ROUGHNESS", (-1.0, -0.5))
                        plane = r.render(cam, [A.material(kind)],
                                         RenderParams(mode=mode, microbuffer=24)).image
                    assert err < evaluate(plane, ref)["rel_rmse_4x4"] / 1.2
                elif asset == "blocks":
                    off = r.render(cam, [A.material(kind)],
                                   RenderParams(mode=mode, microbuffer=24,
                                                asset_occlusion=False)).image
                    assert err < 0.5 * evaluate(off, ref)["rel_rmse_4x4"]
    finally:
        r.release()


@pytest.fixture(scope="module")
def shadow():
    cloud, mesh, cam = A.shadow_scene()
    r = Relighter()
    r.set_cloud(cloud)
    r.set_asset(mesh)
    diff = r.differential(None, RenderParams())
    plain, lit = r.background(cam), r.background(cam, diff)
    asset = r.render(cam, None, RenderParams(mode="envmap")).image[..., 3] > 0
    yield cloud, diff, plain, lit, asset
    r.release()


def _pool(x, k=4):
    h, w = x.shape[0] // k * k, x.shape[1] // k * k
    return x[:h, :w].reshape(h // k, k, w // k, k).mean(axis=(1, 3))


def test_the_shadow_on_the_floor_matches_the_path_tracer(shadow):
    """Mitsuba's shadow catcher (a diffuse square over the demo room's floor, with and without
    the sphere; their ratio is the shadow) against ours (the splats with and without the
    differential): in the shadowed region (reference ratio < 0.9) the composite is darker by
    more than a quarter, its shadow depth within 15% of the reference's (measured -2.5%), the
    4x4-pooled relative RMSE of the ratio within 15% (measured 7.6%); outside it nothing
    darkens by more than 2% on average."""
    _, _, plain, lit, asset = shadow
    w, wo = A.load_image("shadow_with.exr"), A.load_image("shadow_without.exr")
    catcher = np.load(str(A.REFERENCES / "shadow_catcher_mask.npy"))
    ref = w.mean(-1) / np.maximum(wo.mean(-1), 1e-6)
    ours = lit[..., :3].mean(-1) / np.maximum(plain[..., :3].mean(-1), 1e-6)
    covered = catcher & ~asset & (plain[..., 3] > 0)
    shade = covered & (ref < 0.9)
    assert shade.sum() > 500
    assert ours[shade].mean() < 0.75
    depth_ref, depth = (1 - ref[shade]).mean(), (1 - ours[shade]).mean()
    assert abs(depth / depth_ref - 1) < 0.15, (depth, depth_ref)
    full = _pool(shade.astype(float)) > 0.99
    a, b = _pool(np.where(shade, ours, 0)), _pool(np.where(shade, ref, 0))
    assert full.sum() > 20
    assert np.sqrt(((a - b)[full] ** 2).mean()) / b[full].mean() < 0.15
    assert ours[covered & (ref > 0.97)].mean() > 0.98


def test_the_albedo_estimate_on_the_demo_room(shadow):
    """A scan has radiance, not albedo: the differential estimates it as L / (E / pi). The demo
    room knows its albedo (L = albedo / pi x E_true, app/demo/room.py's shade with albedo 1
    gives E_true / pi): the estimate is within 20% for half the points near the asset and
    within 35% for 90% (measured 13% and 26%: the gathered E includes the scan's real indirect
    light, which the demo's constant ambient term underestimates, so the estimate is low)."""
    from app.demo.room import shade
    cloud, diff, _, _, _ = shadow
    p = cloud.positions[diff.index]
    n = cloud.normals[diff.index].astype(np.float64)
    true = cloud.colors[diff.index] / shade(p, n, np.ones((len(p), 3)))
    ok = true.max(axis=1) <= 0.95 + 1e-6                 # diffuse points, not the emitters
    assert ok.sum() > 1000
    rel = np.abs(diff.albedo[ok] / np.maximum(true[ok], 1e-6) - 1)
    assert np.median(rel) < 0.20 and np.percentile(rel, 90) < 0.35
