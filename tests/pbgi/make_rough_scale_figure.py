"""The README's before/after figures of the GI scale per scene (``pbgi.rough_render_scale``):
docs/rough_scale.png; with ``--cases`` and ``--settings`` the others of "Speed against accuracy"
(the scale by roughness, ``pbgi.rough_scale_from``: docs/rough_scale_from.png; the ``final``
preset, Classic M 24 before and Hybrid M 24 after: docs/final_preset.png; the ``balanced``
preset, Hybrid M 24 before and M 20 after: docs/balanced_preset.png; a rough scene's idle
passes at ``balanced``, 4 before and 2 after: docs/rough_idle_passes.png; a glossy metal's
final render, 1 pass before and ``pbgi.glossy_passes`` after: docs/glossy_passes.png).

    python tests/pbgi/make_rough_scale_figure.py [--out docs/rough_scale.png]
    python tests/pbgi/make_rough_scale_figure.py --out docs/rough_scale_from.png \
        --cases apartment:gold_r0.35,apartment:clearcoat,demo:gold_r0.45
    python tests/pbgi/make_rough_scale_figure.py --out docs/final_preset.png --settings mode \
        --cases demo:diffuse,demo:rough_metal,apartment:rough_metal
    python tests/pbgi/make_rough_scale_figure.py --out docs/balanced_preset.png --settings m \
        --cases demo:diffuse,demo:rough_metal,apartment:rough_metal
    python tests/pbgi/make_rough_scale_figure.py --out docs/rough_idle_passes.png \
        --settings passes --cases demo:diffuse,demo:rough_metal,apartment:clearcoat
    python tests/pbgi/make_rough_scale_figure.py --out docs/glossy_passes.png \
        --settings glossy_passes --cases demo:glossy,apartment:glossy,apartment:near_mirror

Per case (the trade-off bench's rooms and materials, or gold of roughness R as ``gold_rR``;
256 x 256 close-ups): the path-traced reference (app/bench/tradeoff.py's, cached; Mitsuba 3
renders it if it is missing), the image before and after (``--settings scale``: Hybrid M 24 at
GI scale 1 and 1/2; ``mode``: Classic M 24 and Hybrid M 24; ``m``: Hybrid M 24 and M 20 at
the scale per scene; ``passes``: ``balanced`` as the viewer converges a rough scene, the mean
of 4 passes before pbgi.rough_idle_passes and of 2 after; ``glossy_passes``: ``balanced``, one
pass before and 4 after), and each one's |image - reference|
x 5 over the asset, both 4x4-pooled (the reference's own noise averages out), tone mapped
alike.
Prints each image's 4x4-pooled relative RMSE (the bench's evaluate).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from app.bench import tradeoff as T  # noqa: E402
from app.io.images import write_png  # noqa: E402
from app.pbgi.renderer import Relighter  # noqa: E402
from app.render.tonemap import tonemap_to_srgb8  # noqa: E402

CASES = "demo:diffuse,demo:rough_metal,apartment:rough_metal"
SETTINGS = {"scale": (T.make_setting("hybrid", 1.0, m=24), T.make_setting("hybrid", 0.5, m=24)),
            "mode": (T.make_setting("classic", 1.0, m=24), T.make_setting("hybrid", 1.0, m=24)),
            "m": (T.make_setting("hybrid", 1.0, rough_scale=0.5, m=24),
                  T.make_setting("hybrid", 1.0, rough_scale=0.5, m=20)),
            "passes": (T.make_setting("hybrid", 1.0, rough_scale=0.5, m=20),) * 2,
            "glossy_passes": (T.make_setting("hybrid", 1.0, rough_scale=0.5, m=20),) * 2}
# passes averaged for each image of a pair (1 each where not named): ``passes`` is balanced
# with the viewer's idle passes of a rough scene before (4) and after (2) pbgi.rough_idle_passes;
# ``glossy_passes`` balanced as a final render of a glossy metal, one pass before and
# pbgi.glossy_passes (4) after
PASSES = {"passes": (4, 2), "glossy_passes": (1, 4)}
GOLD = "gold_r"


def _material(kind: str):
    """The trade-off's material, or gold (its glossy colour) at the roughness ``gold_rR`` names."""
    from dataclasses import replace
    if kind.startswith(GOLD):
        return replace(T.material("glossy"), roughness=float(kind[len(GOLD):]))
    return T.material(kind)


def _pool4(rgb: np.ndarray) -> np.ndarray:
    """4x4 block means, repeated back to the image's size (sides multiples of 4)."""
    h, w = rgb.shape[:2]
    m = rgb.reshape(h // 4, 4, w // 4, 4, 3).mean(axis=(1, 3))
    return np.repeat(np.repeat(m, 4, 0), 4, 1)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/rough_scale.png")
    ap.add_argument("--cases", default=CASES, help="room:material, comma-separated")
    ap.add_argument("--settings", choices=tuple(SETTINGS), default="scale")
    args = ap.parse_args()
    settings = SETTINGS[args.settings]
    rows = []
    for case in args.cases.split(","):
        room, kind = case.split(":")
        mat = _material(kind)
        cloud, mesh, cam = T.scene(room)
        rl = Relighter()
        rl.set_cloud(cloud)
        rl.set_asset(mesh)
        ref = T.reference(room, kind, rl, cloud, mesh, cam, T.SPP[room], T.reference_dir(),
                          mat=mat)
        passes = PASSES.get(args.settings, (1, 1))
        images = [T.render_setting(rl, cam, mat, s, n)[0] for s, n in zip(settings, passes)]
        rl.release()
        ev = -float(np.log2(max(np.percentile(ref.image[..., :3], 99), 1e-6)))
        on = images[0][..., 3] > 0.5                      # the asset's pixels
        mean = float(ref.image[..., :3][on].mean())
        tiles = [tonemap_to_srgb8(im[..., :3], ev) for im in [ref.image] + images]
        for s, n, im in zip(settings, passes, images):
            # over the asset, 4x4-pooled as the error is (the reference's own noise averages out)
            diff = np.abs(_pool4(im[..., :3]) - _pool4(ref.image[..., :3])) * 5.0 * on[..., None]
            tiles.append(tonemap_to_srgb8(diff, -float(np.log2(max(mean, 1e-6)))))
            err = T.evaluate(im, ref.image)
            print(f"{room} {kind} {s.name}, {n} pass(es): {100 * err['rel_rmse_4x4']:.2f}% 4x4, "
                  f"{100 * err['rel_rmse']:.2f}% per pixel")
        rows.append(np.concatenate(tiles, axis=1))
    write_png(args.out, np.concatenate(rows, axis=0))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
