"""Cube-map captures of the LDR cloud by point splatting, with depth (paper Section 4.1, "Capture").

The renderer is a numpy z-buffer splatter rather than GL: it is deterministic and needs no GL
context, so it runs in a worker thread or process beside the viewer. Each point
covers the pixels whose centres lie within its world radius projected to the face (a disc), so the
rendering has no holes where the cloud is dense enough; the colour of a pixel is the weighted mean
of the splats within a depth tolerance of the nearest one (a soft z-buffer), which anti-aliases
edges and keeps PatchMatch from matching splat noise. Each face keeps its camera (intrinsics and
extrinsics) and depth buffer so the expanded values can be projected back with a depth test.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from app.camera import CUBE_FACES, Camera, cube_cameras


@dataclass
class Face:
    """One rendering S_i: the camera it was taken with, its colours and its depth buffer."""

    name: str
    camera: Camera
    color: np.ndarray     # (H, W, 3) float32 linear LDR colour; 0 where nothing was splatted
    depth: np.ndarray     # (H, W) float32 view depth (along -z) of the nearest splat; inf if none
    covered: np.ndarray   # (H, W) bool: a splat (not hole filling) wrote the pixel
    depth_tol: float      # metres: a point this close behind the z-buffer still counts as visible
    _depth_min: np.ndarray | None = field(default=None, repr=False)

    def intrinsics(self) -> np.ndarray:
        """3x3 K in pixel units, row 0 at the top: (u, v) = (cx + fx*x/z, cy - fy*y/z)."""
        return intrinsics(self.camera)

    def extrinsics(self) -> np.ndarray:
        """4x4 world -> camera (the view matrix; the camera looks down -z)."""
        return self.camera.view()

    def project(self, points: np.ndarray):
        return project(self.camera, points)

    def visible(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(mask, u, v): points inside the face and not hidden behind the depth buffer.

        The test is against the nearest depth in the 3x3 pixels around the point: a gap between
        the splats of a near surface must not let the surface behind it count as seen."""
        u, v, z = project(self.camera, points)
        h, w = self.depth.shape
        inside = (z > 1e-6) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
        iu = np.clip(u, 0, w - 1).astype(np.int64)
        iv = np.clip(v, 0, h - 1).astype(np.int64)
        if self._depth_min is None:
            from scipy.ndimage import minimum_filter
            self._depth_min = minimum_filter(self.depth, size=3, mode="nearest")
        front = self._depth_min[iv, iu]
        mask = inside & (z <= front + self.depth_tol + 0.01 * front)
        return mask, u, v


@dataclass
class Capture:
    """The cube map taken at one capture position (six faces, OpenGL face order)."""

    position: np.ndarray
    faces: list[Face]
    report: dict = field(default_factory=dict)


def intrinsics(cam: Camera) -> np.ndarray:
    t = np.tan(np.radians(cam.fov_y_deg) / 2)
    fy = cam.height / (2 * t)
    fx = cam.width / (2 * t * cam.aspect)
    return np.array([[fx, 0, cam.width / 2], [0, fy, cam.height / 2], [0, 0, 1.0]])


def project(cam: Camera, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous pixel coordinates (u, v) (pixel i spans [i, i+1), row 0 at the top) and view
    depth z of world points; matches Camera.pixel_rays (pixel centres at i + 0.5)."""
    r, up, f = cam.basis()
    d = np.asarray(points, dtype=np.float64) - cam.position
    x, y, z = d @ r, d @ up, d @ f
    k = intrinsics(cam)
    with np.errstate(divide="ignore", invalid="ignore"):
        zs = np.where(z > 1e-9, z, np.nan)
        u = k[0, 2] + k[0, 0] * x / zs
        v = k[1, 2] - k[1, 1] * y / zs
    u = np.nan_to_num(u, nan=-1.0, posinf=-1.0, neginf=-1.0)
    v = np.nan_to_num(v, nan=-1.0, posinf=-1.0, neginf=-1.0)
    return u, v, z


def point_spacing(positions: np.ndarray, sample: int = 20_000, k: int = 8, seed: int = 0) -> float:
    """Typical distance between neighbouring points, 1/sqrt(surface density), from a subsample.

    The density of a random m-point subsample is m/N of the cloud's, so a small KD-tree gives the
    global figure in milliseconds instead of a k-NN query over the whole cloud.
    """
    n = len(positions)
    if n < 2:
        return 1.0
    m = min(n, sample)
    rng = np.random.default_rng(seed)
    sub = positions[rng.choice(n, m, replace=False)] if m < n else positions
    kk = min(k, m - 1)
    d, _ = cKDTree(sub).query(sub, kk + 1)
    rk = float(np.median(d[:, kk]))
    if not np.isfinite(rk) or rk <= 0:
        return 1.0
    density_sub = kk / (np.pi * rk * rk)
    return float(1.0 / np.sqrt(density_sub * n / m))


def _splat_offsets(rmax: float) -> list[tuple[int, int, float]]:
    """Pixel offsets around the containing pixel with the smallest possible centre distance."""
    rr = int(np.ceil(rmax + 0.5))
    out = []
    for dy in range(-rr, rr + 1):
        for dx in range(-rr, rr + 1):
            lb = np.hypot(max(abs(dx) - 0.5, 0.0), max(abs(dy) - 0.5, 0.0))
            if lb <= rmax:
                out.append((dx, dy, lb))
    out.sort(key=lambda o: o[2])
    return out


class _Splats:
    """Points projected to a face as discs, largest first, so that each pixel offset of the
    footprint touches a prefix of them (searchsorted instead of a mask over all points)."""

    def __init__(self, u, v, z, rpx, w, h, max_radius_px):
        order = np.argsort(-rpx, kind="stable")
        self.order = order
        self.u, self.v = u[order], v[order]
        self.z = z[order].astype(np.float32)
        self.r = np.clip(rpx[order], 0.5, max_radius_px)
        self.neg_r = -self.r  # ascending, for searchsorted
        self.iu = np.floor(self.u).astype(np.int64)
        self.iv = np.floor(self.v).astype(np.int64)
        self.w, self.h = w, h
        self.offsets = _splat_offsets(max_radius_px)

    def entries(self, dx, dy, lb):
        """(point indices, pixel indices, squared centre distances) of one footprint offset."""
        m = int(np.searchsorted(self.neg_r, -lb, side="right"))  # points with r >= lb
        if m == 0:
            return None
        px, py = self.iu[:m] + dx, self.iv[:m] + dy
        d2 = (px + 0.5 - self.u[:m]) ** 2 + (py + 0.5 - self.v[:m]) ** 2
        ok = (px >= 0) & (px < self.w) & (py >= 0) & (py < self.h)
        if dx or dy:
            ok &= d2 <= self.r[:m] ** 2
        sel = np.flatnonzero(ok)
        return sel, (py[sel] * self.w + px[sel]), d2[sel]

    def depth(self, cancel=None) -> np.ndarray:
        """Nearest splat depth per pixel (flat), inf where none."""
        depth = np.full(self.h * self.w, np.inf, dtype=np.float32)
        for j, (dx, dy, lb) in enumerate(self.offsets):
            if cancel is not None and j % 8 == 0:
                cancel()
            e = self.entries(dx, dy, lb)
            if e is not None:
                np.minimum.at(depth, e[1], self.z[e[0]])
        return depth


def splat_face(cam: Camera, positions: np.ndarray, normals: np.ndarray, colors: np.ndarray,
               radius: float, max_radius_px: float = 6.0, fill_iters: int = 4,
               cancel=None, name: str = "") -> tuple[Face, dict]:
    """Render the points seen by ``cam`` as depth-tested discs of world radius ``radius``.

    Back-facing points (normal away from the camera) are culled from the image; their own depth
    buffer measures how much of the view they would hide, which is how a camera behind a wall,
    inside an object or outside the room shows itself (``back_view_fraction``).
    """
    w, h = cam.width, cam.height
    u, v, z = project(cam, positions)
    near = 1e-3
    k = intrinsics(cam)
    rpx = radius * k[1, 1] / np.maximum(z, near)
    margin = max_radius_px + 1
    sel = (z > near) & (u > -margin) & (u < w + margin) & (v > -margin) & (v < h + margin)
    to_cam = cam.position - positions[sel]
    n = normals[sel].astype(np.float64)
    facing = np.einsum("ij,ij->i", n, to_cam)
    has_normal = np.abs(n).sum(axis=1) > 1e-6
    back = has_normal & (facing <= 0)
    stats = {"points_in_view": int(sel.sum()), "back_facing": int(back.sum())}
    sel_idx = np.flatnonzero(sel)
    bidx, idx = sel_idx[back], sel_idx[~back]
    depth_tol = np.float32(2.0 * radius)

    front = _Splats(u[idx], v[idx], z[idx], rpx[idx], w, h, max_radius_px)
    depth = front.depth(cancel)  # pass 1: nearest depth per pixel
    col = colors[idx][front.order]
    acc = np.zeros((h * w, 3))
    wsum = np.zeros(h * w)
    for j, (dx, dy, lb) in enumerate(front.offsets):  # pass 2: soft z-buffer colour
        if cancel is not None and j % 8 == 0:
            cancel()
        e = front.entries(dx, dy, lb)
        if e is None:
            continue
        s, pix, d2 = e
        keep = front.z[s] <= depth[pix] + depth_tol + 0.01 * depth[pix]
        s, pix, d2 = s[keep], pix[keep], d2[keep]
        wt = 1.0 / (1.0 + d2 / (front.r[s] ** 2))
        wsum += np.bincount(pix, wt, minlength=h * w)
        for c in range(3):
            acc[:, c] += np.bincount(pix, wt * col[s, c], minlength=h * w)
    covered = wsum > 0
    if len(bidx):
        depth_back = _Splats(u[bidx], v[bidx], z[bidx], rpx[bidx], w, h, max_radius_px).depth(cancel)
        seen_back = depth_back < depth - depth_tol
    else:
        seen_back = np.zeros(h * w, dtype=bool)
    stats["back_view_fraction"] = float(seen_back.sum() / max((covered | seen_back).sum(), 1))
    color = np.zeros((h * w, 3), dtype=np.float32)
    color[covered] = (acc[covered] / wsum[covered, None]).astype(np.float32)
    color = color.reshape(h, w, 3)
    depth = depth.reshape(h, w)
    covered = covered.reshape(h, w)
    color, depth = _fill_holes(color, depth, covered, fill_iters)
    stats["coverage"] = float(covered.mean())
    return Face(name, cam, color, depth, covered, float(depth_tol)), stats


def _fill_holes(color, depth, covered, iters):
    """Small holes (points sparser than pixels) take the mean of their filled 3x3 neighbours."""
    filled = covered.copy()
    color, depth = color.copy(), depth.copy()
    for _ in range(iters):
        if filled.all():
            break
        fp = np.pad(filled, 1).astype(np.float32)
        cp = np.pad(color * filled[..., None], ((1, 1), (1, 1), (0, 0)))
        dp = np.pad(np.where(filled, depth, np.inf), 1, constant_values=np.inf)
        h, w = filled.shape
        cnt = sum(fp[1 + a:1 + a + h, 1 + b:1 + b + w] for a in (-1, 0, 1) for b in (-1, 0, 1))
        csum = sum(cp[1 + a:1 + a + h, 1 + b:1 + b + w] for a in (-1, 0, 1) for b in (-1, 0, 1))
        dmin = np.min([dp[1 + a:1 + a + h, 1 + b:1 + b + w] for a in (-1, 0, 1) for b in (-1, 0, 1)],
                      axis=0)
        grow = ~filled & (cnt >= 3)
        if not grow.any():
            break
        color[grow] = csum[grow] / cnt[grow, None]
        depth[grow] = dmin[grow]
        filled |= grow
    return color, depth


def capture_cube(positions: np.ndarray, normals: np.ndarray, colors: np.ndarray, position,
                 face_size: int, radius: float | None = None, splat_scale: float = 1.0,
                 max_radius_px: float = 6.0, cancel=None, progress=None) -> Capture:
    """Six faces of ``face_size``^2 at ``position``; ``radius`` defaults to the point spacing."""
    if radius is None:
        radius = splat_scale * point_spacing(positions)
    faces, stats = [], []
    cams = cube_cameras(position, face_size)
    for i, ((name, _, _), cam) in enumerate(zip(CUBE_FACES, cams)):
        face, st = splat_face(cam, positions, normals, colors, radius, max_radius_px,
                              cancel=cancel, name=name)
        faces.append(face)
        stats.append(st)
        if progress is not None:
            progress((i + 1) / len(cams))
    n_view = sum(s["points_in_view"] for s in stats)
    n_back = sum(s["back_facing"] for s in stats)
    report = {"position": [float(x) for x in np.asarray(position)], "face_size": int(face_size),
              "splat_radius": float(radius), "coverage": float(np.mean([s["coverage"] for s in stats])),
              "back_facing_fraction": float(n_back / max(n_view, 1))}
    return Capture(np.asarray(position, dtype=np.float64), faces, report)
