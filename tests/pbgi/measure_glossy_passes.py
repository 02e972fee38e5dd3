"""The README's table for `pbgi.glossy_passes` ("One pass of a glossy metal is noisy"): what a
final render of a glossy metal gains from its passes, against the trade-off's path-traced
references, and what they cost.

    python tests/pbgi/measure_glossy_passes.py [--rooms demo,apartment]
        [--materials glossy,near_mirror,rough_metal] [--passes 1,2,4,8] [--json out.json]

Per room and material of `scanlight bench tradeoff` (app/bench/tradeoff.py: the same sphere,
camera, 256 x 256 and references; the references are rendered and cached on first use, which
needs Mitsuba 3), each render is what `scanlight render` makes at the default preset
(`balanced`: the mode, M and the GI scales of app/params.py's QUALITY_PRESETS, the scale per
scene as app/pbgi/upsample.py: gi_scale gives it, pbgi.edge_samples on the silhouettes) with N
passes; the table gives the relative RMSE per pixel and 4x4-pooled, FLIP, bright dots (pixels
above 1.3x the median of their 5 x 5 neighbourhood, as the README counts them) and seconds.

    python tests/pbgi/measure_glossy_passes.py --sweep [--rooms apartment,city]

instead takes the glossy sweep's committed 96 x 96 references (tests/pbgi/references, no Mitsuba
needed; app/bench/glossy.py's scene, Hybrid M 24): metal and dielectric at roughness 0 - 0.3,
1 pass against 4, each with the silhouettes' 8 edge samples as `render` gives them - whether
a dielectric's lobe needs the passes a metal's does.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def dots(image: np.ndarray, mask: np.ndarray) -> int:
    """Pixels of ``mask`` brighter than 1.3x the median luminance of their 5 x 5 neighbourhood."""
    from app.color import luminance
    lum = luminance(image[..., :3])
    pad = np.pad(lum, 2, mode="edge")
    h, w = lum.shape
    stack = np.stack([pad[y:y + h, x:x + w] for y in range(5) for x in range(5)])
    return int(((lum > 1.3 * np.median(stack, axis=0)) & mask).sum())


def sweep(rooms: list[str]) -> list[dict]:
    """The --sweep table (module docstring)."""
    from app.bench import glossy as G
    from app.bench import image_metrics as im
    from app.pbgi.renderer import Relighter, RenderParams
    rows = []
    for room in rooms:
        cloud, mesh, cam = G.glossy_scene(f"../shared/data/{room}.exr")
        rl = Relighter()
        rl.set_cloud(cloud)
        rl.set_asset(mesh)
        params = RenderParams(mode="hybrid", microbuffer=24)
        for kind in ("dielectric", "metal"):
            for r in (0.0, 0.05, 0.1, 0.2, 0.3):
                ref = G.load_reference(room, kind, r)
                cells = []
                for n in (1, 4):
                    img = rl.render_passes(cam, [G.material(kind, r)], params, n,
                                           edge_samples=8).image
                    e = G.evaluate(img, ref)
                    row = {"room": room, "material": kind, "roughness": r, "passes": n,
                           "rel_rmse": e["rel_rmse"], "rel_rmse_4x4": e["rel_rmse_4x4"],
                           "dots": dots(img, im.erode(img[..., 3] > 0.5, G.MASK_ERODE))}
                    rows.append(row)
                    cells.append(f"{100 * e['rel_rmse']:.1f} / {100 * e['rel_rmse_4x4']:.1f}%, "
                                 f"{row['dots']}")
                print(f"| {room} | {kind} {r:g} | {cells[0]} | {cells[1]} |", flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rooms", default="demo,apartment")
    ap.add_argument("--materials", default="glossy,near_mirror,rough_metal")
    ap.add_argument("--passes", default="1,2,4,8")
    ap.add_argument("--spp", type=int, default=0,
                    help="the references' samples per pixel (0: the trade-off bench's per room)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--sweep", action="store_true",
                    help="the glossy sweep's committed references instead (module docstring)")
    args = ap.parse_args(argv)
    rows = (sweep([r for r in args.rooms.split(",") if r != "demo"] or ["apartment"])
            if args.sweep else measure(args))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(rows, f, indent=1)
    return 0


def measure(args) -> list[dict]:
    """The default table (module docstring)."""
    from app.bench import image_metrics as im
    from app.bench import tradeoff as T
    from app.params import BY_KEY, DEFAULT_QUALITY, QUALITY_PRESETS
    from app.pbgi.renderer import Relighter, RenderParams
    from app.pbgi.upsample import gi_scale_of, render_upsampled
    preset = QUALITY_PRESETS[DEFAULT_QUALITY]
    values = {k: BY_KEY[k].default for k in BY_KEY if k.startswith("pbgi.")} | preset
    params = RenderParams.from_settings(values)
    edge = int(values["pbgi.edge_samples"])
    rows = []
    for room in args.rooms.split(","):
        cloud, mesh, camera = T.scene(room)
        rl = Relighter()
        rl.set_cloud(cloud)
        rl.set_asset(mesh)
        spp = args.spp or T.SPP[room]
        for kind in args.materials.split(","):
            mat = T.material(kind)
            ref = T.reference(room, kind, rl, cloud, mesh, camera, spp, T.reference_dir())
            scale = gi_scale_of(values, [mat])
            render_upsampled(rl, camera, [mat], params, 1, scale, edge_samples=edge)  # warm
            for n in (int(p) for p in args.passes.split(",")):
                t = time.perf_counter()
                img = render_upsampled(rl, camera, [mat], params, n, scale,
                                       edge_samples=edge).image
                seconds = time.perf_counter() - t
                e = T.evaluate(img, ref.image)
                mask = im.erode(img[..., 3] > 0.5, T.MASK_ERODE)
                row = {"room": room, "material": kind, "passes": n, "scale": scale,
                       "seconds": round(seconds, 2), "dots": dots(img, mask),
                       "ref_dots": dots(np.concatenate([ref.image, img[..., 3:]], -1), mask),
                       "rel_rmse": e["rel_rmse"], "rel_rmse_4x4": e["rel_rmse_4x4"],
                       "flip": e["flip"], "ref_noise": ref.noise, "ref_noise_4x4": ref.noise_4x4}
                rows.append(row)
                print(f"| {room} | {kind} | {n} | {100 * e['rel_rmse']:.1f}% / "
                      f"{100 * e['rel_rmse_4x4']:.2f}% | {e['flip']:.3f} | {row['dots']} "
                      f"({row['ref_dots']}) | {seconds:.1f} |", flush=True)
    return rows


if __name__ == "__main__":
    raise SystemExit(main())
