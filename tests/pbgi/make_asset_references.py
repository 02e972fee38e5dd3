"""Render the path-traced references of the asset in the room (app/bench/asset_scenes.py) with
Mitsuba 3.

    pip install -e .[reference]
    python tests/pbgi/make_asset_references.py [--spp 1024] [--rooms city,apartment]

Writes tests/pbgi/references/asset/: per room (apartment: tuning, city: held out), asset (blocks,
sphere) and material (A.KINDS for the blocks, A.CONVEX_KINDS for the sphere; ``--kinds`` picks
some) a 96 x 96 half EXR of the asset in the panorama room (max_depth 3: one inter-reflection),
and for the demo room's shadow the catcher with and without the demo sphere
(``shadow_with.exr``, ``shadow_without.exr``); references.json holds per image its samples,
render seconds, the Mitsuba version that made it and its own noise floor (relative RMSE of the
mean of two independent halves, per pixel and 4x4-pooled, over the asset or the catcher), and
the BSDF conventions. CI never runs this: the tests read the files.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from app.bench import asset_scenes as A  # noqa: E402
from app.bench import mitsuba_scene as ms  # noqa: E402
from app.bench.image_metrics import erode  # noqa: E402
from app.io.exr import write_exr  # noqa: E402


def _mask(cloud, mesh, cam):
    from app.pbgi.renderer import Relighter, RenderParams
    rl = Relighter()
    rl.set_cloud(cloud)
    rl.set_asset(mesh)
    cover = rl.render(cam, [A.material("diffuse")], RenderParams(mode="envmap")).image
    rl.release()
    return erode(cover[..., 3] > 0.5, 1)


def _entry(ref, mask, spp):
    import mitsuba as mi
    return {"spp": spp, "seconds": round(ref.seconds, 2), "mitsuba": mi.__version__,
            "noise_rel_rmse": round(ref.noise_floor(mask, 1), 5),
            "noise_rel_rmse_4x4": round(ref.noise_floor(mask, 4), 5)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--rooms", default="city,apartment")
    ap.add_argument("--assets", default=",".join(A.ASSETS))
    ap.add_argument("--kinds", default=",".join(A.KINDS))
    ap.add_argument("--no-shadow", action="store_true")
    ap.add_argument("--out", default=str(A.REFERENCES))
    args = ap.parse_args(argv)
    import mitsuba as mi

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    index_path = out / A.INDEX
    index = json.loads(index_path.read_text()) if index_path.exists() else {"references": {}}
    # the version of the references without their own "mitsuba" (the first ones): kept
    index.setdefault("mitsuba", mi.__version__)
    index.update({"variant": ms.VARIANT, "conventions": ms.CONVENTIONS,
                  "max_depth": A.MAX_DEPTH, "size": A.SIZE})

    def save():
        index_path.write_text(json.dumps(index, indent=1, sort_keys=True) + "\n")

    for room in [r for r in args.rooms.split(",") if r]:
        for asset in [a for a in args.assets.split(",") if a]:
            cloud, mesh, cam = A.asset_scene(room, asset)
            side = ms.square_side(cloud)
            mask = _mask(cloud, mesh, cam)
            for kind in [k for k in args.kinds.split(",") if k]:
                if asset == "sphere" and kind not in A.CONVEX_KINDS:
                    continue
                scene = ms.build_scene(cloud, mesh, A.material(kind), cam, side,
                                       max_depth=A.MAX_DEPTH)
                ref = ms.render_reference(scene, args.spp)
                name = A.reference_name(room, asset, kind)
                write_exr(out / name, ref.image, half=True)
                index["references"][name] = {"room": room, "asset": asset, "kind": kind,
                                             "square_side": side, **_entry(ref, mask, args.spp)}
                print(name, index["references"][name], flush=True)
                save()
    if not args.no_shadow:
        cloud, mesh, cam = A.shadow_scene()
        side = ms.square_side(cloud)
        x0, x1, z0, z1 = A.FLOOR_RECT
        catcher = (x0, x1, z0, z1, 1e-3, A.CATCHER_ALBEDO)
        images = {}
        for name, m in (("shadow_with.exr", mesh), ("shadow_without.exr", None)):
            scene = ms.build_scene(cloud, m, A.material("diffuse"), cam, side,
                                   max_depth=A.MAX_DEPTH, catcher=catcher)
            ref = ms.render_reference(scene, args.spp)
            images[name] = ref
            write_exr(out / name, ref.image, half=True)
        # the catcher's pixels: a render with the catcher alone, black room
        rl_mask = _catcher_mask(cam, catcher)
        np.save(out / "shadow_catcher_mask.npy", rl_mask)
        for name, ref in images.items():
            index["references"][name] = {"scene": "demo shadow", "catcher": list(catcher),
                                         **_entry(ref, rl_mask, args.spp)}
            print(name, index["references"][name], flush=True)
        save()
    return 0


def _catcher_mask(cam, catcher) -> np.ndarray:
    """Pixels whose centre ray meets the catcher rectangle (numpy ray-plane test)."""
    x0, x1, z0, z1, y, _ = catcher
    h, w = cam.height, cam.width
    dirs = cam.pixel_directions() if hasattr(cam, "pixel_directions") else None
    if dirs is None:
        fwd = cam.look_at - cam.position
        fwd = fwd / np.linalg.norm(fwd)
        right = np.cross(fwd, cam.up)
        right /= np.linalg.norm(right)
        up = np.cross(right, fwd)
        t = np.tan(np.radians(cam.fov_y_deg) / 2)
        ys, xs = np.mgrid[0:h, 0:w]
        u = ((xs + 0.5) / w * 2 - 1) * t * w / h
        v = (1 - (ys + 0.5) / h * 2) * t
        dirs = fwd + u[..., None] * right + v[..., None] * up
    o = cam.position
    s = (y - o[1]) / np.where(np.abs(dirs[..., 1]) > 1e-9, dirs[..., 1], 1e-9)
    p = o + s[..., None] * dirs
    inside = (s > 0) & (p[..., 0] > x0) & (p[..., 0] < x1) & (p[..., 2] > z0) & (p[..., 2] < z1)
    return erode(inside, 1)


if __name__ == "__main__":
    sys.exit(main())
