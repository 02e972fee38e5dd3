"""Frames whose materials are all glossy metals use a coarse cosine micro-buffer
(pbgi.lobe_only_microbuffer, app/pbgi/lobe.py: lobe_only): their light is in the lobe buffers."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from app.material import Material
from app.pbgi.lobe import LOBE_BLEND, lobe_only
from app.pbgi.renderer import RenderParams

GOLD = dict(base_color=(1.0, 0.78, 0.34), metallic=1.0)


def test_blend_matches_the_shader():
    """The Python rule and lib/lobe.glsl's lobe_spec_share use the same blend."""
    text = (Path(__file__).resolve().parents[2] / "shaders/lib/lobe.glsl").read_text()
    assert float(re.search(r"#define LOBE_BLEND ([0-9.]+)", text).group(1)) == LOBE_BLEND


@pytest.mark.parametrize("materials,expected", [
    ([Material(roughness=0.25, **GOLD)], True),
    ([Material(roughness=0.0, **GOLD)], False),                      # a mirror's tail
    ([Material(roughness=0.05, **GOLD)], False),
    ([Material(roughness=0.1, **GOLD)], True),
    ([Material(roughness=0.25, clearcoat=1.0, **GOLD)], True),       # clearcoat: lobe buffer
    ([Material(roughness=0.34, **GOLD)], True),                      # below 0.7 x 0.5
    ([Material(roughness=0.36, **GOLD)], False),                     # shared with the cosine
    ([Material(roughness=0.25, base_color=(1, 1, 1), metallic=0.99)], False),   # some diffuse
    ([Material(roughness=0.25, **GOLD), Material(roughness=0.8)], False),
    ([], False),
])
def test_which_frames_are_lobe_only(materials, expected):
    assert lobe_only(materials, 0.5) is expected


def test_a_metallic_texture_could_lower_the_metallic_factor():
    tex = np.ones((2, 2, 4), np.float32)
    m = Material(roughness=0.2, metallic_roughness_texture=tex, **GOLD)
    assert lobe_only([m], 0.5) is False


def _render(r, mat, lobe_only_m):
    from app.demo.room import default_views
    cam = default_views(32, 32)["closeup"]
    r.forget_microbuffers()
    return r.render(cam, [mat], RenderParams(mode="classic", microbuffer=16,
                                             lobe_only_microbuffer=lobe_only_m))


def test_gold_renders_with_the_coarse_cosine_buffer_and_the_same_light(demo_relighter):
    """Gold 0.25 on the demo close-up: the cosine micro-buffer drops to M 8 (and its entry tests
    with it) while the image stays within 1% in the mean and 3% per pixel on average of the
    full-M render (measured 0.17% mean difference, 0.05% in the mean radiance); a dielectric
    keeps its M."""
    gold = Material(roughness=0.25, **GOLD)
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
