"""Viewport navigation: orbit, pan, zoom, frame and fly, checked by projecting points."""

from __future__ import annotations

import math

import numpy as np
import pytest

from app.camera import Camera
from app.ui.navigation import MAX_PITCH, ViewNavigator


def _pixel(cam: Camera, p) -> np.ndarray:
    """Where world point p lands in the image (x right, y down), by the camera's matrices."""
    clip = cam.projection(0.01, 100) @ cam.view() @ np.r_[p, 1.0]
    ndc = clip[:2] / clip[3]
    return np.array([(ndc[0] + 1) / 2 * cam.width, (1 - ndc[1]) / 2 * cam.height])


def test_from_camera_round_trip():
    cam = Camera((1.2, 1.5, 1.6), (-0.3, 0.7, 0.1), fov_y_deg=55, width=64, height=48)
    nav = ViewNavigator.from_camera(cam)
    back = nav.camera(64, 48)
    np.testing.assert_allclose(back.position, cam.position, atol=1e-12)
    np.testing.assert_allclose(back.look_at, cam.look_at, atol=1e-12)
    assert back.fov_y_deg == 55


def test_orbit_keeps_the_pivot_and_distance():
    nav = ViewNavigator((0, 0.6, 0), 2.0, yaw=0.3, pitch=0.2)
    nav.orbit(120, -40)
    assert np.linalg.norm(nav.position - nav.pivot) == pytest.approx(2.0)
    cam = nav.camera(100, 100)
    np.testing.assert_allclose(_pixel(cam, nav.pivot), (50, 50), atol=1e-9)
    nav.orbit(0, -1e6)                                   # never past the pole
    assert nav.pitch == pytest.approx(MAX_PITCH)


def test_pan_moves_the_scene_with_the_cursor():
    """A point at the pivot's depth follows a drag of (dx, dy) pixels exactly."""
    nav = ViewNavigator((0, 0, 0), 3.0, yaw=0.7, pitch=-0.3, fov_y_deg=50)
    p = nav.pivot.copy()
    before = _pixel(nav.camera(200, 100), p)
    nav.pan(13, -7, 100)
    after = _pixel(nav.camera(200, 100), p)
    np.testing.assert_allclose(after - before, (13, -7), atol=1e-6)


def test_zoom_is_geometric_and_never_crosses_the_pivot():
    nav = ViewNavigator(distance=4.0)
    nav.zoom(1)
    nav.zoom(-1)
    assert nav.distance == pytest.approx(4.0)
    nav.zoom(1000)
    assert 0 < nav.distance <= 1e-3


def test_frame_fits_the_sphere_in_both_directions():
    for aspect in (0.5, 1.0, 2.0):
        nav = ViewNavigator((5, 5, 5), 0.1, yaw=1.0, pitch=0.4, fov_y_deg=40)
        c, r = np.array([0.0, 0.6, 0.0]), 0.4
        nav.frame(c, r, aspect)
        cam = nav.camera(int(100 * aspect), 100)
        # every silhouette point of the sphere is inside the image
        rgt, up, fwd = nav.basis()
        for a in np.linspace(0, 2 * np.pi, 64):
            d = nav.distance
            edge = c + r * d / math.sqrt(d * d - r * r) * (math.cos(a) * rgt + math.sin(a) * up)
            x, y = _pixel(cam, edge)
            assert 0 <= x <= cam.width and 0 <= y <= cam.height


def test_fly_moves_eye_and_pivot_together_and_look_turns_about_the_eye():
    nav = ViewNavigator((0, 1, 0), 2.0, yaw=0.0, pitch=0.0)
    eye = nav.position.copy()
    nav.fly(1.0, 0.5, 0.25)
    np.testing.assert_allclose(nav.position - eye, (0.5, 0.25, -1.0), atol=1e-12)
    eye = nav.position.copy()
    nav.look(80, 30)
    np.testing.assert_allclose(nav.position, eye, atol=1e-12)
    assert nav.yaw != 0.0 and nav.pitch < 0.0


def test_look_from_points_at_the_target():
    nav = ViewNavigator()
    nav.look_from((0.5, 1.4, 0.8), (0.0, 0.6, 0.0))
    cam = nav.camera(64, 64)
    np.testing.assert_allclose(cam.position, (0.5, 1.4, 0.8), atol=1e-12)
    np.testing.assert_allclose(_pixel(cam, np.array([0.0, 0.6, 0.0])), (32, 32), atol=1e-9)
