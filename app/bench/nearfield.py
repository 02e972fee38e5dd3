"""``scanlight bench nearfield``: where the environment map is exact enough (pbgi.envmap_beyond).

The demo room's sphere shrunk about its centre, so that its clearance (distance to the nearest
scan point over its radius, app/pbgi/nearfield.py) grows from 0.25 to about 16, framed the same
at every size. Per clearance and material (diffuse, and glossy 0.25 for contrast): the
environment map's and Hybrid M = 16's 4x4-pooled relative RMSE against Classic M = 24 on the
same cloud (all three see the same points; only the near field differs), and the frame times.
The hand-over is worth it from the clearance at which the environment map's error falls to
Hybrid's own; a convex asset without asset occlusion, so the three compare the room's light
alone.
"""

from __future__ import annotations

import time

import numpy as np

from app.bench.records import record

FRACTIONS = (0.8, 0.5, 0.33, 0.2, 0.11, 0.06)   # sphere radius / distance centre-nearest point
MATERIALS = ("diffuse", "glossy")


def add_arguments(parser) -> None:
    parser.add_argument("--size", type=int, default=128, help="image side (default 128)")


def run(args) -> list[dict]:
    from scipy.spatial import cKDTree

    from app.bench import image_metrics as im
    from app.bench.tradeoff import material
    from app.camera import Camera
    from app.demo.cache import load_demo
    from app.demo.room import OBJECT_CENTRE
    from app.errors import UsageError
    from app.io.formats import object_from_dict, placed_mesh
    from app.pbgi.renderer import Relighter, RenderParams
    if not 16 <= args.size <= 1024:
        raise UsageError(None, f"--size must be in 16 .. 1024, got {args.size}")
    cloud = load_demo().gt
    c = np.asarray(OBJECT_CENTRE, float)
    d0 = float(cKDTree(cloud.positions).query(c)[0])
    rl = Relighter()
    rl.set_cloud(cloud)
    settings = {"classic": RenderParams(mode="classic", microbuffer=24, asset_occlusion=False,
                                        envmap_beyond=0.0),
                "hybrid": RenderParams(mode="hybrid", microbuffer=16, asset_occlusion=False,
                                       envmap_beyond=0.0),
                "envmap": RenderParams(mode="envmap", envmap_face=128)}
    unit = placed_mesh(object_from_dict({"mesh": "sphere", "translate": list(c), "scale": 1.0},
                                        "."))
    r0 = float(np.linalg.norm(unit.positions - c, axis=1).max())   # the unit sphere's radius
    records = []
    for frac in FRACTIONS:
        r = frac * d0
        rl.set_asset(placed_mesh(object_from_dict({"mesh": "sphere", "translate": list(c),
                                                   "scale": r / r0}, ".")))
        clear = rl.clearance()
        cam = Camera(c + np.array([0.0, 0.12, 1.05]) * (r / 0.4), c, fov_y_deg=45,
                     width=args.size, height=args.size)
        for kind in MATERIALS:
            mat = [material(kind)]
            images, ms = {}, {}
            for name, p in settings.items():
                rl.render(cam, mat, p)                           # warm
                rl.forget_microbuffers()
                t = time.perf_counter()
                images[name] = rl.render(cam, mat, p).image
                ms[name] = 1e3 * (time.perf_counter() - t)
            mask = im.erode(images["classic"][..., 3] > 0.5, 1)
            err = {n: im.relative_rmse(images[n], images["classic"], mask, 4)
                   for n in ("hybrid", "envmap")}
            records.append(record("nearfield", {"clearance": round(clear.ratio, 2),
                                                "material": kind},
                                  {"envmap_vs_classic": err["envmap"],
                                   "hybrid_vs_classic": err["hybrid"],
                                   "ms_classic": ms["classic"], "ms_hybrid": ms["hybrid"],
                                   "ms_envmap": ms["envmap"]}))
    rl.release()
    return records
