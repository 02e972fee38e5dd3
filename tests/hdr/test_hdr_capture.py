"""Cube-map capture by point splatting: geometry, depth and the visibility test."""

from __future__ import annotations

import numpy as np
import pytest

from app.camera import Camera, cube_cameras
from app.hdr.capture import capture_cube, point_spacing, project, splat_face


def _wall(n=40_000, z=-2.0, seed=0):
    """A 4 x 4 m wall at depth z facing +z, coloured by x (a known image)."""
    rng = np.random.default_rng(seed)
    p = np.c_[rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), np.full(n, z)]
    nrm = np.tile([0.0, 0.0, 1.0], (n, 1))
    col = np.c_[(p[:, 0] + 2) / 4, np.full(n, 0.5), np.full(n, 0.2)]
    return p, nrm, col


def test_projection_matches_pixel_rays():
    cam = Camera((0.3, 1.0, -0.2), (1.0, 1.2, -2.0), fov_y_deg=60, width=64, height=48)
    origin, rays = cam.pixel_rays()
    pts = origin + 2.5 * rays.reshape(-1, 3)
    u, v, z = project(cam, pts)
    jj, ii = np.meshgrid(np.arange(64), np.arange(48))
    np.testing.assert_allclose(u, jj.ravel() + 0.5, atol=1e-6)
    np.testing.assert_allclose(v, ii.ravel() + 0.5, atol=1e-6)
    assert np.all(z > 0)


def test_point_spacing_of_a_uniform_plane():
    p, _, _ = _wall(40_000)
    s = point_spacing(p)
    assert s == pytest.approx(np.sqrt(16.0 / 40_000), rel=0.15)


def test_splat_depth_and_colour_of_a_plane():
    p, nrm, col = _wall()
    cam = Camera((0, 0, 0), (0, 0, -1), fov_y_deg=60, width=64, height=64)
    face, st = splat_face(cam, p, nrm, col, point_spacing(p))
    assert st["coverage"] > 0.9                          # splats alone (3 points per pixel)
    np.testing.assert_allclose(face.depth, 2.0, atol=1e-4)  # view depth of z = -2, holes filled
    _, rays = cam.pixel_rays()
    x_hit = 2.0 * rays[..., 0] / -rays[..., 2]           # where each pixel ray meets the wall
    expect = (x_hit + 2) / 4
    assert np.median(np.abs(face.color[..., 0] - expect)) < 0.01
    np.testing.assert_allclose(face.color[..., 1], 0.5, atol=1e-5)


def test_depth_test_hides_points_behind_a_nearer_surface():
    far, nf, cf = _wall(30_000, z=-3.0, seed=1)
    near, nn, cn = _wall(30_000, z=-1.5, seed=2)
    near = near[np.abs(near[:, 0]) < 0.5]             # a 1 m strip in front of the far wall
    nn, cn = nn[: len(near)], cn[: len(near)]
    p = np.r_[far, near]
    cam = Camera((0, 0, 0), (0, 0, -1), fov_y_deg=60, width=96, height=96)
    face, _ = splat_face(cam, p, np.r_[nf, nn], np.r_[cf, cn], point_spacing(p))
    vis, _, _ = face.visible(p)
    behind = (np.abs(far[:, 0]) < 0.8) & (np.abs(far[:, 1]) < 0.8)  # the strip hides |x| < 1
    assert not vis[: len(far)][behind].any()
    uv_in = np.abs(near[:, 1]) < 0.8
    assert vis[len(far):][uv_in].mean() > 0.99
    beside = (np.abs(far[:, 0]) > 1.2) & (np.abs(far[:, 0]) < 1.6) & (np.abs(far[:, 1]) < 1.5)
    assert vis[: len(far)][beside].mean() > 0.99


def test_back_faces_are_culled_and_reported():
    p, nrm, col = _wall()
    cam = Camera((0, 0, -4), (0, 0, 0), fov_y_deg=60, width=32, height=32)  # behind the wall
    face, st = splat_face(cam, p, nrm, col, point_spacing(p))
    assert st["coverage"] == 0.0 and st["back_facing"] > 0
    assert st["back_view_fraction"] > 0.99


def test_cube_capture_keeps_each_face_camera():
    p, nrm, col = _wall()
    cap = capture_cube(p, nrm, col, (0.0, 0.0, 0.0), 32)
    assert [f.camera.look_at.tolist() for f in cap.faces] == \
        [c.look_at.tolist() for c in cube_cameras((0, 0, 0), 32)]
    minus_z = cap.faces[5]
    assert minus_z.covered.mean() > 0.99 and minus_z.intrinsics()[0, 0] == pytest.approx(16.0)
    np.testing.assert_allclose(minus_z.extrinsics(), minus_z.camera.view())


def test_projection_averages_the_faces_by_inverse_ssd():
    """Two faces see the same wall; PatchMatch gave face 0 the value 1 with SSD 0.01, face 1
    the value 3 with SSD 0.03, a third sample is over the threshold. The projection (paper
    Section 4.1: samples weighted by 1 / (SSD + eps), those over t_h refused) gives each point
    (1 / 0.02 x 1 + 1 / 0.04 x 3) / (1 / 0.02 + 1 / 0.04) = 5 / 3 and counts the refusal."""
    from app.hdr.project import SSD_EPS, project_to_points
    p, nrm, col = _wall(20_000)
    faces = [splat_face(Camera((x, 0, 0), (x, 0, -1), fov_y_deg=60, width=48, height=48), p, nrm,
                        col, point_spacing(p))[0] for x in (0.0, 0.1, 0.2)]
    targets = np.flatnonzero((np.abs(p[:, 0] - 0.1) < 0.3) & (np.abs(p[:, 1]) < 0.3))
    given = {0: (1.0, 0.01), 1: (3.0, 0.03), 2: (50.0, 0.5)}

    def sampler(fi, u, v, ldr):
        value, ssd = given[fi]
        return np.full((len(u), 3), value), np.full(len(u), ssd)

    pj = project_to_points(p, col, targets, faces, sampler, th=0.2)
    w0, w1 = 1.0 / (0.01 + SSD_EPS), 1.0 / (0.03 + SSD_EPS)
    assert SSD_EPS == 0.01
    assert pj.has_value[targets].all() and pj.rejected == len(targets)
    np.testing.assert_allclose(pj.values[targets], (w0 * 1.0 + w1 * 3.0) / (w0 + w1), rtol=1e-6)
    np.testing.assert_allclose(pj.score[targets], 0.01)
