"""The README's figure of the block levels taken over the far field's share of the hemisphere
(app/pbgi/farfield.py: LEVEL_COVERAGE): docs/block_levels_share.png.

    python tests/pbgi/make_level_share_figure.py [--out docs/block_levels_share.png]

Demo close-up, 192 x 192, diffuse 0.6, Hybrid at M = 24, 8 passes, the levels' ratio without
(before) and with the share. Top row: pass 0 before and after, then the mean of the 8 passes
before and after, the scan's colours. Below: each
pixel's spread from pass to pass (standard deviation over its mean, white at WHITE), with the
scan's colours and with every point of one colour (where every level should be 1), before and
after. Prints the spread's median and 90th percentile in the sphere's lowest fifth and in the
rest.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import app.pbgi.farfield as F  # noqa: E402
from app.color import LUMA  # noqa: E402
from app.demo.cache import load_demo  # noqa: E402
from app.demo.room import default_object, default_views  # noqa: E402
from app.io.formats import object_from_dict, placed_mesh  # noqa: E402
from app.io.images import write_png  # noqa: E402
from app.pbgi.renderer import Relighter, RenderParams  # noqa: E402
from app.render.tonemap import tonemap_to_srgb8  # noqa: E402
from tests.support import scenes as S  # noqa: E402

SIZE, M, PASSES = 192, 24, 8
WHITE = 0.05          # the spread maps: white at 5% of the pixel's mean


def passes(r, cam, mat, coverage: bool) -> np.ndarray:
    F.LEVEL_COVERAGE = coverage
    p = RenderParams(mode="hybrid", microbuffer=M)
    out = []
    for k in range(PASSES):
        r.forget_microbuffers()
        res = r.render(cam, [mat], p, pass_index=k, passes=PASSES)
        assert res.stats.completed
        out.append(res.image)
    return np.array(out)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/block_levels_share.png")
    args = ap.parse_args()
    gt = load_demo().gt
    mesh = placed_mesh(object_from_dict(default_object(), "."))
    cam = default_views(SIZE, SIZE)["closeup"]
    mat = S.diffuse(0.6)
    runs = {}
    for cloud_name, cloud in (("scan", gt),
                              ("one colour", replace(gt, colors=np.full_like(
                                  gt.colors, gt.colors.mean(0))))):
        r = Relighter()
        r.set_cloud(cloud)
        r.set_asset(mesh)
        for name, coverage in (("before", False), ("after", True)):
            runs[cloud_name, name] = passes(r, cam, mat, coverage)
        r.release()
    F.LEVEL_COVERAGE = True
    mean = runs["scan", "after"].mean(0)
    mask = (runs["scan", "after"][..., 3].min(0) > 0.999)
    rows_y = np.nonzero(mask.any(1))[0]
    low = mask & (np.arange(SIZE)[:, None] > rows_y.min() + 0.8 * (rows_y.max() - rows_y.min()))
    ev = -float(np.log2(max(np.percentile(mean[..., :3][mask], 99), 1e-6)))
    top = ([tonemap_to_srgb8(runs["scan", n][0][..., :3], ev) for n in ("before", "after")]
           + [tonemap_to_srgb8(runs["scan", n].mean(0)[..., :3], ev) for n in ("before", "after")])
    maps = []
    for key in (("scan", "before"), ("scan", "after"), ("one colour", "before"),
                ("one colour", "after")):
        lum = runs[key][..., :3] @ LUMA
        spread = np.where(mask, lum.std(0, ddof=1) / np.maximum(lum.mean(0), 1e-9), 0.0)
        for part, sel in (("lowest fifth", low), ("rest", mask & ~low)):
            print(f"{key[0]}, {key[1]}, {part}: per-pass spread median "
                  f"{100 * np.median(spread[sel]):.2f}%, 90th percentile "
                  f"{100 * np.percentile(spread[sel], 90):.2f}%")
        grey = (np.clip(spread / WHITE, 0.0, 1.0) * 255).astype(np.uint8)
        maps.append(np.repeat(grey[..., None], top[0].shape[-1], -1))
    grid = np.concatenate([np.concatenate(top, 1),
                           np.concatenate(maps, 1)], 0)
    write_png(args.out, grid)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
