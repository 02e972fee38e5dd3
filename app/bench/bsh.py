"""``scanlight bench bsh``: BSH build time per stage and node counts on the synthetic room.

Only the build is timed (the room's cloud is generated first, untimed). Records: case.points,
case.seed; metrics.seconds_total, seconds_<stage>, nodes (before pruning), clusters (nodes after
pruning, Table 1's N.Cluster), leaves, cluster_leaves, cells, depth, bytes_per_node,
bytes_total, seconds_per_mpoint and nlogn_ratio (seconds / (n log2 n), relative to the first case:
values near 1 mean n log n growth).
"""

from __future__ import annotations

import math

import numpy as np

from app.bench.arguments import int_list
from app.bench.records import record
from app.pbgi.hierarchy import STAGES, build_bsh


def add_arguments(parser) -> None:
    parser.add_argument("--points", type=int_list, default=[100_000, 1_000_000, 3_000_000],
                        help="comma-separated cloud sizes (default 100000,1000000,3000000)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeat", type=int, default=1, help="builds per size; the fastest counts")
    parser.add_argument("--tc", type=float, default=0.01)
    parser.add_argument("--tn", type=float, default=0.98)


def synthetic_room(n_points: int, seed: int = 0):
    """The demo room (app.demo.room.room_cloud) at any size."""
    from app.demo.room import room_cloud
    return room_cloud(n_points, seed)


def local_room(n_points: int, seed: int):
    """Points on the 6 walls of a 4 x 2.8 x 4 m room and on 3 boxes, smooth HDR-ish colours."""
    from app.cloud import PointCloud

    rng = np.random.default_rng(seed)
    lo, hi = np.array([-2.0, 0.0, -2.0]), np.array([2.0, 2.8, 2.0])
    boxes = [((-1.8, 0.0, -1.7), (-1.0, 0.9, -0.9)), ((1.0, 0.0, -1.8), (1.7, 0.6, -1.2)),
             ((1.1, 0.0, 1.0), (1.6, 1.2, 1.5))]
    faces = []  # (axis, value, lo, hi, normal sign)
    for ax in range(3):
        faces.append((ax, lo[ax], lo, hi, 1.0))
        faces.append((ax, hi[ax], lo, hi, -1.0))
    for blo, bhi in boxes:
        blo, bhi = np.array(blo), np.array(bhi)
        for ax in range(3):
            faces.append((ax, blo[ax], blo, bhi, -1.0))
            faces.append((ax, bhi[ax], blo, bhi, 1.0))
    areas = np.array([np.prod(np.delete(f[3] - f[2], f[0])) for f in faces])
    counts = rng.multinomial(n_points, areas / areas.sum())
    pos, nrm, col = [], [], []
    for k, ((ax, val, flo, fhi, s), c) in enumerate(zip(faces, counts)):
        pts = flo + rng.random((c, 3)) * (fhi - flo)
        pts[:, ax] = val
        n = np.zeros((c, 3))
        n[:, ax] = s
        base = 0.2 + 0.6 * np.abs(np.sin(np.array([1.0, 2.0, 3.0]) * (k + 1)))
        tex = 1.0 + 0.2 * np.sin(7.0 * pts[:, (ax + 1) % 3])[:, None]
        rgb = base * tex
        if ax == 1 and s < 0:  # a bright ceiling lamp
            lamp = (np.abs(pts[:, 0]) < 0.45) & (np.abs(pts[:, 2]) < 0.45)
            rgb[lamp] = (40.0, 36.0, 30.0)
        pos.append(pts)
        nrm.append(n)
        col.append(rgb)
    return PointCloud(np.concatenate(pos), np.concatenate(nrm), np.concatenate(col), hdr=True,
                      source="bench:room")


def run(args) -> list[dict]:
    records = []
    base = None
    for n in args.points:
        cloud = synthetic_room(n, args.seed)
        best = None
        for _ in range(max(1, args.repeat)):
            h = build_bsh(cloud.positions, cloud.normals, cloud.colors, tc=args.tc, tn=args.tn)
            if best is None or h.stats["seconds_total"] < best.stats["seconds_total"]:
                best = h
        s = best.stats
        nlogn = n * math.log2(max(n, 2))
        ratio = s["seconds_total"] / nlogn
        base = ratio if base is None else base
        metrics = {"seconds_total": s["seconds_total"]}
        metrics.update({f"seconds_{st}": s.get(f"seconds_{st}", 0.0) for st in STAGES})
        metrics.update(nodes=s["nodes"], clusters=s["clusters"], leaves=s["leaves"],
                       cluster_leaves=s["cluster_leaves"], cells=s["cells"], depth=s["depth"],
                       bytes_per_node=s["bytes_per_node"], bytes_total=best.nbytes,
                       seconds_per_mpoint=s["seconds_total"] / n * 1e6, nlogn_ratio=ratio / base)
        records.append(record("bsh", {"points": n, "seed": args.seed}, metrics))
    return records


if __name__ == "__main__":  # python -m app.bench.bsh (the CLI is `scanlight bench bsh`)
    import argparse

    from app.bench.records import table

    ap = argparse.ArgumentParser(description=__doc__)
    add_arguments(ap)
    print(table(run(ap.parse_args())))
