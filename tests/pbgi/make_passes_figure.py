"""The README's before/after figure of "Passes" (docs/passes_centred.png).

    python tests/pbgi/make_passes_figure.py [docs/passes_centred.png]

The demo close-up lit by the demo's ground-truth cloud, gold (metal, roughness 0.2), 192 x 192,
Hybrid M 24: the mean of 4 passes with the pass samples as they were (the R2 points unmoved,
their mean 0.19 px off the centre) and centred (gbuffer.pass_jitter), 16 centred passes, and
each 4-pass image's difference from the 16 (x4, relative to the mean radiance). The same pass
indices, so the same lobe rotations: what differs is only where each pass samples its pixels.
"""
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
import app.pbgi.gbuffer as G  # noqa: E402 - after the path
from app.demo.cache import load_demo
from app.demo.room import default_views, default_object
from app.io.formats import object_from_dict, placed_mesh
from app.material import Material
from app.pbgi.renderer import Relighter, RenderParams
from app.render.tonemap import tonemap_to_srgb8
demo = load_demo()
cam = replace(default_views(192, 192)["closeup"], width=192, height=192)
r = Relighter(); r.set_cloud(demo.gt)
r.set_asset(placed_mesh(object_from_dict(default_object(), ".", None)))
m = [Material(base_color=(1.0, 0.71, 0.29), metallic=1.0, roughness=0.2)]
new = G.pass_jitter
def old(k, n=1):
    if k <= 0: return 0.0, 0.0
    u, v = G.r2_point(k, 0.5); return u - 0.5, v - 0.5
def mean(fn, n):
    G.pass_jitter = fn
    return np.mean([r.render(cam, m, RenderParams(), pass_index=k, passes=n).image
                    for k in range(n)], 0)
before, after, ref = mean(old, 4), mean(new, 4), mean(new, 16)
tiles = []
for name, img in (("4 passes, before", before), ("4 passes, centred", after),
                  ("16 passes, centred", ref)):
    tiles.append((name, tonemap_to_srgb8(img, 0.0, "pbr-neutral")))
for name, img in (("|before - 16| x4", before), ("|centred - 16| x4", after)):
    d = np.abs(img[..., :3] - ref[..., :3]).mean(-1) * 4 / max(ref[..., :3].mean(), 1e-6)
    tiles.append((name, (np.clip(d, 0, 1)[..., None].repeat(3, -1) * 255).astype(np.uint8)))
W = 192; sheet = Image.new("RGB", (W * 5 + 40, W + 22), (255, 255, 255)); dr = ImageDraw.Draw(sheet)
for i, (name, t) in enumerate(tiles):
    sheet.paste(Image.fromarray(np.ascontiguousarray(t[..., :3])), (i * (W + 10), 20))
    dr.text((i * (W + 10) + 2, 4), name, fill=(0, 0, 0))
sheet.save(sys.argv[1] if len(sys.argv) > 1 else
           Path(__file__).resolve().parents[2] / "docs" / "passes_centred.png")
