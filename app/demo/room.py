"""The built-in demo scene: a procedural "toy room" whose ground-truth HDR radiance is known.

Geometry is a set of rectangles (quads): the room box (4 x 2.8 x 4 m, x and z in [-2, 2], floor at
y = 0), a few boxes on the floor, a bright ceiling light and a bright window. Ground truth is an
*analytic* assignment, not a radiosity bake: each non-emitting point gets

    L = albedo(p) / pi * (E_direct(p) + E_ambient)

where E_direct is the irradiance from the two area lights, integrated with a fixed stratified set
of light samples and exact shadows from the boxes (ray-box slab tests), and E_ambient is a constant
standing in for the indirect bounces. Emitters carry their radiance. Albedo is textured (tiles,
stripes, panels) so that image matching has features to lock onto.

Everything is seeded and deterministic. The same shading function colours the point cloud and the
ray-cast HDR photo, so the photo and the cloud agree exactly where they see the same surface.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.camera import Camera
from app.cloud import PointCloud
from app.color import luminance, srgb_to_linear, to_uint8_srgb

ROOM_MIN = np.array([-2.0, 0.0, -2.0])
ROOM_MAX = np.array([2.0, 2.8, 2.0])
AMBIENT_IRRADIANCE = 0.35
_EPS = 1e-4


@dataclass(frozen=True)
class Quad:
    """A rectangle origin + a*u + b*v, a, b in [0, 1]; ``normal`` faces the visible side."""

    origin: tuple
    u: tuple
    v: tuple
    normal: tuple
    albedo: tuple = (0.0, 0.0, 0.0)
    emission: tuple = (0.0, 0.0, 0.0)
    pattern: str = "plain"

    @property
    def area(self) -> float:
        return float(np.linalg.norm(np.cross(self.u, self.v)))


def _box_quads(lo, hi, albedo, pattern="plain", outward=True, skip_bottom=True) -> list[Quad]:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    d = hi - lo
    s = 1.0 if outward else -1.0
    x, y, z = np.diag(d)
    quads = [
        Quad(tuple(lo), tuple(z), tuple(y), (-s, 0, 0), albedo, pattern=pattern),          # -x
        Quad(tuple(lo + x), tuple(y), tuple(z), (s, 0, 0), albedo, pattern=pattern),      # +x
        Quad(tuple(lo), tuple(x), tuple(z), (0, -s, 0), albedo, pattern=pattern),          # -y
        Quad(tuple(lo + y), tuple(z), tuple(x), (0, s, 0), albedo, pattern=pattern),      # +y
        Quad(tuple(lo), tuple(y), tuple(x), (0, 0, -s), albedo, pattern=pattern),          # -z
        Quad(tuple(lo + z), tuple(x), tuple(y), (0, 0, s), albedo, pattern=pattern),      # +z
    ]
    if skip_bottom:
        del quads[2]
    return quads


BOXES = (  # (min, max, albedo): sit on the floor, clear of the object at the centre
    ((-1.8, 0.0, -1.7), (-1.0, 0.9, -0.9), (0.70, 0.45, 0.20)),
    ((1.0, 0.0, -1.8), (1.7, 0.6, -1.2), (0.25, 0.45, 0.70)),
    ((1.1, 0.0, 1.0), (1.6, 1.2, 1.5), (0.65, 0.65, 0.60)),
)
CEILING_LIGHT = Quad((-0.45, 2.8 - _EPS, -0.45), (0.9, 0, 0), (0, 0, 0.9), (0, -1, 0),
                     emission=(40.0, 36.0, 30.0))
WINDOW = Quad((-2.0 + _EPS, 0.9, -0.8), (0, 0, 1.4), (0, 1.2, 0), (1, 0, 0),
              emission=(9.0, 11.0, 14.0))
LIGHTS = (CEILING_LIGHT, WINDOW)


def scene_quads() -> list[Quad]:
    room = _box_quads(ROOM_MIN, ROOM_MAX, (0.0, 0.0, 0.0), outward=False, skip_bottom=False)
    walls = {  # index in _box_quads order -> (albedo, pattern)
        0: ((0.75, 0.72, 0.65), "panels"), 1: ((0.30, 0.55, 0.35), "stripes"),
        2: ((0.55, 0.42, 0.30), "tiles"), 3: ((0.85, 0.85, 0.82), "plain"),
        4: ((0.70, 0.30, 0.25), "stripes"), 5: ((0.60, 0.62, 0.70), "panels"),
    }
    quads = [Quad(q.origin, q.u, q.v, q.normal, walls[i][0], pattern=walls[i][1])
             for i, q in enumerate(room)]
    for lo, hi, alb in BOXES:
        quads += _box_quads(lo, hi, alb, pattern="tiles")
    return quads + list(LIGHTS)


def _pattern(name: str, a: np.ndarray, b: np.ndarray, size_a: float, size_b: float) -> np.ndarray:
    """Albedo modulation in [0.75, 1.15] from quad-local metric coordinates."""
    x, y = a * size_a, b * size_b
    if name == "tiles":
        return np.where((np.floor(x / 0.4) + np.floor(y / 0.4)) % 2 == 0, 1.1, 0.8)
    if name == "stripes":
        return 0.95 + 0.2 * (np.sin(x * 2 * np.pi / 0.5) > 0.6)
    if name == "panels":
        return np.where((np.abs(((x / 0.8) % 1) - 0.5) > 0.45) | (np.abs(((y / 0.7) % 1) - 0.5) > 0.45),
                        0.75, 1.0 + 0.1 * np.sin(3.0 * x) * np.sin(2.0 * y))
    return np.ones_like(a)


def _segment_blocked(p: np.ndarray, s: np.ndarray) -> np.ndarray:
    """True where the segment p -> s passes through a box (slab test)."""
    d = s - p
    blocked = np.zeros(len(p), dtype=bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / np.where(np.abs(d) < 1e-12, 1e-12, d)
        for lo, hi, _ in BOXES:
            t0 = (np.asarray(lo) - p) * inv
            t1 = (np.asarray(hi) - p) * inv
            tmin = np.minimum(t0, t1).max(axis=1)
            tmax = np.maximum(t0, t1).min(axis=1)
            blocked |= (tmax >= tmin) & (tmax > 1e-3) & (tmin < 1 - 1e-3)
    return blocked


def _light_samples(light: Quad, n: int) -> np.ndarray:
    k = int(np.sqrt(n))
    g = (np.arange(k) + 0.5) / k
    a, b = np.meshgrid(g, g, indexing="ij")
    return (np.asarray(light.origin) + a.reshape(-1, 1) * np.asarray(light.u)
            + b.reshape(-1, 1) * np.asarray(light.v))


def shade(points: np.ndarray, normals: np.ndarray, albedo: np.ndarray, shadows: bool = True,
          light_samples: int = 36, chunk: int = 65536) -> np.ndarray:
    """Ground-truth outgoing radiance of diffuse points (see the module docstring)."""
    out = np.empty((len(points), 3), dtype=np.float64)
    for start in range(0, len(points), chunk):
        p = points[start:start + chunk] + normals[start:start + chunk] * 1e-3
        n = normals[start:start + chunk]
        e = np.full((len(p), 3), AMBIENT_IRRADIANCE)
        for light in LIGHTS:
            dA = light.area / light_samples
            ln = np.asarray(light.normal)
            for s in _light_samples(light, light_samples):
                w = s - p
                d2 = np.einsum("ij,ij->i", w, w)
                wn = w / np.sqrt(d2)[:, None]
                g = np.clip(wn @ n.T if False else np.einsum("ij,ij->i", wn, n), 0, None) \
                    * np.clip(-(wn @ ln), 0, None) / d2
                if shadows:
                    g = np.where(_segment_blocked(p, np.broadcast_to(s, p.shape)), 0.0, g)
                e += g[:, None] * dA * np.asarray(light.emission)
        out[start:start + chunk] = albedo[start:start + chunk] / np.pi * e
    return out


def _surface_radiance(quad_ids, a, b, points, normals, quads, shadows=True) -> np.ndarray:
    albedo = np.zeros((len(points), 3))
    emission = np.zeros((len(points), 3))
    for i, q in enumerate(quads):
        m = quad_ids == i
        if not m.any():
            continue
        mod = _pattern(q.pattern, a[m], b[m], np.linalg.norm(q.u), np.linalg.norm(q.v))
        albedo[m] = np.clip(np.asarray(q.albedo) * mod[:, None], 0, 0.95)
        emission[m] = q.emission
    rad = shade(points, normals, albedo, shadows=shadows)
    lit = emission.any(axis=1)
    rad[lit] = emission[lit]
    return rad


def sample_room(n_points: int, seed: int = 0, shadows: bool = True) -> PointCloud:
    """``n_points`` area-uniform samples of the room with ground-truth HDR radiance (hdr=True)."""
    rng = np.random.default_rng(seed)
    quads = scene_quads()
    # Emitters are drawn on top of their wall/ceiling: sample walls, then replace points inside
    # the light rectangles by the emitter (same surface, just brighter).
    surf = [q for q in quads if not any(q.emission)]
    areas = np.array([q.area for q in surf])
    counts = rng.multinomial(n_points, areas / areas.sum())
    ids = np.repeat(np.arange(len(surf)), counts)
    a, b = rng.random(n_points), rng.random(n_points)
    O = np.array([q.origin for q in surf])[ids]
    U = np.array([q.u for q in surf])[ids]
    V = np.array([q.v for q in surf])[ids]
    N = np.array([q.normal for q in surf], dtype=np.float64)[ids]
    P = O + a[:, None] * U + b[:, None] * V
    all_ids = np.array([quads.index(q) for q in surf])[ids]
    for light in LIGHTS:  # points of the wall/ceiling that lie inside a light become emitter points
        lo = np.minimum(np.asarray(light.origin), np.asarray(light.origin) + np.asarray(light.u) + np.asarray(light.v)) - 2e-3
        hi = np.maximum(np.asarray(light.origin), np.asarray(light.origin) + np.asarray(light.u) + np.asarray(light.v)) + 2e-3
        inside = np.all((P >= lo) & (P <= hi), axis=1) & (N @ np.asarray(light.normal) > 0.5)
        all_ids[inside] = quads.index(light)
    colors = _surface_radiance(all_ids, a, b, P, N, quads, shadows=shadows)
    return PointCloud(P, N.astype(np.float32), colors.astype(np.float32), hdr=True,
                      source="demo:room")


def room_cloud(n_points: int, seed: int = 0) -> PointCloud:
    """A synthetic room of any size for benchmarks (no box shadows: O(n) and fast)."""
    return sample_room(n_points, seed, shadows=n_points <= 400_000)


def ray_cast(origin: np.ndarray, dirs: np.ndarray, quads=None):
    """Nearest quad hit per ray: (t, quad_id, a, b); quad_id = -1 where nothing is hit."""
    quads = scene_quads() if quads is None else quads
    n = len(dirs)
    best_t = np.full(n, np.inf)
    best_id = np.full(n, -1)
    best_a = np.zeros(n)
    best_b = np.zeros(n)
    for i, q in enumerate(quads):
        o, u, v, nn = (np.asarray(x, float) for x in (q.origin, q.u, q.v, q.normal))
        denom = dirs @ nn
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((o - origin) @ nn) / denom
        ok = (denom < -1e-9) & (t > 1e-6) & (t < best_t)  # front faces only
        p = origin + t[:, None] * dirs
        a = (p - o) @ u / (u @ u)
        b = (p - o) @ v / (v @ v)
        # emitters sit 0.1 mm in front of their wall: let them win ties
        ok &= (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)
        best_t = np.where(ok, t, best_t)
        best_id = np.where(ok, i, best_id)
        best_a = np.where(ok, a, best_a)
        best_b = np.where(ok, b, best_b)
    return best_t, best_id, best_a, best_b


def render_photo(camera: Camera) -> np.ndarray:
    """The ground-truth HDR image (linear float32, (H, W, 3)) seen by ``camera``: ray cast, exact."""
    quads = scene_quads()
    origin, dirs = camera.pixel_rays()
    d = dirs.reshape(-1, 3)
    t, ids, a, b = ray_cast(origin, d, quads)
    hit = ids >= 0
    P = origin + t[:, None] * d
    N = np.array([q.normal for q in quads], dtype=np.float64)[np.maximum(ids, 0)]
    img = np.zeros((len(d), 3))
    img[hit] = _surface_radiance(ids[hit], a[hit], b[hit], P[hit], N[hit], quads)
    return img.reshape(camera.height, camera.width, 3).astype(np.float32)


def ldr_scan(gt: PointCloud, alpha: float) -> PointCloud:
    """What an LDR scanner stores: clamp(alpha * HDR, 0, 1), sRGB-encoded to 8 bit, then decoded."""
    colors = srgb_to_linear(to_uint8_srgb(np.clip(alpha * gt.colors, 0, 1)) / 255.0)
    return PointCloud(gt.positions, gt.normals, colors, hdr=False, source="demo:ldr-scan")


def scan_exposure(gt: PointCloud) -> float:
    """The scanner's auto-exposure: the 98th percentile of non-emitter luminance maps to 0.85."""
    y = luminance(gt.colors)
    return float(0.85 / np.percentile(y[y < 5.0], 98))


# ---------------------------------------------------------------------------------------------
# The demo scene as a whole: clouds, photo, object and views.

OBJECT_CENTRE = (0.0, 0.6, 0.0)
PHOTO_CAMERA = Camera((1.2, 1.5, 1.6), (-1.5, 1.6, -1.0), fov_y_deg=70, width=512, height=384)
CAPTURE_POSITIONS = ((0.5, 1.4, 0.8),)


def default_views(width: int = 128, height: int = 128) -> dict[str, Camera]:
    """'closeup' (the object fills the view) and 'whole' (object and its surroundings)."""
    c = np.asarray(OBJECT_CENTRE)
    return {
        "closeup": Camera(c + (0.0, 0.12, 1.05), c, fov_y_deg=45, width=width, height=height),
        "whole": Camera(c + (0.6, 0.7, 1.9), c, fov_y_deg=50, width=width, height=height),
    }


def overview_camera(width: int = 128, height: int = 128) -> Camera:
    """The room from a top corner: the ceiling light, the window and the boxes in one view,
    so the demo's LDR / HDR / difference images show where the scan clipped (paper Fig. 1)."""
    return Camera(np.array([1.8, 2.0, 1.8]), np.array([-1.2, 1.3, -0.6]), fov_y_deg=70,
                  width=width, height=height)


def default_object(kind: str = "sphere") -> dict:
    """Object JSON (see README): the sphere, or the procedural non-convex asset ("knot")."""
    return {"mesh": kind, "translate": list(OBJECT_CENTRE), "scale": 0.8}


@dataclass
class DemoScene:
    gt: PointCloud            # ground-truth HDR radiance per point
    ldr: PointCloud           # the clipped 8-bit scan of the same points (hdr=False, linear)
    alpha: float              # exposure the scanner used: ldr = clamp(alpha * gt)
    photo: np.ndarray         # HDR photo (linear, scale of gt) from photo_camera
    photo_camera: Camera      # unknown to the scan/expansion: only for evaluation
    capture_positions: tuple  # default capture camera positions for HDR expansion


def build_demo(n_points: int = 200_000, seed: int = 0) -> DemoScene:
    gt = sample_room(n_points, seed)
    alpha = scan_exposure(gt)
    return DemoScene(gt, ldr_scan(gt, alpha), alpha, render_photo(PHOTO_CAMERA), PHOTO_CAMERA,
                     CAPTURE_POSITIONS)
