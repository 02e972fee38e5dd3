"""A receiver whose lobe carries a small share of its light (a dielectric's specular) uses fewer
lobe micro-pixels (shaders/lib/lobe_size.glsl); a metal keeps them all."""

from __future__ import annotations

import numpy as np

from app.material import Material
from app.pbgi.renderer import RenderParams


def _render(r, mat):
    from app.demo.room import default_views
    cam = default_views(32, 32)["closeup"]
    r.forget_microbuffers()
    return r.render(cam, [mat], RenderParams(mode="classic", microbuffer=24,
                                             lobe_only_microbuffer=0))


def test_a_weak_lobe_walks_fewer_micro_pixels_than_a_metal(demo_relighter):
    """Same roughness, same scene, same walk but for the lobe's micro-pixels: the grey
    dielectric (4% specular under a 0.6 diffuse: 4 x 4 micro-pixels for most receivers, more
    towards the rim where Fresnel raises the share) ray tests under half of what the metal's full
    lobe buffer does (measured 0.3 on the apartment sphere at roughness 0.3); both complete and
    finite."""
    metal = _render(demo_relighter, Material(roughness=0.2, metallic=1.0,
                                             base_color=(0.6, 0.6, 0.6)))
    plastic = _render(demo_relighter, Material(roughness=0.2, metallic=0.0,
                                               base_color=(0.6, 0.6, 0.6)))
    for res in (metal, plastic):
        assert res.stats.completed and res.stats.lobe_receivers
        assert np.isfinite(res.image).all()
    assert plastic.stats.lobe_tests < 0.5 * metal.stats.lobe_tests, (
        plastic.stats.lobe_tests, metal.stats.lobe_tests)
    assert plastic.stats.lobe_visited < metal.stats.lobe_visited
