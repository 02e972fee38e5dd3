"""Pinhole cameras: the JSON camera format and the matrices every renderer uses.

Conventions: right-handed, y up, metres; OpenGL clip space; the camera looks down its -z axis.
Matrices are float64 numpy arrays in row-major math form (``clip = P @ V @ world``); upload them
transposed (``.T``) or with ``.astype('f4').tobytes(order='F')`` for GLSL's column-major mat4.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.errors import ScanlightError
from app.io.limits import MAX_CAMERA_PIXELS, MAX_CAMERA_SIDE
from app.io.schema import Fields


@dataclass
class Camera:
    position: np.ndarray
    look_at: np.ndarray
    up: np.ndarray = None
    fov_y_deg: float = 45.0
    width: int = 128
    height: int = 128

    def __post_init__(self):
        self.position = np.asarray(self.position, dtype=np.float64).reshape(3)
        self.look_at = np.asarray(self.look_at, dtype=np.float64).reshape(3)
        self.up = np.asarray((0, 1, 0) if self.up is None else self.up, dtype=np.float64).reshape(3)
        self.width, self.height = int(self.width), int(self.height)

    @property
    def aspect(self) -> float:
        return self.width / self.height

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, true_up, forward) unit vectors in world space. ``up`` counts by its
        direction only (a short one, such as (0, 1e-10, 0), is as good as (0, 1, 0))."""
        f = self.look_at - self.position
        f = f / np.linalg.norm(f)
        n = float(np.linalg.norm(self.up))
        r = np.cross(f, self.up / n if n > 0.0 else self.up)
        if np.linalg.norm(r) < PARALLEL_SIN:  # looking along 'up': pick any perpendicular
            r = np.cross(f, [1.0, 0.0, 0.0] if abs(f[0]) < 0.9 else [0.0, 0.0, 1.0])
        r = r / np.linalg.norm(r)
        return r, np.cross(r, f), f

    def view(self) -> np.ndarray:
        r, u, f = self.basis()
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = r, u, -f
        m[:3, 3] = -m[:3, :3] @ self.position
        return m

    def projection(self, near: float, far: float) -> np.ndarray:
        t = 1.0 / np.tan(np.radians(self.fov_y_deg) / 2)
        m = np.zeros((4, 4))
        m[0, 0], m[1, 1] = t / self.aspect, t
        m[2, 2] = (far + near) / (near - far)
        m[2, 3] = 2 * far * near / (near - far)
        m[3, 2] = -1.0
        return m

    def pixel_rays(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit world-space ray directions through pixel centres, (H, W, 3), row 0 at the top."""
        r, u, f = self.basis()
        t = np.tan(np.radians(self.fov_y_deg) / 2)
        xs = ((np.arange(self.width) + 0.5) / self.width * 2 - 1) * t * self.aspect
        ys = (1 - (np.arange(self.height) + 0.5) / self.height * 2) * t
        d = f + xs[None, :, None] * r + ys[:, None, None] * u
        return self.position, d / np.linalg.norm(d, axis=-1, keepdims=True)

    def to_dict(self) -> dict:
        return {"position": self.position.tolist(), "look_at": self.look_at.tolist(),
                "up": self.up.tolist(), "fov_y_deg": float(self.fov_y_deg),
                "width": self.width, "height": self.height}


def parse_size(text, minimum: int = 1) -> tuple[int, int]:
    """A ``--size WxH`` argument as (width, height), or one usage-error line."""
    import re

    from app.errors import UsageError
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", str(text or ""))
    if not m:
        raise UsageError(None, f"--size must look like 640x480, got {text!r}")
    w, h = int(m.group(1)), int(m.group(2))
    if not (minimum <= w <= MAX_CAMERA_SIDE and minimum <= h <= MAX_CAMERA_SIDE):
        raise UsageError(None, f"--size must be between {minimum}x{minimum} and "
                               f"{MAX_CAMERA_SIDE}x{MAX_CAMERA_SIDE}, got {text!r}")
    return w, h


MAX_PIXELS = MAX_CAMERA_PIXELS   # re-exported: render --size and the viewer check against it
PARALLEL_SIN = 1e-9   # 'up' within this sine of the view is parallel to it (no roll defined)
CAMERA_KEYS = ("position", "look_at", "up", "fov_y_deg", "width", "height", "name")


def camera_from_dict(d: dict, source=None, what: str = "camera") -> Camera:
    """A camera from its JSON object, every field typed (app.io.schema) and limited
    (app.io.limits): positions within MAX_COORD, at most MAX_CAMERA_PIXELS pixels."""
    f = Fields(d, what, source, CAMERA_KEYS)
    pos, at = np.asarray(f.vec3("position")), np.asarray(f.vec3("look_at"))
    up = np.asarray(f.vec3("up", (0.0, 1.0, 0.0)))
    f.string("name", "")
    if np.linalg.norm(at - pos) < 1e-9:
        raise ScanlightError(source, f"{what} 'look_at' equals 'position'")
    fov = f.number("fov_y_deg", 45.0, 0.1, 179.0, "degrees")
    w = f.integer("width", 128, 1, MAX_CAMERA_SIDE)
    h = f.integer("height", 128, 1, MAX_CAMERA_SIDE)
    if w * h > MAX_PIXELS:
        raise ScanlightError(source, f"{what} image {w}x{h} is larger than the limit of "
                                     f"{MAX_PIXELS:,} pixels (8192x8192)")
    if not np.linalg.norm(up) > 0.0:
        raise ScanlightError(source, f"{what} 'up' is the zero vector (no direction)")
    up_dir = np.cross(at - pos, up)
    if np.linalg.norm(up_dir) < PARALLEL_SIN * np.linalg.norm(at - pos) * np.linalg.norm(up):
        raise ScanlightError(source, f"{what} 'up' is parallel to the viewing direction")
    return Camera(pos, at, up, float(fov), w, h)


def load_camera(path) -> Camera:
    from app.io.files import read_json
    return camera_from_dict(read_json(path, "camera"), str(path))


# The six faces of an axis-aligned cube map, in OpenGL order (+X, -X, +Y, -Y, +Z, -Z) with the
# OpenGL cube-map 'up' vectors, so face images can be uploaded to a cube texture as they are.
CUBE_FACES = (
    ("+x", (1, 0, 0), (0, -1, 0)), ("-x", (-1, 0, 0), (0, -1, 0)),
    ("+y", (0, 1, 0), (0, 0, 1)), ("-y", (0, -1, 0), (0, 0, -1)),
    ("+z", (0, 0, 1), (0, -1, 0)), ("-z", (0, 0, -1), (0, -1, 0)),
)


def cube_cameras(position, face_size: int) -> list[Camera]:
    """Six 90-degree cameras at ``position``, one per cube-map face."""
    pos = np.asarray(position, dtype=np.float64)
    return [Camera(pos, pos + np.asarray(d, float), up, 90.0, face_size, face_size)
            for _, d, up in CUBE_FACES]
