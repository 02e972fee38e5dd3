"""Degenerate geometry and views, in every mode: grazing views, receivers inside a node's
bounding sphere, an asset touching or cutting the cloud, points on the asset's surface, repeated
points, normal cones of aperture pi, clouds of one and two points, planar and collinear clouds,
and a whole scene 1e6 m from the origin. Each render is finite, non-negative and completed, and
the micro-buffer modes agree with Classic where they share its cut."""

from __future__ import annotations

import numpy as np
import pytest

from tests.stability.sane import MODES, assert_sane, params
from tests.support import scenes as S
from app.cloud import PointCloud
from app.material import Material
from app.pbgi.renderer import Relighter

MATERIALS = {"diffuse": Material(base_color=(0.5,) * 3, roughness=0.5),
             "glossy-metal": Material(base_color=(0.9,) * 3, roughness=0.05, metallic=1.0)}
SIZE = 24
OFFSET = np.array([1e6, 0.0, 1e6])


def _room():
    return S.box_room(0.1)


def _cloud(pos, nrm, col):
    pos = np.asarray(pos, float).reshape(-1, 3)
    nrm = np.broadcast_to(np.asarray(nrm, np.float32), pos.shape)
    col = np.broadcast_to(np.asarray(col, np.float32), pos.shape)
    return PointCloud(pos, nrm, col, hdr=True, source="test:stability")


def _ball(c, r=0.3):
    return S.sphere(c, r, subdivisions=3)


def _cam(at, eye_offset=(0.6, 0.2, 0.6)):
    at = np.asarray(at, float)
    return S.look(at + eye_offset, at, SIZE, 40)


def _coincident():
    """Room points plus points on the asset's own vertices (its normals, grey)."""
    room, mesh = _room(), _ball((0.0, 0.8, 0.0))
    cloud = PointCloud(np.r_[room.positions, mesh.positions], np.r_[room.normals, mesh.normals],
                       np.r_[room.colors, np.full((len(mesh.positions), 3), 0.5, np.float32)],
                       hdr=True)
    return cloud, mesh


def _twice(normal_sign):
    """Every room point twice: the same normal (zero-size leaves of duplicates) or the
    opposite one (a normal cone of aperture pi at every point)."""
    room = _room()
    return PointCloud(np.r_[room.positions, room.positions],
                      np.r_[room.normals, normal_sign * room.normals],
                      np.r_[room.colors, room.colors], hdr=True)


def _line(n=200):
    t = np.linspace(-1.0, 1.0, n)
    return _cloud(np.c_[t, np.full(n, 2.0), np.zeros(n)], (0, -1, 0), 3.0)


def _offset(cloud, mesh, cam):
    from app.io.mesh import transform_mesh
    m = np.eye(4)
    m[:3, 3] = OFFSET
    moved = PointCloud(cloud.positions + OFFSET, cloud.normals, cloud.colors, hdr=True)
    return moved, transform_mesh(mesh, m), S.look(np.asarray(cam.position) + OFFSET,
                                                  np.asarray(cam.look_at) + OFFSET, cam.width,
                                                  cam.fov_y_deg)


CENTRE = (0.0, 0.8, 0.0)
# name -> () -> (cloud, mesh, camera)
SCENES = {
    "grazing-2deg": lambda: (_room(), S.quad((0.0, 1.0, 0.0), (0.0, 1.0, 0.0), 0.4),
                             S.look((0.9, 1.03, 0.0), (0.0, 1.0, 0.0), 32, 10)),
    "asset-1cm-above-floor": lambda: (_room(), _ball((0, 0.31, 0)), _cam((0, 0.31, 0))),
    "asset-touching-floor": lambda: (_room(), _ball((0, 0.3, 0)), _cam((0, 0.3, 0))),
    "asset-through-floor": lambda: (_room(), _ball((0, 0.15, 0)), _cam((0, 0.15, 0))),
    "asset-through-wall": lambda: (_room(), _ball((0.9, 0.8, 0)), _cam((0.9, 0.8, 0),
                                                                      (-0.8, 0.2, 0.4))),
    "points-on-asset-surface": lambda: (*_coincident(), _cam(CENTRE)),
    "duplicate-points": lambda: (_twice(1.0), _ball(CENTRE), _cam(CENTRE)),
    "opposite-normals": lambda: (_twice(-1.0), _ball(CENTRE), _cam(CENTRE)),
    "one-point": lambda: (_cloud([[0, 2, 0]], (0, -1, 0), 5.0), _ball(CENTRE), _cam(CENTRE)),
    "two-points": lambda: (_cloud([[0, 2, 0], [0, 0, 0]], [[0, -1, 0], [0, 1, 0]],
                                  [[5, 5, 5], [1, 1, 1]]), _ball(CENTRE), _cam(CENTRE)),
    "fifty-identical-points": lambda: (_cloud(np.tile([0, 2, 0], (50, 1)), (0, -1, 0), 1.0),
                                       _ball(CENTRE), _cam(CENTRE)),
    "planar-floor-only": lambda: (_room().subset(_room().positions[:, 1] < 1e-9),
                                  _ball(CENTRE), _cam(CENTRE)),
    "collinear": lambda: (_line(), _ball(CENTRE), _cam(CENTRE)),
}


@pytest.fixture(scope="module")
def built():
    """One Relighter per scene, built on first use."""
    cache = {}

    def get(name):
        if name not in cache:
            cloud, mesh, cam = SCENES[name]()
            r = Relighter()
            r.set_cloud(cloud)
            r.set_asset(mesh)
            cache[name] = (r, cam)
        return cache[name]
    return get


# Passes whose mean Mipmapped and Hybrid must match Classic's in: one pass of Hybrid is one draw
# of its blocks' frame turns (lib/microbuffer.glsl: mb_frame_shared), and the grazing quad has
# 8 blocks at M 8 - single passes of it ranged 0.835-0.999 against Classic's 0.885-0.929 (8
# passes, 2026-12-06), their means within 3%; with one fixed frame per block the mean of 8 was
# 9% off Classic's, while its pass 0 happened to be within 0.3%.
PASSES = 4


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("scene", list(SCENES))
def test_degenerate_geometry_renders_finite(built, scene, mode):
    r, cam = built(scene)
    for name, mat in MATERIALS.items():
        res = r.render(cam, [mat], params(mode))
        rgb = assert_sane(res, f"{scene}/{mode}/{name}", min_receivers=50)
        assert rgb.max() > 0, (scene, mode, name)   # lit: the points are not lost
        if mode in ("mipmapped", "hybrid"):     # Classic's light, in the mean of PASSES
            got = r.render_passes(cam, [mat], params(mode), passes=PASSES).image
            ref = r.render_passes(cam, [mat], params("classic"), passes=PASSES).image
            ratio = got[..., :3].sum() / ref[..., :3].sum()
            assert abs(ratio - 1) < 0.05, (scene, mode, name, ratio)


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("scene", ["asset-touching-floor", "duplicate-points"])
def test_a_million_metres_away_renders_the_same(built, scene, mode):
    """Cloud, asset and camera all moved by (1e6, 0, 1e6) m: the image at the origin, to float32
    rounding (positions stay float64 until each renderer subtracts its origin)."""
    r, cam = built(scene)
    cloud, mesh, cam_far = _offset(r.cloud, r.mesh, cam)
    far = Relighter()
    far.set_cloud(cloud)
    far.set_asset(mesh)
    for name, mat in MATERIALS.items():
        near = r.render(cam, [mat], params(mode)).image
        res = far.render(cam_far, [mat], params(mode))
        assert_sane(res, f"{scene}/{mode}/{name}/offset", min_receivers=50)
        assert np.array_equal(res.image[..., 3], near[..., 3]), (scene, mode, name)
        diff = np.abs(res.image[..., :3] - near[..., :3]).mean() / near[..., :3].mean()
        assert diff < 1e-3, (scene, mode, name, diff)
