"""The README's table "What the photo does not see" (issue 14's Table 2 target): how far the
paper's Table 2 ratio could go if the clipped points outside the photo were brightened by one
factor k, and whether the inputs say what k is.

    python tests/hdr/measure_unseen_boost.py [--rooms demo,apartment,city,studio,warehouse]
        [--photos plain,wide-roll,narrow-dark,beside] [--json out.json]
        [--points 50000] [--floor 0.1,0.25,0.5 [--face-size 512]]

Per case of `scanlight bench expand --rooms` (app/bench/expand_rooms.py: the same rooms, photos,
relit spheres and ratios - the LDR scan's relative RMSE over the candidate's, higher is better),
starting from the photo read perfectly (every saturated point the photo sees at its true value,
``photo_read_perfectly``), every saturated point the photo does not see is multiplied by k:

- ``best``: the k that maximises the ratio, chosen against the ground truth (25 factors from 1 to
  4x the true mean boost, geometric): what a perfect one-number prior could reach;
- ``k = 4, 8, 16, 32``: one factor for every room (``curve`` in the JSON: the ratios at every
  factor tried);
- ``median seen`` / ``q25 seen``: k estimated from what the inputs hold, the median (lower
  quartile) over the saturated points the photo sees of true luminance over clipped luminance -
  the boost the photo shows for the room's clipped light it does see.

The estimates need the photo read perfectly; a real expansion knows the seen points only as well
as its registration, so these are upper bounds for that rule, not its expected result.

``--floor Q,...``: that rule inside a real expansion (tried, not kept; README). The expansion runs
as `bench expand --rooms` runs it; then every overexposed point Poisson filled is raised to
k x its clipped luminance where it lies below, k the quantile Q of the registered photo's
boost (expanded over clipped luminance, on the overexposed points the photo gave values); the
table gives k and the ratios all / diffuse / metal without and with the floor.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from app.bench import expand_rooms as R  # noqa: E402
from app.cloud import PointCloud  # noqa: E402
from app.color import luminance  # noqa: E402
from app.params import BY_KEY  # noqa: E402

TL = BY_KEY["hdr.threshold_ldr"].default   # the points that count as saturated
STEPS = 25
FIXED = (4.0, 8.0, 16.0, 32.0)


def boosted(cloud: PointCloud, mask: np.ndarray, k: float) -> PointCloud:
    c = cloud.colors.astype(np.float64).copy()
    c[mask] *= k
    return PointCloud(cloud.positions, cloud.normals, c.astype(np.float32), True, cloud.source)


def measure(room: str, kind: str, points: int) -> dict:
    sc, _ = R.build_case(room, kind, points)
    seen = R.photo_sees(sc.gt, sc.photo_camera)
    s = R.point_ratios(sc.ldr, sc.gt, sc.ldr, seen, TL)["scale"]
    spheres = R.RelitSpheres(sc.gt)
    ldr_err = spheres.errors(R.scaled(sc.ldr, s))
    told = R.photo_read_perfectly(sc.ldr, sc.gt, seen, s, TL)
    over = luminance(sc.ldr.colors) > TL
    unseen, seen_c = over & ~seen, over & seen

    def ratio(k: float) -> dict:
        e = spheres.errors(R.scaled(boosted(told, unseen, k), s))
        return {q: ldr_err[q] / max(e[q], 1e-12) for q in e}

    truth = luminance(sc.gt.colors.astype(np.float64) * s)
    clip = np.maximum(luminance(sc.ldr.colors.astype(np.float64)), 1e-6)
    k_true = float(truth[unseen].mean() / clip[unseen].mean()) if unseen.any() else 1.0
    shown = truth[seen_c] / clip[seen_c] if seen_c.any() else np.ones(1)
    k_med, k_q25 = float(np.median(shown)), float(np.quantile(shown, 0.25))
    curve = {float(k): ratio(float(k)) for k in
             sorted({*np.geomspace(1.0, max(4.0 * k_true, 4.0), STEPS).tolist(), *FIXED})}
    best = {q: max(((r[q], k) for k, r in curve.items()), key=lambda t: t[0])
            for q in ("diffuse", "metal")}
    return {"room": room, "photo": kind, "saturated_unseen": int(unseen.sum()),
            "saturated_seen": int(seen_c.sum()), "k_true_mean": k_true,
            "photo_only": curve[1.0], "best": best, "curve": curve, "k_median_seen": k_med,
            "median_seen": ratio(k_med), "k_q25_seen": k_q25, "q25_seen": ratio(k_q25)}


def measure_floor(room: str, kind: str, quantiles, points: int, face_size: int) -> dict:
    from app.hdr import itmo
    from app.hdr.pipeline import ExpandParams, run_expansion
    from app.hdr.result import POISSON, REGISTERED
    sc, _ = R.build_case(room, kind, points)
    res = run_expansion(sc.ldr, sc.photo, sc.capture_positions,
                        params=ExpandParams(face_size=face_size))
    seen = R.photo_sees(sc.gt, sc.photo_camera)
    s = R.point_ratios(res.cloud, sc.gt, sc.ldr, seen, TL)["scale"]
    spheres = R.RelitSpheres(sc.gt)
    ldr_err = spheres.errors(R.scaled(sc.ldr, s))
    y_l = luminance(sc.ldr.colors.astype(np.float64))
    y_h = luminance(res.cloud.colors.astype(np.float64))
    over = y_l > TL
    reg = over & (res.labels == REGISTERED)

    def ratios(cloud: PointCloud) -> list:
        m = R.point_ratios(cloud, sc.gt, sc.ldr, seen, TL)
        e = spheres.errors(R.scaled(cloud, s))
        return [m["ratio_all"], ldr_err["diffuse"] / e["diffuse"], ldr_err["metal"] / e["metal"]]

    row = {"room": room, "photo": kind, "points": points, "face_size": face_size,
           "path": res.report.get("path"), "photo_points": int(reg.sum()),
           "without": ratios(res.cloud)}
    for q in quantiles:
        k = float(np.quantile(y_h[reg] / y_l[reg], q)) if reg.any() else 1.0
        low = over & (res.labels == POISSON) & (y_h < k * y_l)
        c = res.cloud.colors.astype(np.float64).copy()
        c[low] = itmo.rescale_luminance(c[low], k * y_l[low])
        row[f"q{q:g}"] = {"k": k, "raised": int(low.sum()), "ratios": ratios(
            PointCloud(res.cloud.positions, res.cloud.normals, c.astype(np.float32), True, ""))}
    return row


def floor_table(rows, quantiles) -> str:
    out = ["| room | photo | photo's points | without: all / diffuse / metal | "
           + " | ".join(f"q {q:g}: k, all / diffuse / metal" for q in quantiles) + " |",
           "|---|---|---|---|" + "---|" * len(quantiles)]
    for r in rows:
        def three(v):
            return " / ".join(f"{x:.2f}" for x in v)
        cells = " | ".join(f"{r[f'q{q:g}']['k']:.1f}, {three(r[f'q{q:g}']['ratios'])}"
                           for q in quantiles)
        out.append(f"| {r['room']} | {r['photo']} | {r['photo_points']} | "
                   f"{three(r['without'])} | {cells} |")
    return "\n".join(out)


def table(rows) -> str:
    out = ["| room | photo | unseen / seen saturated | photo only | best k (k) | "
           + " | ".join(f"k = {k:.0f}" for k in FIXED) + " | median seen (k) | q25 seen (k) |",
           "|---|---|---|---|---|" + "---|" * len(FIXED) + "---|---|"]
    for r in rows:
        def two(d):
            return f"{d['diffuse']:.2f} / {d['metal']:.2f}"
        best = (f"{r['best']['diffuse'][0]:.2f} / {r['best']['metal'][0]:.2f} "
                f"({r['best']['diffuse'][1]:.0f} / {r['best']['metal'][1]:.0f})")
        fixed = " | ".join(two(r["curve"][k]) for k in FIXED)
        out.append(f"| {r['room']} | {r['photo']} | {r['saturated_unseen']} / "
                   f"{r['saturated_seen']} | {two(r['photo_only'])} | {best} | {fixed} | "
                   f"{two(r['median_seen'])} ({r['k_median_seen']:.1f}) | "
                   f"{two(r['q25_seen'])} ({r['k_q25_seen']:.1f}) |")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rooms", default=",".join(R.room_names()))
    ap.add_argument("--photos", default="plain,wide-roll,narrow-dark,beside")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--floor", help="comma-separated quantiles: the floor inside the expansion")
    ap.add_argument("--points", type=int, default=50000)
    ap.add_argument("--face-size", type=int, default=512)
    a = ap.parse_args(argv)
    rows = []
    if a.floor:
        qs = [float(q) for q in a.floor.split(",")]
        for room in a.rooms.split(","):
            for kind in a.photos.split(","):
                rows.append(measure_floor(room, kind, qs, a.points, a.face_size))
                print(floor_table(rows[-1:], qs).splitlines()[-1], flush=True)
        print(floor_table(rows, qs))
        if a.json:
            a.json.write_text(json.dumps(rows, indent=1))
        return 0
    for room in a.rooms.split(","):
        for kind in a.photos.split(","):
            rows.append(measure(room, kind, a.points))
            print(table(rows[-1:]).splitlines()[-1], flush=True)
    print(table(rows))
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
