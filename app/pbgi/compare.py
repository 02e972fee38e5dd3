"""Relit-render error (paper Table 2 protocol): light the asset with each cloud, compare its
pixels with the render lit by the ground-truth cloud. Clouds are first brought to ground-truth
units (an expanded or LDR cloud is on the scan's alpha x radiance scale)."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter

from app.camera import Camera
from app.cloud import PointCloud
from app.color import luminance
from app.render.tonemap import tonemap


def framing_camera(mesh, room: PointCloud, size: int = 128) -> Camera:
    """A close-up of the asset from the side of the room's centre (inside the room)."""
    lo, hi = (np.asarray(b, float) for b in mesh.bounds())
    c, extent = 0.5 * (lo + hi), float(np.max(hi - lo))
    d = room.positions.mean(axis=0) - c
    d[1] = 0.0
    d = d / np.linalg.norm(d) if np.linalg.norm(d) > 1e-6 else np.array([0.0, 0.0, 1.0])
    pos = c + d * 1.3 * extent + np.array([0.0, 0.15 * extent, 0.0])
    return Camera(pos, c, fov_y_deg=45, width=size, height=size)


def ssim(a: np.ndarray, b: np.ndarray, sigma: float = 1.5) -> float:
    """Mean SSIM (Wang et al. 2004, Gaussian window) of two images in [0, 1]."""
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    mu_a, mu_b = gaussian_filter(a, sigma), gaussian_filter(b, sigma)
    va = gaussian_filter(a * a, sigma) - mu_a ** 2
    vb = gaussian_filter(b * b, sigma) - mu_b ** 2
    cov = gaussian_filter(a * b, sigma) - mu_a * mu_b
    s = ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / ((mu_a ** 2 + mu_b ** 2 + c1) * (va + vb + c2))
    return float(s.mean())


def scaled(cloud: PointCloud, scale: float) -> PointCloud:
    return PointCloud(cloud.positions, cloud.normals, cloud.colors / scale, hdr=True,
                      source=cloud.source)


def relit_errors(clouds: dict[str, PointCloud], gt: PointCloud, mesh, camera: Camera,
                 mode: str = "hybrid", microbuffer: int = 16, relighter=None) -> tuple[dict, dict]:
    """({name: {"render_rms", "render_rel_rms", "render_ssim"}}, {name: image}) for each cloud
    (already in ground-truth units) against the asset lit by ``gt``; object pixels only."""
    from app.pbgi.renderer import Relighter, RenderParams
    r = relighter or Relighter()
    r.set_asset(mesh)
    params = RenderParams(mode=mode, microbuffer=microbuffer)
    images = {}
    for name, cloud in [("gt", gt)] + list(clouds.items()):
        r.set_cloud(cloud)
        images[name] = r.render(camera, None, params).image
    ref = images["gt"]
    mask = ref[..., 3] > 0.5
    ref_y = np.clip(tonemap(ref[..., :3]), 0, 1)
    out = {}
    for name in clouds:
        img = images[name]
        diff = (img[..., :3] - ref[..., :3])[mask]
        rms = float(np.sqrt(np.mean(diff ** 2))) if mask.any() else float("nan")
        mean_ref = float(np.mean(ref[..., :3][mask])) if mask.any() else float("nan")
        ys, xs = np.nonzero(mask)
        box = (slice(ys.min(), ys.max() + 1), slice(xs.min(), xs.max() + 1)) if mask.any() else (slice(0), slice(0))
        a = luminance(np.clip(tonemap(img[..., :3]), 0, 1))[box]
        b = luminance(ref_y)[box]
        rel = rms / mean_ref if mean_ref > 1e-9 else None     # undefined without light
        out[name] = {"render_rms": rms, "render_rel_rms": rel,
                     "render_ssim": ssim(a, b) if a.size else float("nan")}
    return out, images
