"""The README's figure of the asset's mirror bounce (docs/asset_mirror_bounce.png).

    python tests/pbgi/make_mirror_bounce_figure.py [--out docs/asset_mirror_bounce.png]

Rows: the blocks (app/bench/asset_scenes.py) in the apartment and in the city (held out), silver
0.05 ("mirror_metal") and gold 0.25 ("glossy_metal"). Columns: the committed Mitsuba reference
(max_depth 3, masked to the asset), the glossy bounce's plane alone (the bounce before the mirror
bounce: app/pbgi/asset_scene.py with MIRROR_ROUGHNESS moved below every roughness), and the
code, Hybrid M 24, enlarged 2x. Prints each image's 4x4-pooled and per-pixel relative RMSE,
FLIP and largest pixel against the reference's.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from app.bench import asset_scenes as A  # noqa: E402
from app.bench.glossy import evaluate  # noqa: E402
from app.io.images import write_png  # noqa: E402
from app.pbgi import asset_scene  # noqa: E402
from app.pbgi.renderer import Relighter, RenderParams  # noqa: E402
from app.render.tonemap import tonemap_to_srgb8  # noqa: E402

ZOOM = 2
KINDS = ("mirror_metal", "glossy_metal")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/asset_mirror_bounce.png")
    args = ap.parse_args(argv)
    rows = []
    keep = asset_scene.MIRROR_ROUGHNESS
    for room in A.ROOMS:
        cloud, mesh, cam = A.asset_scene(room, "blocks")
        rl = Relighter()
        rl.set_cloud(cloud)
        rl.set_asset(mesh)
        for kind in KINDS:
            ref = A.load_image(A.reference_name(room, "blocks", kind))
            shown = []
            for name, rough in (("plane", (-1.0, -0.5)), ("mirror", keep)):
                asset_scene.MIRROR_ROUGHNESS = rough
                try:
                    image = rl.render(cam, [A.material(kind)],
                                      RenderParams(mode="hybrid", microbuffer=24)).image
                finally:
                    asset_scene.MIRROR_ROUGHNESS = keep
                e = evaluate(image, ref)
                print(f"{room} {kind} {name}: 4x4 {100 * e['rel_rmse_4x4']:.1f}%, "
                      f"per pixel {100 * e['rel_rmse']:.1f}%, FLIP {e['flip']:.3f}, "
                      f"largest pixel / reference's {e['peak_ratio']:.2f}")
                shown.append(image)
            cover = shown[-1][..., 3:4]
            masked = np.concatenate([ref[..., :3] * cover, cover], axis=-1).astype(np.float32)
            rows.append(np.concatenate([tonemap_to_srgb8(i, 0.0) for i in [masked] + shown],
                                       axis=1))
        rl.release()
    sheet = np.concatenate(rows, axis=0)
    write_png(args.out, np.repeat(np.repeat(sheet, ZOOM, 0), ZOOM, 1))
    print("wrote", args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
