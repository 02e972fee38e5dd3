"""The README's figure of Hybrid's block levels (app/pbgi/block_levels.py): docs/block_levels.png.

    python tests/pbgi/make_block_levels_figure.py [--out docs/block_levels.png]

Demo close-up, 128 x 128, diffuse 0.6, one pass: Classic at M = 32 (the reference), Classic at
M = 16, Hybrid at M = 16 without and with the block levels; below, each one's |image -
reference| per pixel over the asset, linear grey, white at WHITE x the reference's mean.
Prints each image's per-pixel and 4x4-pooled relative RMSE and the block-step differences
(tests/support/block_steps.py).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from app.bench.image_metrics import relative_rmse  # noqa: E402
from app.demo.cache import load_demo  # noqa: E402
from app.demo.room import default_object, default_views  # noqa: E402
from app.io.formats import object_from_dict, placed_mesh  # noqa: E402
from app.io.images import write_png  # noqa: E402
from app.pbgi.renderer import Relighter, RenderParams  # noqa: E402
from app.render.tonemap import tonemap_to_srgb8  # noqa: E402
from tests.support import scenes as S  # noqa: E402
from tests.support.block_steps import block_steps  # noqa: E402

SIZE, M = 128, 16
WHITE = 0.15          # the error maps: |image - reference| / the reference's mean, white at 15%


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/block_levels.png")
    args = ap.parse_args()
    r = Relighter()
    r.set_cloud(load_demo().gt)
    r.set_asset(placed_mesh(object_from_dict(default_object(), ".")))
    cam = default_views(SIZE, SIZE)["closeup"]
    mat = S.diffuse(0.6)
    ref = r.render(cam, [mat], RenderParams(mode="classic", microbuffer=32)).image
    images = {"Classic M 16": r.render(cam, [mat], RenderParams(mode="classic",
                                                                 microbuffer=M)).image}
    hybrid = RenderParams(mode="hybrid", microbuffer=M)
    finder = r.mode_for(hybrid).cut
    for name, fit in (("Hybrid M 16", False), ("Hybrid M 16, block levels", True)):
        finder.level_fit = fit
        r.forget_microbuffers()
        images[name] = r.render(cam, [mat], hybrid).image
    r.release()
    mask = ref[..., 3] > 0.999
    ev = -float(np.log2(max(np.percentile(ref[..., :3][mask], 99), 1e-6)))
    mean = float(ref[..., :3][mask].mean())
    top = [tonemap_to_srgb8(ref[..., :3], ev)]
    bottom = [np.zeros_like(top[0])]
    for name, im in images.items():
        steps = block_steps(im, mask, 8)
        print(f"{name}: {100 * relative_rmse(im, ref, mask):.1f}% per pixel, "
              f"{100 * relative_rmse(im, ref, mask, pool=4):.1f}% 4x4-pooled; block edges "
              f"across / inside {100 * steps['across']:.2f} / {100 * steps['inside']:.2f}%")
        top.append(tonemap_to_srgb8(im[..., :3], ev))
        rel = np.abs(im[..., :3] - ref[..., :3]).mean(-1) / mean * mask
        grey = (np.clip(rel / WHITE, 0.0, 1.0) * 255).astype(np.uint8)
        bottom.append(np.repeat(grey[..., None], top[0].shape[-1], -1))
    grid = np.concatenate([np.concatenate(top, 1), np.concatenate(bottom, 1)], 0)
    grid = np.repeat(np.repeat(grid, 2, 0), 2, 1)
    write_png(args.out, grid)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
