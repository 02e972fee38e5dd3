"""Viewport navigation as artists expect it (Blender/Maya): orbit, pan, zoom, frame, fly.

Plain numpy state, no window: the window turns mouse/keyboard events into these calls, and tests
drive them directly. The view is a pivot, a distance and a direction (yaw about +y, pitch above
the horizon); the eye sits ``distance`` behind the pivot along the view direction:

    forward = (cos p sin y, sin p, -cos p cos y)     (yaw = pitch = 0 looks down -z)
    eye     = pivot - distance * forward

Orbit turns the eye about the pivot; fly turns the view about the eye and moves both together.

The floor: a user who orbits under the scan sees the back of the floor splats and loses the
room, so by default every motion keeps the eye ``FLOOR_CLEARANCE`` (5 cm) above the scan's floor
(``floor_y``, found by ``scan_floor``). Motions that turn about the pivot keep the pivot where
it is and tilt the view instead, so what the user looks at stays in the middle of the picture:
orbiting down stops at the lowest pitch that keeps that height (the yaw still turns), zooming
out while looking up slides the eye along the floor towards the horizontal, and "frame" does the
same. Motions that translate (pan, fly) lift pivot and eye together by what is missing, so their
downward part stops at the floor and the rest goes on. When no pitch can keep the eye up (a
pivot more than ``distance`` below the floor, or a saved view under it) pivot and eye are lifted
too. ``free = True`` (the viewer's "free orbit" setting) lifts the constraint. A view placed
explicitly (``from_camera``, ``look_from``: a saved session, "move to" a capture camera) is kept
as given, under the floor too, since it is the user's own choice; only the motions that follow
are constrained (the first one lifts the eye).
"""

from __future__ import annotations

import math

import numpy as np

from app.camera import Camera

ORBIT_RAD_PER_PX = 0.006      # a 500 px drag turns the view by about 170 degrees (Blender: ~same)
ZOOM_STEP = 0.85               # one wheel notch moves the eye 15% closer to the pivot
MIN_DISTANCE = 1e-3
MAX_PITCH = math.radians(89.0)  # never exactly vertical: 'up' would be undefined
FLOOR_CLEARANCE = 0.05          # metres the eye keeps above the scan's floor (a head above a rug)
FLOOR_PERCENTILE = 5.0          # of the heights of horizontal points (below: stray points)


def scan_floor(points, normals=None) -> float | None:
    """The floor height (y is up) of a room scan, or None below 16 points.

    The floor is the lowest large horizontal surface: the 5th percentile of the heights of the
    points on horizontal surfaces (|normal.y| > 0.8: floor, table tops, ceiling; either sign,
    because photogrammetry often flips normals), so the few percent of stray points and noise
    below it do not pull it down; without normals (or fewer than 16 horizontal points), the 5th
    percentile of all heights. Non-finite points are ignored."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    finite = np.isfinite(p).all(axis=1)
    y = p[finite, 1]
    if normals is not None:
        n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)[finite]
        flat = np.abs(n[:, 1]) > 0.8
        if flat.sum() >= 16:
            y = y[flat]
    if len(y) < 16:
        return None
    return float(np.percentile(y, FLOOR_PERCENTILE))


class ViewNavigator:
    def __init__(self, pivot=(0.0, 0.0, 0.0), distance: float = 3.0, yaw: float = 0.0,
                 pitch: float = 0.0, fov_y_deg: float = 50.0):
        self.pivot = np.asarray(pivot, dtype=np.float64).copy()
        self.distance = float(distance)
        self.yaw = float(yaw)
        self.pitch = float(pitch)
        self.fov_y_deg = float(fov_y_deg)
        self.floor_y: float | None = None   # the scan's floor; None: no constraint
        self.free = False                   # True: orbit anywhere, under the floor too

    # -- conversions -----------------------------------------------------------------------------
    @property
    def forward(self) -> np.ndarray:
        cp = math.cos(self.pitch)
        return np.array([cp * math.sin(self.yaw), math.sin(self.pitch), -cp * math.cos(self.yaw)])

    @property
    def position(self) -> np.ndarray:
        return self.pivot - self.distance * self.forward

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up, forward) of the view."""
        f = self.forward
        r = np.array([math.cos(self.yaw), 0.0, math.sin(self.yaw)])
        return r, np.cross(r, f), f

    def camera(self, width: int, height: int) -> Camera:
        return Camera(self.position, self.pivot, (0, 1, 0), self.fov_y_deg, width, height)

    @classmethod
    def from_camera(cls, cam: Camera) -> "ViewNavigator":
        d = cam.look_at - cam.position
        dist = float(np.linalg.norm(d))
        f = d / dist
        pitch = math.asin(float(np.clip(f[1], -1.0, 1.0)))
        pitch = float(np.clip(pitch, -MAX_PITCH, MAX_PITCH))
        yaw = math.atan2(f[0], -f[2])
        return cls(cam.look_at, dist, yaw, pitch, cam.fov_y_deg)

    def look_from(self, position, target) -> None:
        """Place the eye at ``position`` looking at ``target`` (used by "move to" a camera)."""
        nav = ViewNavigator.from_camera(Camera(position, target, fov_y_deg=self.fov_y_deg))
        self.pivot, self.distance = nav.pivot, nav.distance
        self.yaw, self.pitch = nav.yaw, nav.pitch

    # -- orbit / pan / zoom ----------------------------------------------------------------------
    def _lowest_eye(self) -> float | None:
        if self.free or self.floor_y is None:
            return None
        return self.floor_y + FLOOR_CLEARANCE

    def _lift(self) -> None:
        """Raise pivot and eye together until the eye clears the floor."""
        lo = self._lowest_eye()
        if lo is not None and self.position[1] < lo:
            self.pivot[1] += lo - self.position[1]

    def _tilt(self) -> None:
        """Keep the pivot and the distance; lower the pitch until the eye clears the floor
        (eye.y = pivot.y - distance * sin(pitch) >= lo  <=>  sin(pitch) <= s). Only a pivot too
        far below the floor for any pitch is lifted."""
        lo = self._lowest_eye()
        if lo is None:
            return
        s = (self.pivot[1] - lo) / self.distance
        if s < 1.0:
            self.pitch = min(self.pitch, max(math.asin(max(s, -1.0)), -MAX_PITCH))
        self._lift()

    def orbit(self, dx_px: float, dy_px: float) -> None:
        """Mouse drag in pixels (y down): the scene follows the hand, as in Blender."""
        self.yaw = (self.yaw + dx_px * ORBIT_RAD_PER_PX) % (2 * math.pi)
        self.pitch = float(np.clip(self.pitch - dy_px * ORBIT_RAD_PER_PX, -MAX_PITCH, MAX_PITCH))
        self._tilt()

    def pan(self, dx_px: float, dy_px: float, viewport_height_px: int) -> None:
        """Move pivot and eye so the point at the pivot's depth stays under the cursor."""
        r, u, _ = self.basis()
        metres_per_px = 2 * self.distance * math.tan(math.radians(self.fov_y_deg) / 2) / max(
            viewport_height_px, 1)
        self.pivot += (-dx_px * r + dy_px * u) * metres_per_px
        self._lift()

    def zoom(self, notches: float) -> None:
        """Wheel: positive notches move the eye towards the pivot (geometric, never through it)."""
        self.distance = max(self.distance * ZOOM_STEP ** notches, MIN_DISTANCE)
        self._tilt()

    def dolly_drag(self, dy_px: float) -> None:
        """Ctrl+drag zoom (Blender) / Alt+RMB (Maya): drag up moves closer."""
        self.zoom(-dy_px / 40.0)

    def frame(self, centre, radius: float, aspect: float = 1.0) -> None:
        """Centre the pivot on a bounding sphere and back off until it fits both fovs ("F")."""
        half_v = math.radians(self.fov_y_deg) / 2
        half_h = math.atan(math.tan(half_v) * aspect)
        half = min(half_v, half_h)
        self.pivot = np.asarray(centre, dtype=np.float64).copy()
        self.distance = max(1.1 * float(radius) / math.sin(half), MIN_DISTANCE)
        self._tilt()

    # -- fly mode --------------------------------------------------------------------------------
    def look(self, dx_px: float, dy_px: float) -> None:
        """Turn the view about the eye (fly mode mouse look)."""
        eye = self.position
        self.yaw = (self.yaw + dx_px * ORBIT_RAD_PER_PX * 0.5) % (2 * math.pi)
        self.pitch = float(np.clip(self.pitch - dy_px * ORBIT_RAD_PER_PX * 0.5,
                                   -MAX_PITCH, MAX_PITCH))
        self.pivot = eye + self.distance * self.forward
        self._lift()

    def fly(self, forward: float, right: float, up: float) -> None:
        """Move eye and pivot together, in metres along the view axes (up = world up)."""
        r, _, f = self.basis()
        self.pivot += forward * f + right * r + up * np.array([0.0, 1.0, 0.0])
        self._lift()

