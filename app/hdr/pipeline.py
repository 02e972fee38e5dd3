"""HDR expansion of an LDR point cloud from one unregistered HDR photo (paper Section 4).

Stages, each a function of the previous stage's output:
    linearise -> capture (cube maps of the cloud) -> register (find the photo's camera,
    app.hdr.registration) -> exposure (from the registration, else eq. 1) -> expand (nothing
    when registered; else ITMO or PatchMatch per rendering, or ITMO per point) -> project (the
    registered photo through its camera, or the expanded renderings, back to the points with a
    depth test; values that contradict the scan are rejected) -> poisson (eqs. 2-3, fills what
    neither could give).
Registered is the path taken when it can be (the report's "path"); the paper's matching is the
fallback. Every point's provenance (app.hdr.result) says which gave its value.
The output cloud is on the LDR scan's scale: well-exposed points keep their colour, expanded
points get alpha times the photo's radiance, so the two meet at the clipping threshold.

Everything is in memory (arrays in, arrays out); files are app.hdr.job's business. Progress
is reported as (fraction, stage) with a non-decreasing fraction; ``cancel`` (anything with
``is_set()``) is checked between chunks and raises app.jobs.Cancelled.
"""

from __future__ import annotations

import time
from dataclasses import asdict, replace

import numpy as np
from scipy.spatial import cKDTree

from app.camera import Camera, CUBE_FACES, cube_cameras
from app.cloud import PointCloud
from app.color import luminance
from app.errors import ScanlightError
from app.io.files import jsonable
from app.hdr import itmo
from app.hdr.capture import point_spacing, project, splat_face
from app.hdr.exposure import find_exposure
from app.hdr.matching import match_faces
from app.hdr.poisson import poisson_fill
from app.hdr.project import match_samples, project_to_points, transfer
from app.hdr.result import (LABEL_NAMES, POISSON, PROJECTED, PROVENANCE_ATTR,  # noqa: F401
                             REGISTERED, SCORE_ATTR, UNCHANGED, UNRESOLVED, Expansion)
from app.io.clean import clean_rgb, describe_counts
from app.jobs import Cancelled
from app.params import BY_KEY, EXPAND_KEYS, param_record

METHODS = BY_KEY["hdr.method"].choices
STAGES = ("linearise", "capture", "register", "exposure", "expand", "project", "poisson")
_WEIGHTS = {"linearise": 0.02, "capture": 0.2, "register": 0.15, "exposure": 0.03,
            "expand": 0.35, "project": 0.1, "poisson": 0.15}


@param_record(*EXPAND_KEYS)
class ExpandParams:
    """Every setting of one expansion: the ``hdr.*`` rows of the parameter table (app/params.py),
    which give the fields, defaults and ranges (the paper's values where it gives them). The
    viewer builds it with ``from_settings``, the command line from its generated options."""

    @property
    def pm_scale_range(self) -> tuple[float, float]:
        """(smallest, largest) patch scale PatchMatch searches."""
        return (self.pm_scale_min, self.pm_scale_max)

    def _check(self, source):
        if not self.pm_scale_min < self.pm_scale_max:
            raise ScanlightError(source, f"expand parameter 'pm_scale_min' "
                                         f"({self.pm_scale_min!r}) must be below "
                                         f"'pm_scale_max' ({self.pm_scale_max!r})")


class _Progress:
    """Maps per-stage fractions to one non-decreasing overall fraction."""

    def __init__(self, cb, stages):
        self.cb = cb
        total = sum(_WEIGHTS[s] for s in stages)
        self.start, acc = {}, 0.0
        for s in stages:
            self.start[s] = acc / total
            acc += _WEIGHTS[s]
        self.span = {s: _WEIGHTS[s] / total for s in stages}
        self.last = 0.0

    def __call__(self, stage: str, frac: float = 0.0):
        if self.cb is None:
            return
        f = self.start[stage] + self.span[stage] * min(max(frac, 0.0), 1.0)
        self.last = max(self.last, f)
        self.cb(self.last, stage)

    def done(self):
        if self.cb is not None:
            self.last = 1.0
            self.cb(1.0, "done")


def _checker(cancel):
    def check():
        if cancel is not None and cancel.is_set():
            raise Cancelled("expansion cancelled")
    return check


def _name(names, key):
    return (names or {}).get(key) or key


MAX_PHOTO_ASPECT = 16


def validate_photo(photo, names=None) -> tuple[np.ndarray, list[str]]:
    """The photo as finite, non-negative float32 (H, W, 3), or a ScanlightError if it is useless."""
    src = _name(names, "photo")
    a = np.asarray(photo)
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] < 8 or a.shape[1] < 8:
        raise ScanlightError(src, "photo must be an RGB image of at least 8x8 pixels, got "
                                  f"shape {a.shape}")
    h, w = a.shape[:2]
    if max(h, w) > MAX_PHOTO_ASPECT * min(h, w):
        # PatchMatch works on the photo scaled to a few hundred pixels on its long side: a strip
        # this thin leaves no room for one patch (it failed deep inside with "high - low < 0")
        raise ScanlightError(src, f"photo of {w}x{h} pixels is a strip (aspect ratio above "
                                  f"{MAX_PHOTO_ASPECT}:1): crop it to the part of the room")
    rgb, counts = clean_rgb(a, "pixels")
    warnings = []
    if any(counts.values()):
        warnings.append(f"photo: {describe_counts(counts)}")
    y = luminance(rgb)
    if not np.any(y > 0):
        raise ScanlightError(src, "photo is all black: it holds no light to expand the cloud with")
    lo, hi = np.percentile(y, [0.1, 99.9])
    if hi <= lo * 1.001 and float(y.max()) <= float(y.min()) * 1.001:
        raise ScanlightError(src, f"photo is uniform (every pixel has luminance {hi:.4g}): it has "
                                  "no dynamic range to expand the cloud with")
    if float(rgb.max()) <= 1.0 and np.mean(rgb.max(axis=2) >= 0.999) > 0.01:
        warnings.append("photo never exceeds 1.0 and has clipped pixels: it looks LDR, so the "
                        "expansion cannot recover radiance above its clipping point")
    return rgb, warnings


MIN_CAPTURE_SIDE = 8     # pixels per side of a single-view capture camera, like the photo's


def normalise_cameras(capture_cameras, names=None) -> list:
    """Capture cameras as a list of positions (cube maps) and Camera objects (single views)."""
    src = _name(names, "cameras")
    items = list(capture_cameras) if capture_cameras is not None else []
    if not items:
        raise ScanlightError(src, "no capture camera given")
    out = []
    for i, c in enumerate(items):
        if isinstance(c, Camera):
            if min(c.width, c.height) < MIN_CAPTURE_SIDE:
                # a 16384 x 1 view left nothing to filter (an internal error deep in the capture)
                raise ScanlightError(src, f"capture camera {i}: a view of {c.width}x{c.height} "
                                          f"pixels is too thin; each side needs at least "
                                          f"{MIN_CAPTURE_SIDE}")
            out.append(c)
            continue
        p = np.asarray(c, dtype=np.float64)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ScanlightError(src, f"capture camera {i}: position must be 3 finite numbers")
        out.append(p)
    return out


def _capture_faces(cloud, cams, params, prog, check, overexposed, report, whole_first=False):
    """Splat the faces that can see an overexposed point (the others are never used), and every
    face of the first cube-map capture when ``whole_first`` (the registration searches it)."""
    radius = params.splat_scale * point_spacing(cloud.positions)
    jobs = []
    for ci, c in enumerate(cams):
        if isinstance(c, Camera):
            jobs.append((ci, f"view{ci}", c))
        else:
            for (name, _, _), cam in zip(CUBE_FACES, cube_cameras(c, params.face_size)):
                jobs.append((ci, name, cam))
    hot = cloud.positions[overexposed]
    faces, stats = [], []
    skipped = 0
    for j, (ci, name, cam) in enumerate(jobs):
        check()
        u, v, z = project(cam, hot)
        first_cube = whole_first and ci == 0 and not isinstance(cams[0], Camera)
        if not first_cube and not np.any((z > 0) & (u >= 0) & (u < cam.width) & (v >= 0)
                                          & (v < cam.height)):
            skipped += 1
            prog("capture", (j + 1) / len(jobs))
            continue
        face, st = splat_face(cam, cloud.positions, cloud.normals, cloud.colors, radius,
                              cancel=check, name=f"{ci}:{name}")
        faces.append(face)
        stats.append((ci, st))
        prog("capture", (j + 1) / len(jobs))
    lo, hi = cloud.bounds()
    per_cam = []
    for ci, c in enumerate(cams):
        pos = c.position if isinstance(c, Camera) else c
        st = [s for i, s in stats if i == ci]
        cov = [s["coverage"] for s in st]
        back = max([s["back_view_fraction"] for s in st], default=0.0)
        entry = {"position": [float(x) for x in pos], "faces_rendered": len(st),
                 "coverage": float(np.mean(cov)) if cov else 0.0,
                 "min_face_coverage": float(min(cov)) if cov else 0.0,
                 "back_view_fraction": float(back)}
        per_cam.append(entry)
        where = f"capture camera {ci} at ({', '.join(f'{x:.3g}' for x in pos)})"
        if np.any(pos < lo) or np.any(pos > hi):
            report["warnings"].append(f"{where} is outside the cloud's bounding box")
        if back > 0.2:
            report["warnings"].append(f"{where} sees surfaces from behind ({back:.0%} of a face): "
                                      "is it inside a wall or an object, or outside the room?")
        if cov and min(cov) < 0.1:
            report["warnings"].append(f"{where}: a face of its cube map sees almost no point "
                                      f"({min(cov):.0%} covered): is it inside a wall?")
    report["capture"] = {"splat_radius": radius, "faces_rendered": len(faces),
                         "faces_skipped": skipped, "cameras": per_cam}
    return faces


def _resolve(method: str | None, params: ExpandParams | None) -> ExpandParams:
    """The params checked, with ``method`` (when given) in place of ``params.method``: the
    method is a field of ExpandParams, so its default is the table's and nowhere else."""
    params = params or ExpandParams()
    if method is not None:
        params = replace(params, method=method)
    return params.validated()


def run_expansion(ldr_cloud: PointCloud, photo, capture_cameras, method: str | None = None,
                  params: ExpandParams | None = None, progress=None, cancel=None,
                  names: dict | None = None) -> Expansion:
    """The whole pipeline; see expand_cloud for the short form. The method is
    ``params.method``; a ``method`` given here overrides it (a shorthand for callers that
    compare methods with otherwise equal parameters)."""
    params = _resolve(method, params)
    method = params.method
    check = _checker(cancel)
    t_all = time.perf_counter()
    timings = {}
    report = {"method": method, "params": jsonable(asdict(params)), "warnings": [],
              "units": "ldr-scan: expanded colours are alpha x photo radiance"}
    per_point = method.endswith("-pc")
    registering = params.registration == "auto" and not per_point
    stages = [s for s in STAGES if not (per_point and s in ("capture", "project"))
              and not (s == "register" and not registering)]
    prog = _Progress(progress, stages)

    # -- linearise ------------------------------------------------------------------------------
    t = time.perf_counter()
    prog("linearise", 0.0)
    n = len(ldr_cloud)
    if n == 0:
        raise ScanlightError(_name(names, "cloud"), "the cloud has no points")
    if not np.all(np.isfinite(ldr_cloud.positions)):
        raise ScanlightError(_name(names, "cloud"), "the cloud has non-finite positions")
    if ldr_cloud.hdr:
        report["warnings"].append("the input cloud is marked HDR; it is treated as an LDR scan "
                                  "(values clipped to [0, 1])")
    ldr_rgb, counts = clean_rgb(ldr_cloud.colors, "colors")
    ldr_rgb = np.clip(ldr_rgb, 0.0, 1.0)  # colours are sRGB-decoded 8-bit: linear [0, 1]
    cloud = PointCloud(ldr_cloud.positions, ldr_cloud.normals, ldr_rgb, False, ldr_cloud.source)
    photo_rgb, pw = validate_photo(photo, names)
    report["warnings"] += pw
    cams = normalise_cameras(capture_cameras, names)
    y_ldr = luminance(ldr_rgb)
    over = y_ldr > params.threshold_ldr
    labels = np.zeros(n, dtype=np.uint8)
    scores = np.full(n, np.nan, dtype=np.float32)
    timings["linearise"] = time.perf_counter() - t
    prog("linearise", 1.0)

    def finish(colors, alpha=None, faces=()):
        timings["total"] = time.perf_counter() - t_all
        report["alpha"] = alpha
        report["counts"] = {"points": int(n), "overexposed": int(over.sum()),
                            **{LABEL_NAMES[k]: int((labels == k).sum()) for k in LABEL_NAMES}}
        report["timings"] = {f"seconds_{k}": float(v) for k, v in timings.items()}
        report.setdefault("path", "none")
        report["provenance"] = provenance_summary(labels, scores)
        out = PointCloud(cloud.positions, cloud.normals, colors, True,
                         f"expanded:{ldr_cloud.source or 'cloud'}",
                         {"expansion": {k: report[k] for k in ("method", "path", "alpha",
                                                                "counts")}})
        out.attributes = {PROVENANCE_ATTR: labels, SCORE_ATTR: scores}
        prog.done()
        return Expansion(out, report, labels, list(faces), scores)

    if not over.any():
        report["warnings"].append(f"no overexposed points (LDR luminance > "
                                  f"{params.threshold_ldr}): nothing to expand; the output is "
                                  "the input")
        report["nothing_to_do"] = True
        return finish(ldr_rgb.copy())

    # -- capture --------------------------------------------------------------------------------
    faces = []
    if not per_point:
        t = time.perf_counter()
        prog("capture", 0.0)
        faces = _capture_faces(cloud, cams, params, prog, check, over, report, registering)
        timings["capture"] = time.perf_counter() - t

    # -- register -------------------------------------------------------------------------------
    reg = None
    if registering:
        t = time.perf_counter()
        prog("register", 0.0)
        reg = _register(photo_rgb, faces, cloud, cams, params, check,
                        lambda f: prog("register", f), report)
        timings["register"] = time.perf_counter() - t
        prog("register", 1.0)
    report["path"] = "registered" if reg is not None and reg.ok else "matching"

    # -- exposure -------------------------------------------------------------------------------
    t = time.perf_counter()
    prog("exposure", 0.0)
    if params.alpha is not None:
        alpha = float(params.alpha)
        report["exposure"] = {"alpha": alpha, "source": "given"}
    elif reg is not None and reg.ok:
        alpha = float(reg.alpha)
        report["exposure"] = {"alpha": alpha, "source": "registration: median scan / photo "
                                                        "ratio at the points the photo sees"}
    else:
        ex = find_exposure(ldr_rgb, photo_rgb, params.bins, params.iterations,
                           include_clipped=params.exposure_include_clipped, cancel=check)
        if not np.isfinite(ex.distance):
            ex = find_exposure(ldr_rgb, photo_rgb, params.bins, params.iterations,
                               include_clipped=True, cancel=check)
        alpha = ex.alpha
        report["exposure"] = {"alpha": alpha, "source": "search", "wasserstein": ex.distance,
                              "iterations": ex.iterations}
        if ex.distance > 0.1:
            report["warnings"].append(f"the photo's luminance distribution matches the cloud's "
                                      f"poorly (Wasserstein {ex.distance:.3f} at alpha "
                                      f"{alpha:.4g}): is it a photo of the same scene?")
    photo_ldr = np.clip(alpha * photo_rgb, 0.0, 1.0)
    y_photo = luminance(photo_rgb)
    l_max = float(alpha * np.percentile(y_photo, params.l_max_percentile))
    if l_max <= params.threshold_ldr:
        report["warnings"].append(f"at the matched exposure the photo peaks at {l_max:.3g} "
                                  f"(<= tl = {params.threshold_ldr}): it adds no range above "
                                  "the scan's")
    l_max = max(l_max, 1.0)
    report["l_max"] = l_max
    timings["exposure"] = time.perf_counter() - t
    prog("exposure", 1.0)

    # -- expand ---------------------------------------------------------------------------------
    t = time.perf_counter()
    prog("expand", 0.0)
    threshold = params.threshold_ldr if params.landis_threshold is None \
        else params.landis_threshold
    hdr = ldr_rgb.astype(np.float32).copy()
    values = np.zeros((n, 3), dtype=np.float32)
    has_value = np.zeros(n, dtype=bool)
    tree = None
    lum_only = method != "pmatch-rgb"
    registered = report["path"] == "registered"
    match_unseen = registered and params.unseen == "matching" and not per_point
    if registered and not match_unseen:
        pass   # the photo's own values go to the points it sees (project)
    elif per_point:
        idx = np.flatnonzero(over)
        nbr = None
        if method == "banterle-pc":
            tree = cKDTree(cloud.positions)
            check()
            # the bright points and their k-NN (the expand map is non-zero only around them)
            _, nb = tree.query(cloud.positions[idx], params.neighbours + 1, workers=-1)
            region = np.unique(np.concatenate([idx, nb.ravel()]))
            region = region[region < n]
            _, nbr_g = tree.query(cloud.positions[region], params.neighbours + 1, workers=-1)
            loc = np.full(n + 1, -1, dtype=np.int64)
            loc[region] = np.arange(len(region))
            nbr = loc[np.minimum(nbr_g[:, 1:], n)]
            exp = itmo.expand_points(ldr_rgb[region], "banterle-pc", l_max, threshold, nbr,
                                     params.landis_exponent)
            values[region] = exp
        else:
            values[idx] = itmo.expand_points(ldr_rgb[idx], "landis-pc", l_max, threshold,
                                             exponent=params.landis_exponent)
        has_value[idx] = True
        prog("expand", 1.0)
    elif method in ("landis", "banterle"):
        expanded = []
        for fi, face in enumerate(faces):
            check()
            expanded.append(itmo.expand_face(face.color, method, l_max, threshold,
                                             params.landis_exponent))
            prog("expand", (fi + 1) / max(len(faces), 1))

        def sampler(fi, u, v, ldr_pts):
            img = expanded[fi]
            h, w = img.shape[:2]
            iu = np.clip(u.astype(np.int64), 0, w - 1)
            iv = np.clip(v.astype(np.int64), 0, h - 1)
            return transfer(img[iv, iu], ldr_pts, True), None
    else:
        matches = match_faces(faces, photo_ldr, params, check,
                              lambda f: prog("expand", f), report)

        def sampler(fi, u, v, ldr_pts):
            rgb, ssd = match_samples(matches[fi], photo_rgb, u, v)
            return transfer(alpha * rgb, ldr_pts, lum_only), ssd
    timings["expand"] = time.perf_counter() - t
    prog("expand", 1.0)

    # -- project --------------------------------------------------------------------------------
    source = np.full(n, PROJECTED, dtype=np.uint8)   # where has_value: REGISTERED or PROJECTED
    if registered:
        t = time.perf_counter()
        prog("project", 0.0)
        values, has_value, seen = project_registered(photo_rgb, reg.camera, cloud, over, params,
                                                     alpha, check)
        report["projection"] = {"overexposed_seen": int(seen.sum())}
        scores[has_value] = reg.quality
        source[has_value] = REGISTERED
        timings["project"] = time.perf_counter() - t
        prog("project", 1.0 if not match_unseen else 0.5)
    if not per_point and (not registered or match_unseen):
        t = time.perf_counter()
        prog("project", 0.5 if registered else 0.0)
        targets = np.flatnonzero(over)
        pj = project_to_points(cloud.positions, ldr_rgb, targets, faces, sampler,
                               params.threshold_ssd if method.startswith("pmatch") else None,
                               cancel=check)
        if registered:
            use = pj.has_value & ~has_value
            if not _matching_agrees(values, has_value, pj, params, report):
                use[:] = False
            values[use] = pj.values[use]
            has_value = has_value | use
            pj.has_value = use
        else:
            values, has_value = pj.values, pj.has_value
        scores[pj.has_value] = pj.score[pj.has_value]
        source[pj.has_value] = PROJECTED
        report.setdefault("projection", {}).update({
            "overexposed_seen_by_captures": int(pj.seen.sum()),
            "samples_accepted": pj.samples, "samples_rejected": pj.rejected})
        if method.startswith("pmatch") and len(pj.ssd):
            fin = pj.ssd[np.isfinite(pj.ssd)]
            med = float(np.median(fin)) if len(fin) else None
            rej = pj.rejected / max(pj.rejected + pj.samples, 1)
            report["match"].update({"median_ssd": med, "rejected_fraction": rej})
            if report["match"]["close_match_fraction"] < params.good_match_min:
                report["low_match_quality"] = True
                if reg is not None and not reg.ok:   # registration failed too: another room
                    raise ScanlightError(_name(names, "photo"), _another_room(report, params))
                report["warnings"].append(
                    f"low match quality: only {report['match']['close_match_fraction']:.1%} of "
                    "the renderings' textured patches have a close match in the photo; the photo "
                    f"may show another scene. {rej:.0%} of the projected samples were rejected "
                    "and filled by Poisson editing from their neighbours")
        seen = int(pj.seen.sum())
        if seen == 0:
            report["warnings"].append("no capture camera sees an overexposed point: every "
                                      "overexposed point is left to Poisson editing")
        elif seen < 0.75 * len(targets):
            report["warnings"].append(f"{1 - seen / len(targets):.0%} of the overexposed points "
                                      "are seen by no capture camera (left to Poisson editing): "
                                      "add a capture position that faces them")
        timings["project"] = time.perf_counter() - t
        prog("project", 1.0)

    got = over & has_value
    bad = got & ~consistent(values, ldr_rgb, params.consistency)
    report["rejected_inconsistent"] = int(bad.sum())
    if bad.any():
        got &= ~bad
        has_value = has_value & ~bad
        scores[bad] = np.nan
    if bad.sum() > 0.01 * over.sum():
        report["warnings"].append(f"{int(bad.sum())} expanded values contradicted the scan (a "
                                  "channel it measured, or darker than its clip level) and were "
                                  "left to Poisson editing")
    hdr[got] = np.maximum(values[got], 0.0)
    labels[got] = source[got]

    # -- poisson --------------------------------------------------------------------------------
    t = time.perf_counter()
    prog("poisson", 0.0)
    omega = over & ~has_value
    report["poisson"] = {"omega": int(omega.sum())}
    if omega.any():
        if tree is None:
            tree = cKDTree(cloud.positions)
        check()
        prog("poisson", 0.3)
        if lum_only:
            res = poisson_fill(cloud.positions, y_ldr, luminance(hdr), omega,
                               params.neighbours, tree, params.poisson_solver, cancel=check)
            filled_rgb = itmo.rescale_luminance(ldr_rgb[omega], res.values[omega, 0])
        else:
            res = poisson_fill(cloud.positions, ldr_rgb, hdr, omega, params.neighbours, tree,
                               params.poisson_solver, cancel=check)
            filled_rgb = res.values[omega]
        hdr[omega] = np.maximum(filled_rgb, 0.0)
        labels[res.filled] = POISSON
        labels[res.unresolved] = UNRESOLVED
        hdr[res.unresolved] = ldr_rgb[res.unresolved]
        report["poisson"].update({"components": res.components, "cg_iterations": res.iterations,
                                  "solver": params.poisson_solver})
        if res.unresolved.any():
            report["warnings"].append(f"{int(res.unresolved.sum())} overexposed points lie in "
                                      "regions with no expanded neighbour at all: they keep their "
                                      "LDR colour")
    timings["poisson"] = time.perf_counter() - t
    prog("poisson", 1.0)

    # an overexposed point's true value cannot be darker than its clipped measurement
    y_h = luminance(hdr)
    low = over & (y_h < y_ldr) & (labels != UNRESOLVED)
    if low.any():
        hdr[low] = itmo.rescale_luminance(hdr[low], y_ldr[low].astype(np.float64))
    if not np.all(np.isfinite(hdr)):  # never expected; never let it out either
        bad = ~np.all(np.isfinite(hdr), axis=1)
        hdr[bad] = ldr_rgb[bad]
        report["warnings"].append(f"{int(bad.sum())} non-finite expanded colours replaced by LDR")
    return finish(hdr, alpha, faces)


def _register(photo_rgb, faces, cloud, cams, params, check, progress, report):
    """The first cube-map capture position whose panorama the photo registers to."""
    from app.hdr.registration import Registration, register
    positions = [c for c in cams if not isinstance(c, Camera)]
    if not positions:
        reg = Registration(None, "registration searches a cube-map capture; only single-view "
                                 "cameras were given")
    else:
        reg = register(photo_rgb, faces, cloud, positions[0], params.threshold_ldr, check,
                       progress)
    report["registration"] = reg.to_report()
    if not reg.ok:
        report["warnings"].append(f"the photo could not be registered ({reg.reason}): falling "
                                  f"back to {params.method}")
    return reg


UNSEEN_TRUST = 0.75  # share of the points both see where matching is within 2x of the photo
                     # (measured: 0.81-0.99 where matching helped, 0.66-0.67 in the studio)


def _matching_agrees(reg_values, reg_has, pj, params, report) -> bool:
    """Whether matching may fill the points the registered photo does not see: only when, on the
    points both see, its values agree with the photo's own (within a factor of 2 in luminance)
    for at least UNSEEN_TRUST of them. The photo is the truth where it looks; a matcher that
    misses there (a studio lamp matched to a clipped softbox) would miss where it does not."""
    both = reg_has & pj.has_value
    yr, ym = luminance(reg_values[both]), luminance(pj.values[both])
    agree = float(np.mean(np.abs(np.log((ym + 1e-6) / (yr + 1e-6))) < np.log(2.0))) \
        if both.any() else 0.0
    ok = bool(both.sum() >= 50 and agree >= UNSEEN_TRUST)
    report["unseen"] = {"mode": params.unseen, "checked_points": int(both.sum()),
                        "matching_agrees": agree, "used": ok}
    if not ok:
        report["warnings"].append(
            f"matching agreed with the registered photo on only {agree:.0%} of the {int(both.sum())} "
            f"points both see ({UNSEEN_TRUST:.0%} needed): the points the photo does not see are "
            "left to Poisson editing")
    return ok


def provenance_summary(labels: np.ndarray, scores: np.ndarray) -> dict:
    """Per provenance label: points, share, the score's meaning and its median where it has one."""
    from app.hdr.result import PROVENANCE
    out = {}
    n = max(len(labels), 1)
    for code, (name, meaning) in PROVENANCE.items():
        sel = labels == code
        s = scores[sel]
        s = s[np.isfinite(s)]
        out[LABEL_NAMES[code]] = {"label": name, "code": code, "points": int(sel.sum()),
                                  "share": float(sel.sum() / n), "score": meaning,
                                  "median_score": float(np.median(s)) if len(s) else None}
    return out


def _another_room(report, params) -> str:
    close = report["match"]["close_match_fraction"]
    return (f"the photo does not show this room: no camera makes it agree with the scan "
            f"({report['registration']['reason']}) and only {close:.1%} of the renderings' "
            f"textured patches match it closely ({params.good_match_min:.0%} needed). If it is "
            "this room, take it nearer the capture position with a wider view, or pass "
            "--registration off to expand by matching anyway")


def project_registered(photo_rgb, camera, cloud, over, params, alpha, check):
    """(values, has_value, seen): alpha x the photo's radiance at the overexposed points its
    registered ``camera`` sees, depth-tested against the cloud splatted from that camera (at
    most 1024 px on a side)."""
    from app.hdr.project import bilinear
    h, w = photo_rgb.shape[:2]
    f = min(1.0, 1024 / max(h, w))
    zcam = Camera(camera.position, camera.look_at, camera.up, camera.fov_y_deg,
                  max(8, round(w * f)), max(8, round(h * f)))
    radius = params.splat_scale * point_spacing(cloud.positions)
    face, _ = splat_face(zcam, cloud.positions, cloud.normals, cloud.colors, radius,
                         cancel=check, name="photo")
    targets = np.flatnonzero(over)
    vis, u, v = face.visible(cloud.positions[targets])
    n = len(cloud)
    values = np.zeros((n, 3), dtype=np.float32)
    has = np.zeros(n, dtype=bool)
    sel = targets[vis]
    rgb = bilinear(photo_rgb, u[vis] / f - 0.5, v[vis] / f - 0.5)
    values[sel] = (alpha * rgb).astype(np.float32)
    has[sel] = True
    return values, has, has.copy()


def consistent(values: np.ndarray, ldr: np.ndarray, tolerance: float) -> np.ndarray:
    """Whether each expanded value agrees with what the scan did measure: channels below the
    clip level within ``tolerance`` (relative, plus two 8-bit steps), clipped ones not darker
    than half the tolerance below the clip level."""
    clipped = ldr >= 0.98
    slack = tolerance * ldr + 2.0 / 255.0
    ok_open = clipped | (np.abs(values - ldr) <= slack)
    ok_clip = ~clipped | (values >= ldr * (1.0 - 0.5 * tolerance))
    return np.all(ok_open & ok_clip, axis=1)


def expand_cloud(ldr_cloud: PointCloud, photo, capture_cameras, method: str | None = None,
                 params: ExpandParams | None = None, progress=None, cancel=None,
                 names: dict | None = None) -> tuple[PointCloud, dict]:
    """(HDR cloud, JSON-able report). ``capture_cameras``: positions (cube maps) or Cameras."""
    res = run_expansion(ldr_cloud, photo, capture_cameras, method, params, progress, cancel, names)
    return res.cloud, res.report


