"""``scanlight bench expand``: HDR expansion of a 1M-point room from one capture position.

The cloud is the synthetic room (app.demo.room.room_cloud) scanned to LDR with the scanner's
auto exposure; the photo is the demo's ray-cast HDR photo; one cube map at the demo capture
position (``--face-size``, default the table's ``hdr.face_size``; the paper's setting is 1024).
Set-up (generating the scene) is not timed. Records: case.points, case.method,
metrics.seconds_total and one metrics.seconds_<stage> per stage, plus the point RMS on the
overexposed points against the ground truth (and the LDR cloud's, for scale).

``--rooms`` (comma-separated, or ``all``) runs instead the real-room protocol of
app/bench/expand_rooms.py: per room and photo kind (``--photos``), the path taken, the points
expanded from the photo, the error ratios against the LDR scan and the exposure error.

``--poisson-stress`` adds the Poisson solver comparison on a large Omega: every overexposed
point of the cloud is treated as unknown (as if no rendering had seen it; boundary values 3x the
LDR colour), for both solvers.
"""

from __future__ import annotations

import time


from app.bench.records import record
from app.commands.options import add_param_options, param_values

BENCH = "expand"


def add_arguments(parser) -> None:
    parser.add_argument("--points", type=int, default=None,
                        help="cloud size (default 1000000; with --rooms 50000)")
    parser.add_argument("--methods", default="pmatch-rgb",
                        help="comma-separated methods, or 'all' (default pmatch-rgb)")
    parser.add_argument("--rooms", default=None,
                        help="real-room protocol: comma-separated rooms (demo, apartment, city, "
                             "studio, warehouse) or 'all'")
    parser.add_argument("--photos", default="all",
                        help="with --rooms: comma-separated photo kinds (plain, wide-roll, "
                             "narrow-dark, beside; demo room also 'demo') or 'all'")
    parser.add_argument("--poisson-stress", action="store_true",
                        help="also time both Poisson solvers with Omega = all overexposed points")
    add_param_options(parser, "bench expand")   # --face-size, --solver, --seed


def scene(points: int, seed: int = 0):
    from app.demo.room import (CAPTURE_POSITIONS, PHOTO_CAMERA, ldr_scan, render_photo,
                               room_cloud, scan_exposure)
    gt = room_cloud(points, seed)
    alpha = scan_exposure(gt)
    return gt, ldr_scan(gt, alpha), alpha, render_photo(PHOTO_CAMERA), CAPTURE_POSITIONS


def run(args) -> list[dict]:
    from app.errors import UsageError
    from app.hdr.evaluate import expansion_errors
    from app.hdr.pipeline import METHODS, STAGES, ExpandParams, run_expansion

    values = param_values(args, "bench expand")
    if args.rooms:
        return _rooms(args, values)
    methods = list(METHODS) if args.methods == "all" else args.methods.split(",")
    bad = [m for m in methods if m not in METHODS]
    if bad:
        raise UsageError(None, f"unknown method(s) {', '.join(bad)} (known: {', '.join(METHODS)})")
    points = args.points or 1_000_000
    if points < 1000:
        raise UsageError(None, "--points must be at least 1000")
    gt, ldr, alpha, photo, positions = scene(points, values["hdr.seed"])
    records = []
    for method in methods:
        params = ExpandParams.from_dict({**values, "method": method})
        t0 = time.perf_counter()
        res = run_expansion(ldr, photo, positions, params=params)
        wall = time.perf_counter() - t0
        rep = res.report
        err = expansion_errors(res.cloud, gt, ldr, params.threshold_ldr, exposure=alpha)
        metrics = {"seconds_total": wall}
        for s in STAGES:
            metrics[f"seconds_{s}"] = rep["timings"].get(f"seconds_{s}", 0.0)
        metrics.update({"rms_overexposed": err["rms_overexposed"],
                        "ldr_rms_overexposed": err["ldr_rms_overexposed"],
                        "alpha_error_pct": 100.0 * (rep["alpha"] / alpha - 1.0),
                        "overexposed": rep["counts"]["overexposed"],
                        "poisson_points": rep["counts"]["filled_by_poisson"]})
        case = {"points": len(ldr), "method": method, "face_size": params.face_size,
                "faces_rendered": rep.get("capture", {}).get("faces_rendered", 0)}
        records.append(record(BENCH, case, metrics))
    if args.poisson_stress:
        records += _poisson_stress(ldr, points)
    return records


def _rooms(args, values) -> list[dict]:
    from app.bench import expand_rooms as er
    from app.errors import UsageError
    from app.hdr.pipeline import ExpandParams
    rooms = list(er.room_names()) if args.rooms == "all" else args.rooms.split(",")
    bad = [r for r in rooms if r not in er.room_names()]
    if bad:
        raise UsageError(None, f"unknown room(s) {', '.join(bad)} "
                               f"(known: {', '.join(er.room_names())})")
    kinds = None if args.photos == "all" else args.photos.split(",")
    known = set(er.kinds_for("demo"))
    if kinds and any(k not in known for k in kinds):
        raise UsageError(None, f"unknown photo kind(s) in {args.photos!r} "
                               f"(known: {', '.join(sorted(known))})")
    points = args.points or 50_000
    if points < 1000:
        raise UsageError(None, "--points must be at least 1000")
    params = ExpandParams.from_dict({**values, "method": args.methods.split(",")[0]})
    return er.run_rooms(rooms, kinds, points, params)


def _poisson_stress(ldr, points: int) -> list[dict]:
    from scipy.spatial import cKDTree

    from app.color import luminance
    from app.hdr.poisson import poisson_fill

    y = luminance(ldr.colors)
    omega = y > 0.9
    # boundary values brighter than the guidance, so the solve has to carry them inwards
    values = 3.0 * ldr.colors
    t0 = time.perf_counter()
    tree = cKDTree(ldr.positions)
    t_tree = time.perf_counter() - t0
    out = []
    for solver in ("cg", "direct"):
        t0 = time.perf_counter()
        res = poisson_fill(ldr.positions, ldr.colors, values, omega, 16, tree, solver)
        dt = time.perf_counter() - t0
        out.append(record(BENCH, {"points": points, "method": f"poisson-{solver}",
                                  "omega": int(omega.sum())},
                          {"seconds_total": dt + t_tree, "seconds_kdtree": t_tree,
                           "seconds_poisson": dt, "cg_iterations": res.iterations,
                           "filled": int(res.filled.sum())}))
    return out
