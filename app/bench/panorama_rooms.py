"""Test rooms made from real HDR panoramas (../shared/data/*.exr, see its README), for the
expansion's tests and benchmarks: unlike the demo room, their light is measured, not modelled.
Not part of the application (nothing in app/ outside app/bench imports it).

The panorama is mapped onto a box room around the capture centre: every wall point gets the
panorama's radiance in its direction from the centre (that is the ground truth). The LDR scan
clips it at an exposure that saturates the brightest few percent; a rectilinear crop of the
panorama with its own yaw, pitch and field of view is the unregistered HDR photo. The capture
position is off the centre, so the cube-map renderings see the walls with a parallax the photo
does not have: the matching is not a pure rotation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.camera import Camera
from app.cloud import PointCloud
from app.color import luminance
from app.demo.room import DemoScene, ldr_scan
from app.render.equirect import direction_to_uv, sample_panorama  # noqa: F401 (re-exported)

ROOM_MIN = np.array([-2.0, 0.0, -2.0])
ROOM_MAX = np.array([2.0, 2.8, 2.0])
CENTRE = np.array([0.0, 1.4, 0.0])


def box_points(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Area-uniform points on the inside of the room box, normals facing in."""
    rng = np.random.default_rng(seed)
    size = ROOM_MAX - ROOM_MIN
    faces = []  # (axis, value, inward normal sign)
    for axis in range(3):
        faces += [(axis, ROOM_MIN[axis], 1.0), (axis, ROOM_MAX[axis], -1.0)]
    areas = np.array([np.prod(np.delete(size, a)) for a, _, _ in faces])
    counts = rng.multinomial(n, areas / areas.sum())
    pos, nrm = [], []
    for (axis, val, sign), c in zip(faces, counts):
        p = ROOM_MIN + rng.random((c, 3)) * size
        p[:, axis] = val
        nn = np.zeros((c, 3))
        nn[:, axis] = sign
        pos.append(p)
        nrm.append(nn)
    return np.concatenate(pos), np.concatenate(nrm).astype(np.float32)


def brightest_direction(pano: np.ndarray) -> np.ndarray:
    """Unit direction of the panorama's brightest (smoothed) region."""
    from scipy.ndimage import uniform_filter

    h, w = pano.shape[:2]
    y = uniform_filter(luminance(pano), size=5, mode="wrap")
    i, j = np.unravel_index(np.argmax(y), y.shape)
    lon = ((j + 0.5) / w - 0.5) * 2 * np.pi
    lat = (0.5 - (i + 0.5) / h) * np.pi
    return np.array([np.cos(lat) * np.sin(lon), np.sin(lat), -np.cos(lat) * np.cos(lon)])


def box_exit(origin: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Points where rays from ``origin`` (inside the room) leave the box."""
    d = np.where(np.abs(dirs) < 1e-12, 1e-12, dirs)
    t = np.maximum((ROOM_MIN - origin) / d, (ROOM_MAX - origin) / d).min(axis=1)
    return origin + t[:, None] * dirs


def photo_camera(pano: np.ndarray, position, look_offset_deg=(20.0, -10.0), fov: float = 75.0,
                 size=(384, 256), roll_deg: float = 0.0) -> Camera:
    """A camera at ``position`` looking ``look_offset_deg`` (yaw, pitch) away from the brightest
    region of the panorama, so its lights are in frame but not centred; rolled by ``roll_deg``."""
    d = brightest_direction(pano)
    yaw, pitch = np.radians(look_offset_deg)
    # rotate the look direction by yaw about +y, then tilt by pitch
    c, s = np.cos(yaw), np.sin(yaw)
    d = np.array([c * d[0] + s * d[2], d[1], -s * d[0] + c * d[2]])
    lat = np.clip(np.arcsin(np.clip(d[1], -1, 1)) + pitch, -1.2, 1.2)
    hz = d[[0, 2]] / max(np.linalg.norm(d[[0, 2]]), 1e-9)
    look = np.array([np.cos(lat) * hz[0], np.sin(lat), np.cos(lat) * hz[1]])
    right = np.cross(look, (0.0, 1.0, 0.0))
    right /= max(np.linalg.norm(right), 1e-9)
    up = np.cross(right, look)
    r = np.radians(roll_deg)
    up = np.cos(r) * up + np.sin(r) * right
    pos = np.asarray(position, dtype=np.float64)
    return Camera(pos, pos + look, up, fov_y_deg=fov, width=int(size[0]), height=int(size[1]))


def render_room_photo(pano: np.ndarray, cam: Camera) -> np.ndarray:
    """What ``cam`` sees of the box room: each pixel's ray hits a wall, whose radiance is the
    panorama's in that point's direction from the centre (exact from the centre; from elsewhere
    the walls show the parallax a real photo beside the capture has)."""
    origin, rays = cam.pixel_rays()
    hit = box_exit(np.asarray(origin, dtype=np.float64), rays.reshape(-1, 3).astype(np.float64))
    return sample_panorama(pano, hit - CENTRE).reshape(cam.height, cam.width, 3)


@dataclass(frozen=True)
class PhotoKind:
    """One way of taking the expansion's photo (the issue's protocol: field of view 40-100 deg,
    roll up to 30 deg, exposure -3..+3 stops, 256-1024 px, at the capture or beside it)."""

    name: str
    fov: float = 75.0
    roll: float = 0.0           # degrees
    stops: float = 0.0          # exposure of the photo relative to the scene's radiance
    size: tuple = (384, 256)
    beside: float = 0.0         # metres from the capture position, sideways
    look: tuple = (20.0, -10.0)  # (yaw, pitch) degrees away from the brightest region


PHOTO_KINDS = (
    PhotoKind("plain"),
    PhotoKind("wide-roll", fov=100.0, roll=30.0, stops=3.0, size=(1024, 768), look=(35.0, -5.0)),
    PhotoKind("narrow-dark", fov=40.0, roll=-15.0, stops=-3.0, size=(256, 256), look=(8.0, -4.0)),
    PhotoKind("beside", fov=60.0, roll=10.0, stops=1.0, size=(512, 384), beside=0.5,
              look=(15.0, -15.0)),
)
BY_PHOTO_KIND = {k.name: k for k in PHOTO_KINDS}


def panorama_room(pano: np.ndarray, n_points: int = 50_000, seed: int = 0,
                   photo_offset_deg: tuple[float, float] = (20.0, -10.0), photo_fov: float = 75.0,
                   photo_size: tuple[int, int] = (384, 256),
                   capture_offset=(0.35, -0.15, 0.25), clip_percentile: float = 97.0,
                   kind: PhotoKind | None = None) -> DemoScene:
    """The scene. Without ``kind`` the photo is taken from the room centre and the capture is
    ``capture_offset`` from it (the earlier protocol); with a ``kind`` (the issue-14 protocol)
    the capture is at the centre and the photo at it or ``kind.beside`` metres to its side."""
    pano = np.asarray(pano, dtype=np.float32)
    pos, nrm = box_points(n_points, seed)
    gt_cols = sample_panorama(pano, pos - CENTRE)
    gt = PointCloud(pos, nrm, gt_cols, hdr=True, source="panorama-room")
    y = luminance(gt_cols)
    alpha = float(1.0 / max(np.percentile(y, clip_percentile), 1e-6))
    ldr = ldr_scan(gt, alpha)
    if kind is None:
        cam = photo_camera(pano, CENTRE, photo_offset_deg, photo_fov, photo_size)
        capture = CENTRE + np.asarray(capture_offset)
        photo = render_room_photo(pano, cam)
    else:
        look = photo_camera(pano, CENTRE, kind.look).basis()
        side = look[0] * kind.beside  # the camera's right: sideways, level
        cam = photo_camera(pano, CENTRE + side, kind.look, kind.fov, kind.size, kind.roll)
        capture = CENTRE
        photo = render_room_photo(pano, cam) * np.float32(2.0 ** kind.stops)
    return DemoScene(gt, ldr, alpha, photo, cam, (tuple(float(x) for x in capture),))
