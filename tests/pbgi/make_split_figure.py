"""The README's before/after figure of "Where a frame is split" (docs/frame_split.png).

    python tests/pbgi/make_split_figure.py [--out docs/frame_split.png]

Top row, batches: the demo close-up at 256 x 256 (Hybrid M 24, diffuse 0.6, one pass; four
batches of receivers) with the blocks chosen per batch as before (FarFieldShare.begin_group
skipped, so each batch chooses its own, as the code did until the fix) and for the whole frame
(the code), the middle of the sphere enlarged 3x; beside each, |horizontal pixel difference|
relative to the pixels, white at 5%: the batch split shows as a vertical line.
Bottom row, tiles: the viewer's layer (app/ui/refine.py with the real renderer) of the 96 x 96
close-up, Hybrid M 16, cells of 16 (each band one render call), one pass, with each tile
choosing its own blocks as before (the render not told its layer) and sharing the layer's
(the code), enlarged 3x, and the differences of vertically adjacent pixels (the bands' edges
are horizontal), white at 15%.
Prints the seam column's and the cell edges' figures the README quotes.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from app.bench import tradeoff as T  # noqa: E402
from app.io.images import write_png  # noqa: E402
from app.pbgi.farfield import FarFieldShare  # noqa: E402
from app.pbgi.renderer import Relighter, RenderParams  # noqa: E402
from app.render.tonemap import tonemap_to_srgb8  # noqa: E402
from tests.support.block_steps import block_steps  # noqa: E402

ZOOM = 3
WHITE = 0.05          # the difference images' white: 5% of the pixel's radiance ...
WHITE_TILES = 0.15    # ... and 15% on the 96 x 96 sphere, whose light changes faster per pixel


def _diff(image: np.ndarray, axis: int = 1, white: float = WHITE) -> np.ndarray:
    """|L(p + 1) - L(p)| / mean of the two along ``axis`` (1: horizontal neighbours, 0:
    vertical), on the asset, white at ``white``, as an sRGB8 image."""
    lum = image[..., :3].mean(-1)
    a, b = np.moveaxis(lum, axis, 0)[1:], np.moveaxis(lum, axis, 0)[:-1]
    cov = np.moveaxis(image[..., 3] > 0.5, axis, 0)
    d = np.abs(a - b) / np.maximum(0.5 * (a + b), 1e-6)
    v = np.where(cov[1:] & cov[:-1], np.clip(d / white, 0, 1), 0)
    v = np.moveaxis(np.concatenate([v, np.zeros((1,) + v.shape[1:])], 0), 0, axis)
    return np.repeat((255 * v[..., None]).astype(np.uint8), 3, -1)


def _zoom(img8: np.ndarray) -> np.ndarray:
    return np.repeat(np.repeat(img8, ZOOM, 0), ZOOM, 1)


def _column_jump(image: np.ndarray, column: int) -> tuple[float, float]:
    """The mean relative difference across ``column`` | ``column + 1`` and over every column."""
    from scipy.ndimage import binary_erosion
    on = binary_erosion(image[..., 3] > 0.5, iterations=12)
    lum = image[..., :3].mean(-1)
    d = np.abs(lum[:, 1:] - lum[:, :-1]) / np.maximum(0.5 * (lum[:, 1:] + lum[:, :-1]), 1e-6)
    both = on[:, 1:] & on[:, :-1]
    return float(d[:, column][both[:, column]].mean()), float(d[both].mean())


def batches_row(ev: float | None = None):
    cloud, mesh, cam = T.scene("demo", 256)
    rl = Relighter()
    rl.set_cloud(cloud)
    rl.set_asset(mesh)
    mat = T.material("diffuse")
    params = RenderParams.from_dict(T.make_setting("hybrid", 1.0, m=24).params)
    images = []
    for per_batch in (True, False):
        real = FarFieldShare.begin_group
        if per_batch:                    # each batch chooses its own blocks (fill's fallback)
            FarFieldShare.begin_group = lambda self, *args: None
        try:
            rl.forget_microbuffers()
            res = rl.render(cam, [mat], params)
        finally:
            FarFieldShare.begin_group = real
        seam, mean = _column_jump(res.image, 127)
        print(f"batches ({res.stats.batches}), blocks per {'batch' if per_batch else 'frame'}: "
              f"across column 127 {100 * seam:.2f}%, every column {100 * mean:.2f}%")
        images.append(res.image)
    rl.release()
    ev = -float(np.log2(np.percentile(images[1][..., :3], 99))) if ev is None else ev
    crop = (slice(16, 176), slice(48, 208))
    tiles = []
    for im in images:
        tiles += [_zoom(tonemap_to_srgb8(im[..., :3], ev)[crop]), _zoom(_diff(im, 1)[crop])]
    return tiles


def tiles_row():
    import app.ui.refine as refine
    from app.demo.room import default_views
    from tests.support import scenes as S
    cloud, mesh, _ = T.scene("demo", 96)
    rl = Relighter()
    rl.set_cloud(cloud)
    rl.set_asset(mesh)
    cam, cell, mat = default_views(96, 96)["closeup"], 16, S.diffuse(0.6)
    params = RenderParams(mode="hybrid", microbuffer=16)
    images = []
    for share in (False, True):
        gi = refine.ProgressiveGI(lambda camera, tile, p, layer: rl.render(
            camera, [mat], params, tile=tile, pass_index=p,
            layer=layer if share else None).image)
        gi.cell_size = lambda budget_ms: cell
        gi.restart(cam, (0, 0, 96, 96), 0.25, budget_ms=1e9, passes=1)
        gi.finish()
        from scipy.ndimage import binary_erosion
        mask = binary_erosion(gi.full[..., 3] > 0.5, iterations=2)
        steps = block_steps(gi.full, mask, block=cell)
        print(f"tiles {'with' if share else 'without'} their layer: across / inside the cell "
              f"edges {steps['ratio']:.2f}")
        images.append(gi.full.copy())
    one = rl.render(cam, [mat], params).image
    print(f"one render of the layer: {block_steps(one, mask, block=cell)['ratio']:.2f}")
    rl.release()
    ev = -float(np.log2(np.percentile(images[1][..., :3], 99)))
    tiles = []
    for im in images:
        tiles += [_zoom(tonemap_to_srgb8(im[..., :3], ev)), _zoom(_diff(im, 0, WHITE_TILES))]
    return tiles


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/frame_split.png")
    args = ap.parse_args()
    top, bottom = batches_row(), tiles_row()
    width = sum(t.shape[1] for t in top)
    pad = [np.zeros((t.shape[0], 8, 3), np.uint8) for t in bottom]
    row2 = np.concatenate([x for t, p in zip(bottom, pad) for x in (t, p)], 1)
    row2 = np.pad(row2, ((0, 0), (0, max(width - row2.shape[1], 0)), (0, 0)))[:, :width]
    sheet = np.concatenate([np.concatenate(top, 1), np.zeros((8, width, 3), np.uint8), row2], 0)
    write_png(args.out, sheet)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
