"""pbgi.envmap_beyond: the micro-buffer modes hand the frame to the environment map only when
the asset is far from every surface, rough, and cannot shadow itself (app/pbgi/nearfield.py);
the stats say when they did."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from app.io.formats import object_from_dict, placed_mesh
from app.material import Material
from app.pbgi.nearfield import clearance, mesh_is_convex
from app.pbgi.renderer import Relighter, RenderParams
from tests.support import scenes as S

CENTRE = np.array([0.0, 1.0, 0.0])


def _sphere(radius):
    m = S.sphere(tuple(CENTRE), radius, subdivisions=3)
    return m


def test_clearance_is_the_gap_over_the_bounding_radius():
    """A sphere of radius r centred at distance D from a plane of points: (D - r) / r."""
    g = np.mgrid[-3:3:0.02, -3:3:0.02].reshape(2, -1).T
    plane = np.c_[g[:, 0], np.zeros(len(g)), g[:, 1]]          # y = 0; the centre is 1 above
    for r in (0.1, 0.25, 0.5):
        c = clearance(plane, _sphere(r))
        assert c.radius == pytest.approx(r, rel=1e-3)
        assert c.ratio == pytest.approx((1.0 - r) / r, rel=2e-2)
        assert c.convex


def test_convexity():
    assert mesh_is_convex(_sphere(0.3))
    knot = placed_mesh(object_from_dict({"mesh": "knot", "translate": [0, 0, 0], "scale": 1}, "."))
    assert not mesh_is_convex(knot)
    assert not mesh_is_convex(S.quad((0, 0, 0), (0, 0, 1), 1.0))      # open: may shadow itself


@pytest.fixture(scope="module")
def room(ctx):
    rl = Relighter(ctx)
    rl.set_cloud(S.box_room(spacing=0.08))
    return rl


def _cam(radius):
    return S.look(CENTRE + (0.0, 0.3, 4.0 * radius), CENTRE, size=24, fov=40.0)


def test_far_from_every_surface_a_rough_convex_asset_gets_the_environment_map(room):
    room.set_asset(_sphere(0.1))
    cam = _cam(0.1)
    assert room.clearance().ratio > 4
    p = RenderParams(mode="hybrid", microbuffer=12)
    res = room.render(cam, [S.diffuse(0.6)], p)
    assert res.stats.mode == "envmap" and res.stats.envmap_instead_of == "hybrid"
    env = room.render(cam, [S.diffuse(0.6)], replace(p, mode="envmap"))
    assert np.array_equal(res.image, env.image)
    kept = room.render(cam, [S.diffuse(0.6)], replace(p, envmap_beyond=0.0))
    assert kept.stats.mode == "hybrid" and kept.stats.envmap_instead_of is None
    # (how close the two are as the clearance grows: `scanlight bench nearfield`, README)


@pytest.mark.parametrize("why, material, asset, occlusion", [
    ("glossy", Material(metallic=1.0, roughness=0.25), "sphere", True),
    ("clearcoat", Material(roughness=0.8, clearcoat=0.5), "sphere", True),
    ("concave", S.diffuse(0.6), "knot", True),
])
def test_the_near_field_stays_where_the_environment_map_would_be_wrong(room, why, material,
                                                                       asset, occlusion):
    mesh = _sphere(0.1) if asset == "sphere" else placed_mesh(object_from_dict(
        {"mesh": "knot", "translate": list(CENTRE), "scale": 0.2}, "."))
    room.set_asset(mesh)
    assert room.clearance().ratio > 4
    res = room.render(_cam(0.12), [material], RenderParams(mode="hybrid", microbuffer=12,
                                                           asset_occlusion=occlusion))
    assert res.stats.mode == "hybrid" and res.stats.envmap_instead_of is None


def test_near_a_wall_the_near_field_stays(room):
    room.set_asset(_sphere(0.5))
    assert room.clearance().ratio < 4
    res = room.render(_cam(0.5), [S.diffuse(0.6)], RenderParams(mode="classic", microbuffer=8))
    assert res.stats.mode == "classic" and res.stats.clearance < 4
