"""An HDRI (an equirectangular EXR panorama) as the asset's light: the reference artists know,
beside the scan's light, with the same BRDF and gather as every mode.

The panorama becomes the environment map's six cube faces (app/pbgi/envmap.py) instead of the
cloud's splats seen from the asset's centre, and the environment-map mode gathers it: an HDRI is
distant light by definition, so the environment map is exact for it (no parallax to miss). Each
face texel is the mean of k x k bilinear lookups inside it, k chosen so that a texel averages
the panorama pixels it covers: a small bright source (a sun) keeps its energy instead of being
hit or missed by one lookup. Conventions (up, centre column, rotation): app/render/equirect.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from app.camera import Camera, cube_cameras
from app.errors import ScanlightError
from app.render.equirect import sample_panorama

ROWS_PER_CHUNK = 256


@dataclass(frozen=True, eq=False)
class Hdri:
    """rgb: (H, W, 3) float32 linear radiance, finite and >= 0; rotation about +y in degrees."""

    rgb: np.ndarray
    rotation_deg: float = 0.0
    source: str | None = None
    key: tuple = field(default=(), compare=False)

    def rotated(self, deg: float) -> "Hdri":
        return Hdri(self.rgb, float(deg), self.source, (self.key[0], float(deg)))


def make_hdri(rgb: np.ndarray, rotation_deg: float = 0.0, source=None) -> Hdri:
    """Checks an equirectangular image (twice as wide as high, within a pixel; some light)."""
    rgb = np.asarray(rgb, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] < 3:
        raise ScanlightError(source, f"an HDRI needs an RGB image, got shape {rgb.shape}")
    h, w = rgb.shape[:2]
    if h < 2 or abs(w - 2 * h) > 1:
        raise ScanlightError(source, f"an HDRI must be an equirectangular panorama, twice as wide "
                                     f"as high; this one is {w}x{h}")
    rgb = np.ascontiguousarray(rgb[..., :3])
    if not np.isfinite(rgb).all() or (rgb < 0).any():
        raise ScanlightError(source, "the HDRI has NaN, Inf or negative pixels")
    if not (rgb > 0).any():
        raise ScanlightError(source, "the HDRI is black everywhere: it would light nothing")
    if not np.isfinite(rotation_deg):
        raise ScanlightError(source, f"HDRI rotation must be finite, got {rotation_deg}")
    return Hdri(rgb, float(rotation_deg), None if source is None else str(source),
                (id(rgb), float(rotation_deg)))


def load_hdri(path, rotation_deg: float = 0.0) -> Hdri:
    """An equirectangular EXR (app/io/exr.py repairs negative and non-finite pixels, logged)."""
    from app.io.exr import read_exr
    img = read_exr(path)
    return make_hdri(img.rgb, rotation_deg, Path(path))


def _texel_of(d: np.ndarray, cams, face_size: int) -> tuple[np.ndarray, np.ndarray]:
    """(flat texel index over the six faces, row 0 at the top) of (N, 3) unit directions: the
    face whose forward axis is nearest, projected the way Camera.pixel_rays casts its rays."""
    bases = [cam.basis() for cam in cams]
    fwd = np.stack([f for _, _, f in bases])
    face = np.argmax(d @ fwd.T, axis=1)
    r = np.stack([b[0] for b in bases])[face]
    u = np.stack([b[1] for b in bases])[face]
    f = fwd[face]
    z = np.einsum("ij,ij->i", d, f)
    x = np.einsum("ij,ij->i", d, r) / z
    y = np.einsum("ij,ij->i", d, u) / z
    col = np.clip(((x + 1) * 0.5 * face_size).astype(np.int64), 0, face_size - 1)
    row = np.clip(((1 - y) * 0.5 * face_size).astype(np.int64), 0, face_size - 1)
    return (face * face_size + row) * face_size + col, face


def hdri_faces(hdri: Hdri, face_size: int) -> list[np.ndarray]:
    """The six (S, S, 3) cube faces in cube_cameras' order, row 0 at the top. Each texel is the
    solid-angle-weighted mean of the panorama pixels whose centres fall in it, so the faces hold
    the panorama's energy however small its sources; texels no pixel centre reached (a
    panorama coarser than the faces) take the bilinear lookup of their centre direction."""
    s = int(face_size)
    cams = cube_cameras(np.zeros(3), s)
    h, w = hdri.rgb.shape[:2]
    n = 6 * s * s
    acc, wsum = np.zeros((n, 3)), np.zeros(n)
    lon = ((np.arange(w) + 0.5) / w - 0.5) * 2 * np.pi
    c, sn = np.cos(np.radians(hdri.rotation_deg)), np.sin(np.radians(hdri.rotation_deg))
    for r0 in range(0, h, ROWS_PER_CHUNK):
        lat = (0.5 - (np.arange(r0, min(h, r0 + ROWS_PER_CHUNK)) + 0.5) / h) * np.pi
        la, lo = np.meshgrid(lat, lon, indexing="ij")
        d = np.stack([np.cos(la) * np.sin(lo), np.sin(la), -np.cos(la) * np.cos(lo)],
                     axis=-1).reshape(-1, 3)
        # the pixel that was at d now lights from R(rotation) d (app/render/equirect.py)
        d = np.stack([c * d[:, 0] + sn * d[:, 2], d[:, 1], -sn * d[:, 0] + c * d[:, 2]], axis=1)
        omega = np.repeat((2 * np.pi / w) * (np.pi / h) * np.cos(lat), w)
        idx, _ = _texel_of(d, cams, s)
        wsum += np.bincount(idx, omega, n)
        rgb = hdri.rgb[r0:r0 + len(lat)].reshape(-1, 3).astype(np.float64)
        for ch in range(3):
            acc[:, ch] += np.bincount(idx, rgb[:, ch] * omega, n)
    out = acc / np.maximum(wsum, 1e-300)[:, None]
    empty = wsum <= 0
    if empty.any():
        rays = np.concatenate([cam.pixel_rays()[1].reshape(-1, 3) for cam in cams])
        out[empty] = sample_panorama(hdri.rgb, rays[empty], hdri.rotation_deg)
    return [f.astype(np.float32) for f in out.reshape(6, s, s, 3)]


def hdri_backdrop(hdri: Hdri, camera: Camera) -> np.ndarray:
    """The panorama seen by ``camera`` (its background at infinity), (h, w, 4), alpha 1."""
    _, rays = camera.pixel_rays()
    rgb = sample_panorama(hdri.rgb, rays.reshape(-1, 3), hdri.rotation_deg)
    out = np.ones((camera.height, camera.width, 4), np.float32)
    out[..., :3] = rgb.reshape(camera.height, camera.width, 3)
    return out


__all__ = ["Hdri", "make_hdri", "load_hdri", "hdri_faces", "hdri_backdrop"]
