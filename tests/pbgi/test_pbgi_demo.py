"""Classic PBGI on the built-in demo room (the benchmark's scene), at a test-sized viewport."""

from __future__ import annotations

import numpy as np
import pytest

from app.demo.room import default_views
from app.material import Material
from app.pbgi.renderer import RenderParams


@pytest.mark.parametrize("view", ["closeup", "whole"])
def test_demo_views_render_completely(demo_relighter, view):
    cam = default_views(24, 24)[view]
    mat = Material(base_color=(0.8, 0.8, 0.8), roughness=0.6)
    res = demo_relighter.render(cam, [mat], RenderParams(mode="classic", microbuffer=16))
    s = res.stats
    assert s.completed and s.receivers > 20 and s.nodes_visited > 100
    img = res.image
    assert np.isfinite(img).all()
    lit = img[..., :3][img[..., 3] > 0]
    assert (lit >= 0).all() and lit.mean() > 0.05
    # the ceiling light is above: the upper half of the sphere is brighter than the lower half
    rows = np.nonzero(img[..., 3].any(axis=1))[0]
    mid = (rows[0] + rows[-1]) // 2
    top = img[rows[0]:mid, :, :3][img[rows[0]:mid, :, 3] > 0].mean()
    bottom = img[mid + 1:rows[-1] + 1, :, :3][img[mid + 1:rows[-1] + 1, :, 3] > 0].mean()
    assert top > 1.5 * bottom


def test_envmap_and_classic_agree_roughly_on_the_demo(demo_relighter):
    """Both light the sphere with the same room: the envmap baseline ignores parallax, so the
    two differ (that is the point of PBGI), but the image means agree within 35%."""
    cam = default_views(20, 20)["closeup"]
    mat = Material(base_color=(0.7, 0.7, 0.7), roughness=0.8)
    c = demo_relighter.render(cam, [mat], RenderParams(mode="classic", microbuffer=16)).image
    e = demo_relighter.render(cam, [mat], RenderParams(mode="envmap", microbuffer=16)).image
    mask = c[..., 3] > 0
    assert np.array_equal(mask, e[..., 3] > 0)
    ratio = c[..., :3][mask].mean() / e[..., :3][mask].mean()
    assert 0.65 < ratio < 1.35, ratio
