"""Render the path-traced references of the glossy sweep (app/bench/glossy.py) with Mitsuba 3.

    pip install -e .[reference]
    python tests/pbgi/make_references.py [--room ../shared/data/apartment.exr] [--spp 1024]

The sweep tests use two rooms: apartment (the one the renderer's settings were chosen on) and
city (held out: its references were made after the settings were fixed). The other panoramas
make references too noisy at 1024 spp for a test: small bright sources are rarely hit
(pooled noise floor: studio 30%, warehouse 5-6%).

Writes tests/pbgi/references/<room>_<kind>_r<roughness>.exr (half float, 96 x 96) and
references.json: per reference its samples, render seconds and its own noise floor (relative
RMSE of the mean of two independent halves, per pixel and 4x4-pooled, over the sphere), plus the
Mitsuba version and the BSDF conventions. CI never runs this: the tests read the files.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from app.bench import glossy  # noqa: E402
from app.bench import mitsuba_scene as ms  # noqa: E402
from app.bench.image_metrics import erode  # noqa: E402
from app.io.exr import write_exr  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--room", default=glossy.ROOM)
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--out", default=str(glossy.REFERENCES))
    args = ap.parse_args(argv)
    import mitsuba as mi
    from app.pbgi.renderer import Relighter, RenderParams

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    room = Path(args.room).stem
    cloud, mesh, cam = glossy.glossy_scene(args.room)
    side = ms.square_side(cloud)
    rl = Relighter()
    rl.set_cloud(cloud)
    rl.set_asset(mesh)
    cover = rl.render(cam, [glossy.material("metal", 1.0)], RenderParams(mode="envmap")).image
    mask = erode(cover[..., 3] > 0.5, glossy.MASK_ERODE)
    rl.release()
    index_path = out / glossy.INDEX
    index = json.loads(index_path.read_text()) if index_path.exists() else {"references": {}}
    index.update({"mitsuba": mi.__version__, "variant": ms.VARIANT, "conventions": ms.CONVENTIONS})
    index.setdefault("scenes", {})[room] = {"room": args.room, "points": glossy.POINTS,
                                            "size": glossy.SIZE, "sphere": glossy.SPHERE,
                                            "square_side": side}
    for kind in glossy.KINDS:
        for r in glossy.ROUGHNESS:
            scene = ms.build_scene(cloud, mesh, glossy.material(kind, r), cam, side)
            ref = ms.render_reference(scene, args.spp)
            name = glossy.reference_name(room, kind, r)
            write_exr(out / name, ref.image, half=True)
            index["references"][name] = {
                "kind": kind, "roughness": r, "spp": args.spp, "seconds": round(ref.seconds, 2),
                "noise_rel_rmse": round(ref.noise_floor(mask, 1), 5),
                "noise_rel_rmse_4x4": round(ref.noise_floor(mask, 4), 5)}
            print(name, index["references"][name], flush=True)
            index_path.write_text(json.dumps(index, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
