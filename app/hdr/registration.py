"""Find the photo's camera in the cloud's frame, with no calibration from the user.

The photo and the capture renderings (app.hdr.capture) show the same room. The camera is found
photometrically (app.hdr.alignment): a global search over view direction, roll and field of view
at the capture position on thumbnails, then a local refinement of rotation, field of view and
position against the scan's points. Feature matching (SIFT + RANSAC PnP, OpenCV) was tried first
and registered only 4-8 of 20 test photos: the capture renderings of a scan are soft splats and
the photos of real rooms soft too, so keypoints are few and their matches ambiguous; the whole
image's agreement is a far stronger signal.

A registration is accepted only when it explains the photo: most of the scan's points it sees
agree with the photo up to one exposure (``AGREE_LOG`` in log luminance), over enough of them.
A photo of another room fails that test at its best camera. The same median offset is the
exposure (alpha), so a registered photo needs no histogram search.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from app.camera import Camera
from app.color import luminance

SCREEN = 8                # coarse candidates screened by a short refinement
FINALISTS = 3             # screened candidates refined fully (rotation, fov, then position)
AGREE_LOG = 0.3           # a point agrees when |log(scan/photo) - median| is below this (~35%)
MIN_AGREE = 0.8           # fraction of the seen points that must agree (true cameras: 0.86-1)
MIN_CORRELATION = 0.5     # of log luminance, scan vs photo, at those points (true: 0.62-1)
MIN_SPREAD = 0.2          # std of the scan's log luminance there (a flat wall agrees with a
                          # flat sky at any camera: 0.09 for a city photo in the warehouse)
MIN_POINTS = 300          # unsaturated scan points the photo must see


@dataclass
class Registration:
    """The outcome: ``camera`` is None when the photo could not be registered (``reason``)."""

    camera: Camera | None
    reason: str
    points: int = 0                      # unsaturated scan points the photo sees
    agree: float = 0.0                   # fraction of them agreeing with the photo
    cost: float = float("nan")           # app.hdr.alignment.PointScore.cost at the camera
    alpha: float | None = None           # the exposure: scan = alpha x photo (median ratio)
    quality: float = 0.0                 # in [0, 1]; 0 when not registered
    details: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.camera is not None

    def to_report(self) -> dict:
        out = {"registered": self.ok, "reason": self.reason, "points": self.points,
               "agree": self.agree, "cost": self.cost, "alpha": self.alpha,
               "quality": self.quality, **self.details}
        if self.camera is not None:
            out["camera"] = self.camera.to_dict()
        return {k: (None if isinstance(v, float) and not np.isfinite(v) else v)
                for k, v in out.items()}


def register(photo_rgb: np.ndarray, faces, ldr: "PointCloud", position, tl: float,
             check=None, progress=None) -> Registration:
    """The photo's camera, searched from the capture at ``position`` (its cube-map ``faces``)."""
    from app.hdr import alignment as al
    prog = progress or (lambda f: None)
    h, w = photo_rgb.shape[:2]
    mine = [f for f in faces if np.linalg.norm(f.camera.position - np.asarray(position)) < 1e-6]
    if len(mine) < 6:
        return Registration(None, "the capture's cube map is incomplete (faces that see no "
                                  "overexposed point were skipped): no panorama to search")
    cands = al.coarse_search(photo_rgb, mine, position, top=SCREEN, check=check)
    if not cands:
        return Registration(None, "the capture's panorama has no view to compare with the photo")
    # progress in proportion to the work (coarse search ~1/8, screening ~1/4, finalists the rest)
    prog(0.12)
    score = al.PointScore(photo_rgb, ldr.positions, ldr.normals, ldr.colors, tl)
    screened = []
    for k, c in enumerate(cands):
        screened.append(al.refine(score, c, False, check, resolutions=(48, 96)))
        prog(0.12 + 0.2 * (k + 1) / len(cands))
    screened.sort(key=lambda c: -c.score)
    best = None
    finalists = screened[:FINALISTS]
    for k, c in enumerate(finalists):
        c = al.refine(score, c, False, check, resolutions=(192,))
        c = al.refine(score, c, True, check, resolutions=(96, 192, 384))
        if best is None or c.score > best.score:
            best = c
        prog(0.32 + 0.63 * (k + 1) / len(finalists))
    score.set_resolution(max(h, w))
    ys, yp = score.pairs(best.basis, best.fov, best.position)
    r = ys - yp
    details = {"candidates": len(cands), "coarse_score": cands[0].score if cands else None}
    if len(r) < MIN_POINTS:
        return Registration(None, f"at the best camera the photo sees only {len(r)} unsaturated "
                                  f"scan points ({MIN_POINTS} needed)", len(r), details=details)
    m = float(np.median(r))
    agree = float(np.mean(np.abs(r - m) < AGREE_LOG))
    # agreement means something only where the view has structure to agree on: a flat wall
    # agrees with a flat sky at any camera
    spread = float(np.std(ys))
    corr = float(np.corrcoef(ys, yp)[0, 1]) if spread > 1e-6 and np.std(yp) > 1e-6 else 0.0
    details.update({"log_spread": spread, "correlation": corr})
    cost = -best.score
    cam = al.to_camera(best, w, h)
    if spread < MIN_SPREAD:
        return Registration(None, f"the best camera sees a featureless part of the scan (log "
                                  f"luminance spread {spread:.2f}, {MIN_SPREAD} needed): the "
                                  "agreement proves nothing", len(r), agree, cost,
                            details={**details, "best_camera": cam.to_dict()})
    if agree < MIN_AGREE or corr < MIN_CORRELATION:
        return Registration(None, f"no camera makes the photo agree with the scan: at the best "
                                  f"one {agree:.0%} of {len(r)} points agree ({MIN_AGREE:.0%} "
                                  f"needed), correlation {corr:.2f} ({MIN_CORRELATION} needed)",
                            len(r), agree, cost,
                            details={**details, "best_camera": cam.to_dict()})
    q = float(np.clip((agree - MIN_AGREE) / (1 - MIN_AGREE), 0, 1))  # 0 at the threshold
    return Registration(cam, "registered", len(r), agree, cost, float(np.exp(m)), q, details)
