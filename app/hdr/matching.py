"""PatchMatch between every rendering and the exposed photo, and what the pipeline checks on the
resulting fields before it trusts them (match quality, scale consistency, clipped regions).

Work resolution: faces are box-downsampled to ``pm_face_size`` and the photo to
``pm_photo_size``; the fields are then applied at full resolution by app.hdr.project (the
similarity transform of the nearest work pixel, extended to the exact position).
"""

from __future__ import annotations

import numpy as np

from app.camera import Camera
from app.color import linear_to_srgb, luminance
from app.hdr.patchmatch import evidence_cost, patchmatch, resize_area
from app.hdr.project import PhotoMatch


def match_faces(faces, photo_ldr: np.ndarray, params, check, progress, report: dict) -> list:
    """One PhotoMatch per face (NNF to I_LDR); fills ``report["match"]``.

    ``faces`` may be empty: the capture renders only faces that can see an overexposed point
    (pipeline._capture_faces), so single-view capture cameras that all look away from them
    leave none. There is then nothing to match and no evidence either way about the photo:
    the report says so (``faces`` 0, ``close_match_fraction`` None, not 0.0, which would read
    as "a photo of another scene"), and the pipeline leaves those points to Poisson editing,
    as it does for points a cube map's faces do not see."""
    if not faces:
        report["match"] = {"faces": 0, "work_size_face": params.pm_face_size,
                           "work_size_photo": None, "close_match_fraction": None,
                           "scale_octaves": None, "scale_rejected_fraction": 0.0}
        return []
    match_lum = params.pm_match == "luminance"
    b_img = photo_ldr if not match_lum else luminance(photo_ldr)[..., None]
    b_work, photo_factor = resize_area(b_img, params.pm_photo_size)
    matches = []
    for fi, face in enumerate(faces):
        check()
        a_img = face.color if not match_lum else luminance(face.color)[..., None]
        a_work, face_factor = resize_area(a_img, params.pm_face_size)
        sub = lambda f, fi=fi: progress((fi + f) / len(faces))
        nnf = patchmatch(a_work, b_work, params.pm_patch_radius, 1, params.pm_iterations,
                         params.pm_levels, params.pm_scale_range,
                         angle_init=angle_prior(face.camera), seed=params.seed + fi,
                         cancel=check, progress=sub)
        matches.append(PhotoMatch(nnf, face_factor, photo_factor,
                                  textured(a_work, params.pm_patch_radius)))
        progress((fi + 1) / len(faces))
    # Close matches of textured patches are what tells a photo of this scene from another one:
    # measured 7-69% of textured pixels on photos of the same scene (the demo, four real
    # panoramas), 0-0.6% on photos of another scene. The SSD rejection rate does not separate
    # them (51-86% on the real panoramas, whose photo is a blurry crop of a 512-px panorama).
    tex = np.concatenate([m.field.cost[m.textured & ~_flat(m.field)] for m in matches])
    good = float(np.mean(tex < params.good_match_ssd * params.threshold_ssd)) if len(tex) else 0.0
    report["match"] = {"faces": len(faces), "work_size_face": params.pm_face_size,
                       "work_size_photo": list(b_work.shape[:2]),
                       "close_match_fraction": good,
                       **scale_consistency(matches, faces, params.threshold_ssd,
                                           params.pm_scale_tolerance)}
    return matches


def perspective_scale(cam: Camera, shape) -> np.ndarray:
    """Angular size of each work pixel relative to the centre pixel: cos^1.5 of the off-axis
    angle (cos^2 along the radius, cos across it)."""
    h, w = shape
    t = np.tan(np.radians(cam.fov_y_deg) / 2)
    a = ((np.arange(w) + 0.5) / w * 2 - 1) * t * cam.aspect
    b = ((np.arange(h) + 0.5) / h * 2 - 1) * t
    return (1.0 + a[None, :] ** 2 + b[:, None] ** 2) ** -0.75


def scale_consistency(matches, faces, th: float, tolerance: float | None) -> dict:
    """Reject matches whose scale strays from the one all faces share, then let clipped pixels
    inherit the evidence of their borders (patchmatch.evidence_cost).

    The photo is one camera and the faces share their intrinsics, so every correct match has
    the same scale once each face's perspective stretch is divided out; the common scale is the
    mode over textured, well-matched pixels. A clipped region that the photo does not show (a
    studio softbox beside the one lamp in frame) finds a look-alike only at a very different
    scale; without this check it takes the lamp's radiance with a perfect SSD."""
    norm, good = [], []
    for m, face in zip(matches, faces):
        f = m.field
        ls = np.log2(np.maximum(f.scale, 1e-6)) - np.log2(perspective_scale(face.camera,
                                                                             f.scale.shape))
        norm.append(ls)
        # only textured, well-matched pixels say anything about scale: a smooth patch matches
        # equally well at any scale (and best shrunk to a point)
        good.append(ls[~_flat(f) & (f.cost <= th) & m.textured])
    pool = np.concatenate(good) if good else np.zeros(0)
    if tolerance is None or len(pool) < 64:
        for m in matches:
            m.field.cost = evidence_cost(m.field.cost, _flat(m.field))
        return {"scale_octaves": None, "scale_rejected_fraction": 0.0}
    hist, edges = np.histogram(pool, bins=40, range=(-4.0, 4.0))
    hist = np.convolve(hist, [1, 2, 3, 2, 1], mode="same")  # the mode, robust to bin edges
    mode = float(0.5 * (edges[np.argmax(hist)] + edges[np.argmax(hist) + 1]))
    rejected = total = 0
    for m, ls in zip(matches, norm):
        f = m.field
        flat = _flat(f)
        bad = ~flat & (np.abs(ls - mode) > tolerance)
        rejected += int(bad.sum())
        total += int((~flat).sum())
        f.cost = evidence_cost(np.where(bad, np.inf, f.cost).astype(np.float32), flat)
    return {"scale_octaves": mode, "scale_rejected_fraction": rejected / max(total, 1)}


def textured(img: np.ndarray, radius: int, min_std: float = 0.02) -> np.ndarray:
    """Pixels whose patch varies (std of display-encoded luminance above ``min_std``)."""
    from scipy.ndimage import uniform_filter

    y = linear_to_srgb(np.clip(img.mean(axis=2), 0, 1)).astype(np.float64)
    size = 2 * radius + 1
    m = uniform_filter(y, size, mode="nearest")
    v = uniform_filter(y * y, size, mode="nearest") - m * m
    return np.sqrt(np.maximum(v, 0.0)) > min_std


def angle_prior(cam: Camera) -> float | None:
    """Photos are usually upright: the rotation from this face's image to an upright view (pi
    for the side faces of an OpenGL cube map, whose 'up' is -y); None looking up or down."""
    r, up, f = cam.basis()
    if abs(f[1]) > 0.9:
        return None
    world_up = np.array([0.0, 1.0, 0.0])
    return float(np.arctan2(-(world_up @ r), world_up @ up))


def _flat(f) -> np.ndarray:
    return f.flat if f.flat is not None else np.zeros(f.cost.shape, dtype=bool)
