"""Photometric alignment of the photo to the scan: the camera that makes the photo and the scan agree.

Two steps, both on log luminance (an exposure is a constant offset there):
- ``coarse_search``: every candidate view direction (a Fibonacci sphere), roll and field of view,
  from the capture position, scored by the zero-normalised cross-correlation of a thumbnail of the
  photo with the capture's panorama (the cube-map renderings resampled to equirectangular) seen
  through that candidate camera. Cheap because both images are tiny; it finds the basin. The
  best distinct candidates are then polished on finer grids around them (``polish_candidates``):
  a narrow photo's basin is narrower than the grid.
- ``refine``: from a start camera, minimise over rotation, field of view and position the robust
  spread of log(Y_scan) - log(Y_photo) at sample points of the scan (projected into the photo,
  back-facing points skipped, saturated scan points left out), at increasing photo resolution.
  Slope one in log space: the scan is the photo times one exposure, which is why the median offset
  at the optimum is the exposure itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter

from app.camera import Camera
from app.color import luminance

EQ_W, EQ_H = 256, 128        # the capture panorama the coarse search samples
THUMB = 28                   # photo thumbnail, pixels on the long side
N_DIRECTIONS = 500           # candidate view directions (about 9 degrees apart)
ROLLS = tuple(range(-40, 41, 10))
FOVS = tuple(range(30, 121, 10))
CHUNK = 512                  # candidates per vectorised block (bounded memory, GIL released often)
POLISH = 32                  # distinct coarse candidates polished on a finer grid (polish_candidates)
POLISH_STEPS = ((4.0, 5.0), (2.0, 2.5), (1.0, 1.25))   # (degrees of rotation, of fov) per round
TRUNCATE = 0.7               # log-residual beyond which a point counts as an outlier (~2x)


def log_lum(rgb: np.ndarray) -> np.ndarray:
    return np.log(np.maximum(luminance(rgb), 1e-4)).astype(np.float32)


def resize(img: np.ndarray, long_side: int) -> np.ndarray:
    import cv2
    h, w = img.shape[:2]
    f = long_side / max(h, w)
    if f >= 1.0:
        return img
    return cv2.resize(img, (max(2, round(w * f)), max(2, round(h * f))),
                      interpolation=cv2.INTER_AREA)


def capture_panorama(faces, position) -> tuple[np.ndarray, np.ndarray]:
    """(log luminance, valid) of the capture's faces resampled to EQ_W x EQ_H equirectangular
    (longitude 0 = -z, as app.bench.panorama_rooms; here only a lookup table, any convention
    consistent with ``directions_to_eq`` would do)."""
    from app.hdr.capture import project
    j, i = np.meshgrid(np.arange(EQ_W), np.arange(EQ_H))
    lon = ((j + 0.5) / EQ_W - 0.5) * 2 * np.pi
    lat = (0.5 - (i + 0.5) / EQ_H) * np.pi
    d = np.stack([np.cos(lat) * np.sin(lon), np.sin(lat), -np.cos(lat) * np.cos(lon)], -1)
    d = d.reshape(-1, 3)
    out = np.zeros(len(d), np.float32)
    valid = np.zeros(len(d), bool)
    pos = np.asarray(position, dtype=np.float64)
    for face in faces:
        if np.linalg.norm(face.camera.position - pos) > 1e-6:
            continue
        u, v, z = project(face.camera, pos + d)
        h, w = face.depth.shape
        inside = (z > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h) & ~valid
        iu, iv = u[inside].astype(int), v[inside].astype(int)
        ok = np.isfinite(face.depth[iv, iu])
        idx = np.flatnonzero(inside)[ok]
        out[idx] = log_lum(face.color[iv[ok], iu[ok]])
        valid[idx] = True
    return out.reshape(EQ_H, EQ_W), valid.reshape(EQ_H, EQ_W)


def directions_to_eq(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lon = np.arctan2(d[..., 0], -d[..., 2])
    lat = np.arcsin(np.clip(d[..., 1], -1, 1))
    j = ((lon / (2 * np.pi) + 0.5) * EQ_W).astype(np.int64) % EQ_W
    i = np.clip(((0.5 - lat / np.pi) * EQ_H).astype(np.int64), 0, EQ_H - 1)
    return i, j


def _ranks(img: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Each valid pixel's quantile among the valid pixels (ties share the mean rank)."""
    from scipy.stats import rankdata
    out = np.zeros(img.shape, np.float32)
    v = img[valid]
    if len(v):
        out[valid] = (rankdata(v) / len(v)).astype(np.float32)
    return out


def fibonacci_sphere(n: int) -> np.ndarray:
    k = np.arange(n) + 0.5
    y = 1 - 2 * k / n
    r = np.sqrt(1 - y * y)
    phi = np.pi * (3 - np.sqrt(5)) * k
    return np.stack([r * np.cos(phi), y, r * np.sin(phi)], -1)


def camera_bases(forwards: np.ndarray, rolls_deg) -> np.ndarray:
    """Rows (right, up, forward) of cameras looking along each of ``forwards`` (N, 3), rolled
    about it by each of ``rolls_deg``: (N * len(rolls), 3, 3), rolls varying fastest. One array
    expression: a Python loop over thousands of candidates would hold the GIL in the job's
    thread and stall the window that owns it."""
    f = forwards / np.linalg.norm(forwards, axis=1, keepdims=True)
    ref = np.where(np.abs(f[:, 1:2]) < 0.99, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    r = np.cross(f, ref)
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    u = np.cross(r, f)
    a = np.radians(np.asarray(rolls_deg, dtype=np.float64))[None, :, None]       # (1, R, 1)
    r, u, f = r[:, None], u[:, None], np.broadcast_to(f[:, None], (len(f), a.shape[1], 3))
    rr, uu = np.cos(a) * r - np.sin(a) * u, np.sin(a) * r + np.cos(a) * u
    return np.stack([rr, uu, f], axis=2).reshape(-1, 3, 3)


@dataclass
class Candidate:
    basis: np.ndarray      # rows right, up, forward
    fov: float             # vertical, degrees
    score: float           # ZNCC (coarse) or -cost (refined)
    position: np.ndarray


def _pixel_dirs(w: int, h: int, fov: float) -> np.ndarray:
    """Camera-space (x right, y up, z forward) rays through the pixel centres."""
    t = np.tan(np.radians(fov) / 2)
    xs = ((np.arange(w) + 0.5) / w * 2 - 1) * t * (w / h)
    ys = (1 - (np.arange(h) + 0.5) / h * 2) * t
    x, y = np.meshgrid(xs, ys)
    return np.stack([x, y, np.ones_like(x)], -1).reshape(-1, 3)


def _zncc(eq, valid, p, world) -> np.ndarray:
    """ZNCC of the photo thumbnail ``p`` with the panorama along each candidate's rays, over the
    rays that hit a valid panorama pixel (-1 where fewer than 80% do, or either side is flat)."""
    i, j = directions_to_eq(world)
    ok = valid[i, j]
    n = ok.sum(1)
    okf = ok.astype(np.float32)
    vals = eq[i, j] * okf
    pm = okf * p[None]
    nn = np.maximum(n, 1).astype(np.float64)
    sv, sp = vals.sum(1, dtype=np.float64), pm.sum(1, dtype=np.float64)
    num = (vals * pm).sum(1, dtype=np.float64) - sv * sp / nn
    vv = (vals * vals).sum(1, dtype=np.float64) - sv * sv / nn
    pp = (pm * pm).sum(1, dtype=np.float64) - sp * sp / nn
    # ranks are in [0, 1]: a spread below 1e-3 per pixel is a flat window (a clipped plateau)
    flat = (vv < 1e-3 * nn) | (pp < 1e-3 * nn)
    z = num / np.sqrt(np.maximum(vv, 1e-12) * np.maximum(pp, 1e-12))
    return np.where((n > 0.8 * len(p)) & ~flat, z, -1.0)


def coarse_search(photo_rgb: np.ndarray, faces, position, top: int = 6, check=None) -> list[Candidate]:
    """The ``top`` best candidate cameras at the capture position, best first."""
    eq, valid = capture_panorama(faces, position)
    # ranks, not values: the scan is clipped where the photo is not, a monotone difference that
    # a rank transform removes (a Spearman-like correlation)
    eq = _ranks(eq, valid)
    thumb = resize(log_lum(photo_rgb), THUMB)
    thumb = _ranks(thumb, np.ones(thumb.shape, bool))
    th, tw = thumb.shape
    p = thumb.ravel().astype(np.float32)
    p = p - p.mean()
    dirs = fibonacci_sphere(N_DIRECTIONS)
    bases = camera_bases(dirs, ROLLS)                                     # (D*R, 3, 3)
    results = []
    for fov in FOVS:
        cam_d = _pixel_dirs(tw, th, fov).astype(np.float32)                # (P, 3)
        for b0 in range(0, len(bases), CHUNK):
            if check is not None:
                check()
            part = bases[b0:b0 + CHUNK].astype(np.float32)
            z = _zncc(eq, valid, p, np.matmul(cam_d[None], part))           # (B, P, 3) rays
            for b in np.argsort(-z)[:top]:
                results.append(Candidate(bases[b0 + b], float(fov), float(z[b]),
                                         np.asarray(position, dtype=np.float64)))
    polished = polish_candidates(_distinct(results, POLISH), eq, valid, p, tw, th, check)
    return _distinct(polished, top)


def _distinct(cands: list[Candidate], top: int) -> list[Candidate]:
    """The best ``top`` of ``cands`` whose forward directions lie at least 5 degrees apart (or
    whose fields of view differ by more than 15), best first."""
    out = []
    for c in sorted(cands, key=lambda c: -c.score):
        if all(np.dot(c.basis[2], o.basis[2]) < np.cos(np.radians(5)) or abs(c.fov - o.fov) > 15
               for o in out):
            out.append(c)
        if len(out) == top:
            break
    return out


def _turns(step_deg: float) -> np.ndarray:
    """(27, 3, 3) rotations by -step, 0, +step degrees about each camera axis (x, y, z), in
    the camera's own frame: pitch, yaw and roll."""
    a = np.radians(step_deg) * np.array([-1.0, 0.0, 1.0])
    c, s = np.cos(a), np.sin(a)
    one, zero = np.ones(3), np.zeros(3)
    rx = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, c, -s], -1),
                   np.stack([zero, s, c], -1)], 1)
    ry = np.stack([np.stack([c, zero, s], -1), np.stack([zero, one, zero], -1),
                   np.stack([-s, zero, c], -1)], 1)
    rz = np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1),
                   np.stack([zero, zero, one], -1)], 1)
    return np.einsum("aij,bjk,ckl->abcil", rx, ry, rz).reshape(27, 3, 3)


def polish_candidates(cands: list[Candidate], eq, valid, p, tw: int, th: int,
                      check=None) -> list[Candidate]:
    """Each candidate moved to the best ZNCC on finer grids around it: per round of
    POLISH_STEPS, the 27 turns of -s, 0, +s about its three axes times fov - d, fov, fov + d,
    kept when better. Why: the coarse grid is 9 degrees, 10 degrees of roll and 10 of fov
    apart, and a narrow photo's score falls off faster than that - a 40-degree photo of the
    demo room scored 0.93 at its true camera, 0.77 at the nearest grid point (20th of 45,000),
    so the screening never saw it; polishing the best distinct ones finds it (0.96)."""
    out = []
    fovs_cache = {}
    for c in cands:
        basis, fov, score = np.asarray(c.basis, np.float64), float(c.fov), float(c.score)
        for rot, dfov in POLISH_STEPS:
            if check is not None:
                check()
            bases = np.einsum("tij,jk->tik", _turns(rot), basis)          # (27, 3, 3)
            best = (score, basis, fov)
            for f in (fov - dfov, fov, fov + dfov):
                if not 10.0 <= f <= 150.0:
                    continue
                key = round(f, 4)
                if key not in fovs_cache:
                    fovs_cache[key] = _pixel_dirs(tw, th, f).astype(np.float32)
                z = _zncc(eq, valid, p, np.matmul(fovs_cache[key][None],
                                                  bases.astype(np.float32)))
                k = int(np.argmax(z))
                if z[k] > best[0]:
                    best = (float(z[k]), bases[k], f)
            score, basis, fov = best
        out.append(Candidate(basis, fov, score, c.position))
    return out


def _rot(rv: np.ndarray) -> np.ndarray:
    import cv2
    return cv2.Rodrigues(np.asarray(rv, dtype=np.float64))[0]


class PointScore:
    """Robust disagreement of the photo and the scan at sample points, for one camera."""

    def __init__(self, photo_rgb, positions, normals, ldr_rgb, tl: float, samples: int = 30_000,
                 seed: int = 0):
        rng = np.random.default_rng(seed)
        y = luminance(ldr_rgb)
        ok = np.flatnonzero((y > 0.01) & (y < tl))
        pick = rng.choice(ok, min(samples, len(ok)), replace=False) if len(ok) else ok
        self.p, self.n = positions[pick], normals[pick].astype(np.float64)
        self.logy = np.log(y[pick]).astype(np.float64)
        self.full = log_lum(photo_rgb)
        self.shape = photo_rgb.shape[:2]
        self.set_resolution(64)

    def set_resolution(self, long_side: int) -> None:
        img = resize(self.full, long_side)
        self.img = gaussian_filter(img, 0.7).astype(np.float64)
        self.scale = img.shape[0] / self.shape[0]

    def residuals(self, basis, fov, position) -> np.ndarray:
        """log(Y_scan) - log(Y_photo) at the sample points the camera sees."""
        return self._residuals(basis, fov, position)

    def pairs(self, basis, fov, position) -> tuple[np.ndarray, np.ndarray]:
        """(log Y_scan, log Y_photo) at the sample points the camera sees."""
        r, ok = self._residuals(basis, fov, position, keep=True)
        logy = self.logy[ok]
        return logy, logy - r

    def _residuals(self, basis, fov, position, keep: bool = False):
        h, w = self.img.shape
        d = self.p - position
        front = np.einsum("ij,ij->i", self.n, -d) > 0
        c = d @ basis.T
        z = c[:, 2]
        t = np.tan(np.radians(fov) / 2)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = (c[:, 0] / (z * t * (w / h)) + 1) * 0.5 * w - 0.5
            v = (1 - c[:, 1] / (z * t)) * 0.5 * h - 0.5
        ok = front & (z > 1e-3) & (u >= 0) & (u <= w - 1) & (v >= 0) & (v <= h - 1)
        u, v = u[ok], v[ok]
        x0 = np.minimum(u.astype(int), w - 2)
        y0 = np.minimum(v.astype(int), h - 2)
        fx, fy = u - x0, v - y0
        im = self.img
        val = ((im[y0, x0] * (1 - fx) + im[y0, x0 + 1] * fx) * (1 - fy)
               + (im[y0 + 1, x0] * (1 - fx) + im[y0 + 1, x0 + 1] * fx) * fy)
        return (self.logy[ok] - val, ok) if keep else self.logy[ok] - val

    def cost(self, basis, fov, position) -> tuple[float, int, float]:
        """(truncated mean squared deviation from the median, points, median offset)."""
        r = self.residuals(basis, fov, position)
        if len(r) < 200:
            return TRUNCATE ** 2, len(r), float("nan")
        m = float(np.median(r))
        e = np.minimum((r - m) ** 2, TRUNCATE ** 2)
        return float(e.mean()), len(r), m


def refine(score: PointScore, start: Candidate, move: bool, check=None,
           resolutions=(48, 96, 192, 384)) -> Candidate:
    """Local minimisation of score.cost over rotation and field of view (and position when
    ``move``), coarse to fine in the photo's resolution."""
    from scipy.optimize import minimize
    cur = start
    for res in resolutions:
        if check is not None:
            check()
        score.set_resolution(res)
        b0, p0 = cur.basis, cur.position

        def unpack(x):
            basis = b0 @ _rot(x[:3]).T
            fov = float(np.degrees(2 * np.arctan(np.exp(x[3]) * np.tan(np.radians(cur.fov) / 2))))
            pos = p0 + (x[4:7] if move else 0.0)
            return basis, fov, pos

        def f(x):
            basis, fov, pos = unpack(x)
            if not 5.0 < fov < 150.0:
                return 10.0
            return score.cost(basis, fov, pos)[0]

        n = 7 if move else 4
        step = 2.0 / res
        simplex = np.zeros((n + 1, n))
        for k in range(n):
            simplex[k + 1, k] = step if k < 4 else 0.05
        r = minimize(f, np.zeros(n), method="Nelder-Mead",
                     options={"initial_simplex": simplex, "xatol": 1e-4, "fatol": 1e-6,
                              "maxfev": 400 if move else 250})
        basis, fov, pos = unpack(r.x)
        cur = Candidate(basis, fov, -float(r.fun), pos)
    return cur


def to_camera(c: Candidate, w: int, h: int) -> Camera:
    return Camera(c.position, c.position + c.basis[2], c.basis[1], c.fov, int(w), int(h))
