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


def _room(floor=-1.3, seed=0):
    """A synthetic scan: a noisy floor at ``floor``, two walls, a table top, strays below."""
    rng = np.random.default_rng(seed)
    n = 4000
    fl = np.c_[rng.uniform(-2, 2, n), floor + rng.normal(0, 0.003, n), rng.uniform(-2, 2, n)]
    wall = np.c_[rng.uniform(-2, 2, n), rng.uniform(floor, floor + 2.5, n), np.full(n, -2.0)]
    table = np.c_[rng.uniform(-0.5, 0.5, 500), np.full(500, floor + 0.7), rng.uniform(-0.5, 0.5, 500)]
    strays = np.c_[rng.uniform(-2, 2, 40), floor - rng.uniform(0.2, 1.0, 40), rng.uniform(-2, 2, 40)]
    pts = np.vstack([fl, wall, table, strays])
    nrm = np.vstack([np.tile([0, 1, 0], (n, 1)), np.tile([0, 0, 1], (n, 1)),
                     np.tile([0, 1, 0], (500, 1)), np.tile([0, 1, 0], (40, 1))]).astype(float)
    return pts, nrm


def test_scan_floor_finds_the_floor_under_noise_and_strays():
    from app.ui.navigation import scan_floor
    pts, nrm = _room()
    assert scan_floor(pts, nrm) == pytest.approx(-1.3, abs=0.01)
    assert scan_floor(pts) == pytest.approx(-1.3, abs=0.02)       # without normals
    assert scan_floor(pts, -nrm) == pytest.approx(-1.3, abs=0.01)   # flipped (photogrammetry)
    assert scan_floor(pts[:5]) is None
    pts[::50] = np.nan                                              # holes are ignored
    assert scan_floor(pts, nrm) == pytest.approx(-1.3, abs=0.01)


def test_scan_floor_of_the_demo_room():
    from app.demo import room
    from app.demo.cache import load_demo
    from app.ui.navigation import scan_floor
    scene = load_demo()
    floor = scan_floor(scene.ldr.positions, scene.ldr.normals)
    assert floor == pytest.approx(room.ROOM_MIN[1], abs=0.01)       # y = 0 (app/demo/room.py)


def _nav_above(floor=-1.3):
    from app.ui.navigation import ViewNavigator
    nav = ViewNavigator(pivot=(0.0, -0.8, 0.0), distance=2.0, pitch=-0.3)
    nav.floor_y = floor
    return nav


def test_orbit_stops_above_the_floor_and_still_turns():
    from app.ui.navigation import FLOOR_CLEARANCE
    nav = _nav_above()
    yaw0 = nav.yaw
    for _ in range(50):
        nav.orbit(20, -200)            # drag up: the eye goes down
        assert nav.position[1] >= -1.3 + FLOOR_CLEARANCE - 1e-9
    assert nav.position[1] == pytest.approx(-1.3 + FLOOR_CLEARANCE)   # it stopped right there
    assert nav.yaw != yaw0
    nav.orbit(0, 100)                  # and comes back up at once
    assert nav.position[1] > -1.3 + FLOOR_CLEARANCE + 0.1


def test_free_orbit_goes_under_the_floor():
    nav = _nav_above()
    nav.free = True
    for _ in range(10):
        nav.orbit(0, -200)
    assert nav.position[1] < -1.3


def test_pan_zoom_and_fly_lift_the_eye_above_the_floor():
    from app.ui.navigation import FLOOR_CLEARANCE
    lo = -1.3 + FLOOR_CLEARANCE
    nav = _nav_above()
    nav.pan(0, 5000, 600)              # drag down: the view moves down
    assert nav.position[1] >= lo - 1e-9
    nav = _nav_above()
    nav.pivot[1] = -2.0                # a pivot below the floor (a gizmo target, say)
    nav.zoom(-5)
    assert nav.position[1] >= lo - 1e-9
    nav = _nav_above()
    nav.fly(0, 0, -10)
    assert nav.position[1] >= lo - 1e-9


def test_one_long_drag_under_the_floor_stops_at_the_clearance():
    """Thousands of pixels in one event, and a pivot near the floor, as when orbiting an object
    standing on it."""
    from app.ui.navigation import FLOOR_CLEARANCE
    lo = -1.3 + FLOOR_CLEARANCE
    for pivot_y in (-0.8, -1.25, -1.3, -1.6):
        nav = _nav_above()
        nav.pivot[1] = pivot_y
        nav.orbit(300, -5000)
        assert nav.position[1] == pytest.approx(lo) and nav.yaw == pytest.approx(1.8)
        if pivot_y > lo:
            assert nav.pivot[1] == pivot_y           # the pivot stays: the view tilts
    nav = _nav_above()
    nav.pivot[1] = -9.0                             # no pitch can keep the eye up: lifted
    nav.orbit(0, -5000)
    assert nav.position[1] == pytest.approx(lo)


def test_zoom_out_while_looking_up_keeps_the_pivot_in_the_middle():
    from app.ui.navigation import FLOOR_CLEARANCE
    nav = _nav_above()
    nav.pitch = 0.6                                  # looking up: the eye is below the pivot
    nav.zoom(-10)
    assert nav.position[1] == pytest.approx(-1.3 + FLOOR_CLEARANCE)
    np.testing.assert_allclose(nav.pivot, (0.0, -0.8, 0.0))
    cam = nav.camera(100, 100)
    np.testing.assert_allclose(_pixel(cam, nav.pivot), (50, 50), atol=1e-9)
    assert 0 < nav.pitch < 0.6


def test_frame_above_the_floor_keeps_the_asset_centred():
    from app.ui.navigation import FLOOR_CLEARANCE
    nav = _nav_above()
    nav.pitch = 0.5
    c = np.array([0.0, -1.0, 0.0])                   # an asset standing on the floor
    nav.frame(c, 0.3)
    assert nav.position[1] >= -1.3 + FLOOR_CLEARANCE - 1e-9
    np.testing.assert_allclose(_pixel(nav.camera(100, 100), c), (50, 50), atol=1e-9)


def test_a_view_placed_under_the_floor_is_kept_until_the_next_motion():
    from app.ui.navigation import FLOOR_CLEARANCE
    nav = _nav_above()
    nav.look_from((0.0, -2.0, 2.0), (0.0, -0.5, 0.0))
    np.testing.assert_allclose(nav.position, (0.0, -2.0, 2.0), atol=1e-12)
    nav.orbit(5, 0)
    assert nav.position[1] >= -1.3 + FLOOR_CLEARANCE - 1e-9


def test_no_floor_means_no_constraint():
    nav = _nav_above(floor=None)
    nav.orbit(0, -2000)
    assert nav.position[1] < -1.3
