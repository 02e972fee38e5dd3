"""Receivers whose light is all in the lobe buffers (glossy metals) use a coarse cosine
micro-buffer (pbgi.lobe_only_microbuffer, app/pbgi/lobe.py: lobe_only_receivers), in the same
image as receivers of other materials at the full M."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from app.material import Material
from app.pbgi.lobe import LOBE_BLEND, lobe_only_receivers
from app.pbgi.renderer import RenderParams

GOLD = dict(base_color=(1.0, 0.78, 0.34), metallic=1.0)


def test_blend_matches_the_shader():
    """The Python rule and lib/lobe.glsl's lobe_spec_share use the same blend."""
    text = (Path(__file__).resolve().parents[2] / "shaders/lib/lobe.glsl").read_text()
    assert float(re.search(r"#define LOBE_BLEND ([0-9.]+)", text).group(1)) == LOBE_BLEND


@pytest.mark.parametrize("metallic,roughness,expected", [
    (1.0, 0.25, True),
    (1.0, 0.0, True),                        # the mirror too (lib/lobe.glsl: lobe_tan_floor)
    (1.0, 0.05, True),
    (1.0, 0.1, True),
    (1.0, 0.34, True),                       # below 0.7 x 0.5
    (1.0, 0.36, False),                      # shared with the cosine buffer
    (0.99, 0.25, False),                     # some diffuse (a metallic texture below 1, too)
    (0.0, 0.25, False),
])
def test_which_receivers_are_lobe_only(metallic, roughness, expected):
    got = lobe_only_receivers(np.float32([metallic]), np.float32([roughness]), 0.5)
    assert got.tolist() == [expected]


def _render(r, mat, lobe_only_m, mode="classic", size=32):
    from app.demo.room import default_views
    cam = default_views(size, size)["closeup"]
    r.forget_microbuffers()
    mats = mat if isinstance(mat, list) else [mat]
    return r.render(cam, mats, RenderParams(mode=mode, microbuffer=16,
                                            lobe_only_microbuffer=lobe_only_m))


@pytest.mark.parametrize("roughness", [0.25, 0.0])
def test_gold_renders_with_the_coarse_cosine_buffer_and_the_same_light(demo_relighter,
                                                                        roughness):
    """Gold 0.25 and a gold mirror on the demo close-up: the cosine micro-buffer drops to M 8
    (and its entry tests with it) while the image stays within 1% in the mean and 3% per pixel
    on average of the full-M render (measured 0.17% mean difference, 0.05% in the mean radiance
    at 0.25; 0.02% and 0.00% at 0); a dielectric keeps its M."""
    gold = Material(roughness=roughness, **GOLD)
    full = _render(demo_relighter, gold, 0)
    coarse = _render(demo_relighter, gold, 8)
    assert full.stats.microbuffer == 16 and coarse.stats.microbuffer == 8
    assert full.stats.completed and coarse.stats.completed
    assert coarse.stats.splat_tests < 0.5 * full.stats.splat_tests
    cover = full.image[..., 3] > 0.5
    a, b = full.image[..., :3][cover], coarse.image[..., :3][cover]
    assert np.isfinite(b).all() and cover.sum() > 100
    assert abs(b.mean() / a.mean() - 1.0) < 0.01
    assert np.abs(a - b).mean() / a.mean() < 0.03
    plastic = _render(demo_relighter, Material(roughness=0.25, base_color=(0.8, 0.2, 0.2)), 8)
    assert plastic.stats.microbuffer == 16


@pytest.fixture
def two_material_sphere(demo_relighter):
    """The demo sphere with its faces left of the centre given material 1."""
    from dataclasses import replace
    mesh = demo_relighter.mesh
    centre = mesh.positions[mesh.indices].mean(axis=1)[:, 0]
    ids = (centre < np.median(centre)).astype(np.uint32)
    demo_relighter.set_asset(replace(mesh, material_ids=ids, materials=[Material()] * 2))
    yield demo_relighter
    demo_relighter.set_asset(mesh)


@pytest.mark.parametrize("mode", ["classic", "hybrid"])
def test_mixed_materials_give_each_receiver_its_own_microbuffer(two_material_sphere, mode):
    """Plastic and gold 0.25 on one sphere: the gold receivers get the coarse cosine buffer (M 8),
    the plastic ones keep M 16, in one image. Each half is what a frame of that material alone
    gives: in Classic (a receiver's cut is its own) to float noise; in Hybrid (a block shares
    its far field only between receivers of one group) within 1.5% on average."""
    r = two_material_sphere
    plastic = Material(roughness=0.25, base_color=(0.8, 0.2, 0.2))
    gold = Material(roughness=0.25, **GOLD)
    mixed = _render(r, [plastic, gold], 8, mode, 48)
    rec = r.last_receivers                      # the mixed render's rows: plastic, then gold
    all_gold = _render(r, [gold, gold], 8, mode, 48)
    all_plastic = _render(r, [plastic, plastic], 8, mode, 48)
    st = mixed.stats
    n_gold = all_gold.stats.receivers
    assert all_gold.stats.microbuffer == 8 and all_plastic.stats.microbuffer == 16
    assert st.microbuffer == 16 and st.coarse_microbuffer == 8 and st.completed
    assert 0.3 * st.receivers < st.coarse_receivers < 0.7 * st.receivers
    assert st.micropixels == (st.receivers - st.coarse_receivers) * 256 + st.coarse_receivers * 64
    assert n_gold == st.receivers
    from app.pbgi.gpu_layout import RECEIVER
    assert (RECEIVER.view(rec)["metallic"][-st.coarse_receivers:] == 1.0).all()
    cover = mixed.image[..., 3] > 0.5
    gold_px = np.zeros(cover.shape, bool)
    gold_px.reshape(-1)[RECEIVER.view(rec)["pixel"][-st.coarse_receivers:]] = True
    tol = 1e-4 if mode == "classic" else 0.015
    for part, alone in ((gold_px, all_gold), (cover & ~gold_px, all_plastic)):
        a, b = alone.image[..., :3][part], mixed.image[..., :3][part]
        assert np.isfinite(b).all() and part.sum() > 50
        assert np.abs(a - b).mean() / a.mean() < tol, mode
