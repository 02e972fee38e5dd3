"""Errors of an expanded cloud against ground truth (paper Table 2, "Points" column).

The expanded cloud is on the LDR scan's scale (alpha x radiance) and the ground truth on the
photo's, so colours are compared after dividing by a scale s: given (``exposure``), or measured as
the median ratio Y_cloud / Y_gt over well-exposed points, where an LDR scan equals s x truth up to
8-bit rounding. RMS is over points and the three channels, in ground-truth units.

The relit-render half of the protocol renders the asset lit by each cloud (app.pbgi.compare) and
reports RMS and SSIM on the object's pixels against the render lit by the ground truth.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from app.cloud import PointCloud
from app.color import luminance
from app.errors import ScanlightError

def render_errors(expanded: PointCloud, gt: PointCloud, ldr: PointCloud | None,
                  options: dict) -> dict:
    """The relit-render errors (paper Table 2): the asset lit by the expanded (and LDR) cloud
    against the asset lit by the ground truth, on the object's pixels.

    options: "scale" (cloud units per ground-truth unit, from expansion_errors), "object"
    (object JSON path; default a sphere at the cloud's centre), "renderer" (hybrid | classic),
    "size" (render size, default 128), "microbuffer" (default 16).
    """
    from app.io.formats import load_object, object_from_dict, placed_mesh
    from app.pbgi.compare import framing_camera, relit_errors, scaled
    if options.get("object"):
        spec = load_object(options["object"])
    else:
        lo, hi = gt.bounds()
        spec = object_from_dict({"mesh": "sphere", "translate": list(0.5 * (lo + hi)),
                                 "scale": float(0.2 * np.min(hi - lo)) or 0.1}, None, "default sphere")
    mesh = placed_mesh(spec)
    camera = framing_camera(mesh, gt, int(options.get("size", 128)))
    s = float(options.get("scale", 1.0))
    clouds = {"expanded": scaled(expanded, s)}
    if ldr is not None:
        clouds["ldr"] = scaled(ldr, s)
    errs, _ = relit_errors(clouds, gt, mesh, camera, mode=options.get("renderer", "hybrid"),
                           microbuffer=int(options.get("microbuffer", 16)))
    out = dict(errs["expanded"])
    if ldr is not None:
        out.update({f"ldr_{k}": v for k, v in errs["ldr"].items()})
    return out


def correspondence(cloud: PointCloud, gt: PointCloud, source=None) -> tuple[np.ndarray, str, float]:
    """Index of each cloud point's ground-truth point: same order when the positions agree,
    nearest neighbour otherwise. Returns (index, how, largest distance)."""
    if len(cloud) == len(gt):
        lo, hi = gt.bounds()
        tol = 1e-6 * max(float(np.max(hi - lo)), 1e-9)
        d = np.abs(cloud.positions - gt.positions).max(axis=1)
        if float(d.max()) <= tol:
            return np.arange(len(gt)), "same order", float(d.max())
    dist, idx = cKDTree(gt.positions).query(cloud.positions, workers=-1)
    far = float(np.max(dist)) if len(dist) else 0.0
    lo, hi = gt.bounds()
    if far > 0.05 * float(np.max(hi - lo)):
        raise ScanlightError(source, f"the cloud does not overlap the ground truth (a point is "
                                     f"{far:.3g} m from the nearest ground-truth point)")
    return idx, "nearest neighbour", far


def estimate_scale(colors: np.ndarray, gt_colors: np.ndarray, tl: float) -> float:
    y, yg = luminance(colors), luminance(gt_colors)
    ok = (y > 0.02) & (y < tl) & (yg > 1e-6)
    if ok.sum() < 10:
        return 1.0
    return float(np.median(y[ok] / yg[ok]))


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    if len(a) == 0:
        return float("nan")
    return float(np.sqrt(np.mean((a.astype(np.float64) - b) ** 2)))


def expansion_errors(cloud: PointCloud, gt: PointCloud, ldr: PointCloud | None = None,
                     tl: float = 0.9, exposure: float | None = None, source=None) -> dict:
    """Point RMS overall and on the overexposed points (those an LDR scan clipped)."""
    if not np.any(luminance(gt.colors) > 0):
        raise ScanlightError(gt.source or source, "the ground truth is all black: there is no "
                                                  "light to compare with (relative errors are "
                                                  "undefined)")
    idx, how, far = correspondence(cloud, gt, source)
    g = gt.colors[idx].astype(np.float64)
    ldr_cols = None
    if ldr is not None:
        if len(ldr) != len(cloud):
            lidx, _, _ = correspondence(cloud, ldr, source)
            ldr_cols = ldr.colors[lidx]
        else:
            ldr_cols = ldr.colors
    ref = ldr_cols if ldr_cols is not None else cloud.colors
    if exposure is None:
        s, s_src = estimate_scale(ref, g, tl), "median ratio on well-exposed points"
    else:
        s, s_src = float(exposure), "given"
    if ldr_cols is not None:
        over = luminance(ldr_cols) > tl
        over_src = "LDR luminance > tl"
    else:
        over = s * luminance(g) > tl
        over_src = "scale x ground-truth luminance > tl"
    c = cloud.colors / s
    eps = 1e-3
    log_err = np.log2((luminance(c[over]) + eps) / (luminance(g[over]) + eps))
    out = {"points": int(len(cloud)), "overexposed": int(over.sum()), "overexposed_from": over_src,
           "correspondence": how, "max_distance": far, "scale": s, "scale_from": s_src,
           "rms_all": _rms(c, g), "rms_overexposed": _rms(c[over], g[over]),
           "rms_well_exposed": _rms(c[~over], g[~over]),
           # scale-free companion: RMS of log2(Y / Y_gt) on the overexposed points (stops)
           "log2_rms_overexposed": float(np.sqrt(np.mean(log_err ** 2))) if len(log_err) else float("nan")}
    if ldr_cols is not None:
        lc = ldr_cols / s
        ll = np.log2((luminance(lc[over]) + eps) / (luminance(g[over]) + eps))
        out.update({"ldr_rms_all": _rms(lc, g), "ldr_rms_overexposed": _rms(lc[over], g[over]),
                    "ldr_log2_rms_overexposed": float(np.sqrt(np.mean(ll ** 2))) if len(ll)
                    else float("nan")})
    return out
