"""``scanlight render --compare A B``: the same asset and camera rendered twice, side by side,
with a difference image and its metrics - the question a look-dev artist asks before trusting a
setting ("is the preview close enough?", "what did the expansion change?", "how far is the scan's
light from a plain HDRI?").

A side is ``mode:NAME`` (a render mode), ``quality:NAME`` (a preset of app/params.py),
``cloud:FILE`` (another cloud lighting the asset: e.g. the LDR scan against its HDR expansion)
or ``hdri:FILE`` (an equirectangular EXR lighting the asset instead of the scan, rotated by
``--hdri-rotation``). Everything a side does not name is the command line's.

Outputs (the render command's, written together): ``--out`` a linear RGBA EXR of A and B side
by side; ``--png`` the two tone-mapped, then the difference in false colour with its legend;
``--stats`` both renders' stats and the metrics. The metrics are B against A (A is the
reference): relative RMSE per pixel and 4x4-pooled over the pixels both cover
(app/bench/image_metrics.py, the reference protocol's) and HDR-FLIP when flip-evaluator is
installed. The difference image shows |B - A| / mean luminance of A per pixel (the relative
RMSE's summand), from 0 (black) to DIFF_FULL_SCALE (white) on the inferno-like ramp below.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.errors import UsageError
from app.params import QUALITY_PRESETS, RENDER_MODES

KINDS = ("mode", "quality", "cloud", "hdri")
DIFF_FULL_SCALE = 0.5      # 50% of the reference's mean luminance is white
LEGEND_HEIGHT = 28         # pixels under the sheet: the ramp and its labels
# a perceptually ordered ramp (black - purple - orange - yellow - white), linear between stops
RAMP = np.array([[0, 0, 0], [60, 15, 110], [185, 55, 85], [250, 140, 10], [250, 250, 160],
                 [255, 255, 255]], np.float64) / 255.0


@dataclass(frozen=True)
class Side:
    kind: str
    value: str

    @property
    def label(self) -> str:
        v = Path(self.value).name if self.kind in ("cloud", "hdri") else self.value
        return f"{self.kind}:{v}"


def parse_side(text: str) -> Side:
    kind, sep, value = text.partition(":")
    if not sep or kind not in KINDS or not value:
        raise UsageError(None, f"--compare: {text!r} is not KIND:VALUE with KIND one of "
                               f"{', '.join(KINDS)} (e.g. mode:classic, quality:preview, "
                               "cloud:room_hdr.ply, hdri:studio.exr)")
    if kind == "mode" and value not in RENDER_MODES:
        raise UsageError(None, f"--compare: unknown mode {value!r} (one of "
                               f"{', '.join(RENDER_MODES)})")
    if kind == "quality" and value not in QUALITY_PRESETS:
        raise UsageError(None, f"--compare: unknown quality {value!r} (one of "
                               f"{', '.join(QUALITY_PRESETS)})")
    return Side(kind, value)


def side_values(side: Side, values: dict, given: dict) -> dict:
    """The parameter values of one side: the command line's, with the side's mode or preset
    (a preset does not override the flags given explicitly, as with --quality)."""
    out = dict(values)
    if side.kind == "mode":
        out["pbgi.mode"] = side.value
    elif side.kind == "quality":
        for key, value in QUALITY_PRESETS[side.value].items():
            if key in out and key not in given:
                out[key] = value
    return out


def input_files(sides) -> dict:
    """Flag-like names of the sides' files, for check_outputs (never overwrite an input)."""
    return {f"--compare {s.kind}": s.value for s in sides if s.kind in ("cloud", "hdri")}


def ramp(t: np.ndarray) -> np.ndarray:
    """[0, 1] -> RGB in [0, 1] on RAMP."""
    x = np.clip(np.asarray(t, np.float64), 0, 1) * (len(RAMP) - 1)
    i = np.minimum(np.floor(x).astype(int), len(RAMP) - 2)
    f = (x - i)[..., None]
    return RAMP[i] * (1 - f) + RAMP[i + 1] * f


def metrics(a: np.ndarray, b: np.ndarray) -> dict:
    """B against A over the pixels both cover (alpha > 0.5)."""
    from app.bench import image_metrics as im
    mask = (a[..., 3] > 0.5) & (b[..., 3] > 0.5)
    out = {"pixels": int(mask.sum())}
    if not mask.any():
        return out
    out["rel_rmse"] = im.relative_rmse(b, a, mask, 1)
    try:
        out["rel_rmse_4x4"] = im.relative_rmse(b, a, mask, 4)
    except ValueError:          # no 4x4 block wholly covered (a tiny image)
        out["rel_rmse_4x4"] = None
    flip = im.flip(b, a, mask)
    out["flip"] = flip
    la, lb = a[..., :3][mask] @ im.LUMA, b[..., :3][mask] @ im.LUMA
    out["mean_luminance_ratio"] = float(lb.mean() / max(la.mean(), 1e-30))
    return out


def difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|B - A| (RGB norm) / A's mean luminance per pixel, 0 where neither covers."""
    from app.bench.image_metrics import LUMA
    cover = (a[..., 3] > 0.5) | (b[..., 3] > 0.5)
    ref = a[..., :3][cover] @ LUMA if cover.any() else np.ones(1)
    d = np.linalg.norm(b[..., :3] - a[..., :3], axis=-1) / max(float(ref.mean()), 1e-30)
    return np.where(cover, d, 0.0)


def _legend(width: int) -> np.ndarray:
    """The ramp with "0" and the full scale written under it, (LEGEND_HEIGHT, width, 3) uint8."""
    from PIL import Image, ImageDraw
    bar = (ramp(np.linspace(0, 1, width))[None] * 255).repeat(10, axis=0)
    img = Image.new("RGB", (width, LEGEND_HEIGHT), (0, 0, 0))
    img.paste(Image.fromarray(bar.astype(np.uint8)), (0, 0))
    draw = ImageDraw.Draw(img)
    draw.text((2, 12), "0", fill=(255, 255, 255))
    right = f"{DIFF_FULL_SCALE:.0%} of A's mean"
    draw.text((max(width - 6 * len(right) - 2, 14), 12), right, fill=(255, 255, 255))
    return np.asarray(img)


def sheet(a: np.ndarray, b: np.ndarray, exposure: float,
          tonemapper: str = "pbr-neutral") -> np.ndarray:
    """[A | B | difference] tone-mapped, a legend under the difference, (h + legend, 3w, 3)."""
    from app.render.tonemap import tonemap_to_srgb8
    h, w = a.shape[:2]
    ta = tonemap_to_srgb8(a[..., :3], exposure, tonemapper)
    tb = tonemap_to_srgb8(b[..., :3], exposure, tonemapper)
    td = np.round(ramp(difference(a, b) / DIFF_FULL_SCALE) * 255).astype(np.uint8)
    out = np.zeros((h + LEGEND_HEIGHT, 3 * w, 3), np.uint8)
    out[:h] = np.concatenate([ta, tb, td], axis=1)
    out[h:, 2 * w:] = _legend(w)
    return out


def load_side_inputs(sides, hdri_rotation: float) -> dict:
    """Each side's cloud or HDRI, loaded before anything renders (a bad file: exit 3, nothing
    written)."""
    from app.io.pointcloud import load_cloud
    from app.pbgi.hdri import load_hdri
    out = {}
    for s in sides:
        if s.kind == "cloud":
            out[s] = load_cloud(s.value)
        elif s.kind == "hdri":
            out[s] = load_hdri(s.value, hdri_rotation)
    return out


def render_side(r, side: Side, loaded, camera, materials, values: dict, given: dict,
                background: bool):
    """One side's render (RenderResult-like: image, stats) on the shared Relighter; the scan,
    or an HDRI the command line set, is restored afterwards."""
    from app.render.alpha import over
    from app.pbgi.renderer import RenderParams
    from app.pbgi.upsample import gi_scale_of, render_passes_of, render_upsampled
    vals = side_values(side, values, given)
    cloud, hdri = r.cloud, r.hdri
    if side.kind == "cloud":
        r.set_cloud(loaded)
    elif side.kind == "hdri":
        r.set_hdri(loaded)
    try:
        res = render_upsampled(r, camera, materials, RenderParams.from_settings(vals),
                               render_passes_of(vals, r.materials_for(materials)),
                               gi_scale_of(vals, r.materials_for(materials)),
                               edge_samples=int(vals["pbgi.edge_samples"]))
        image = over(res.image, r.background(camera)) if background else res.image
        return image, res.stats
    finally:
        if side.kind == "cloud":
            r.set_cloud(cloud)
        elif side.kind == "hdri":
            r.set_hdri(hdri)


def run_compare(args, r, camera, materials, values: dict, given: dict, extra_stats: dict) -> int:
    """``render --compare A B`` after the cloud and asset are set on ``r``: both renders, then
    the EXR, PNG sheet and stats written together (app/io/outputs.py)."""
    from app.io.exr import write_exr
    from app.io.files import write_json
    from app.io.outputs import OutputSet
    sides = [parse_side(t) for t in args.compare]
    loaded = load_side_inputs(sides, float(args.hdri_rotation))
    images, stats = [], []
    for side in sides:
        img, st = render_side(r, side, loaded.get(side), camera, materials, values, given,
                              args.background)
        images.append(img)
        stats.append(st.to_dict())
    a, b = images
    found = metrics(a, b)
    report = dict(extra_stats)
    report["compare"] = {"a": sides[0].label, "b": sides[1].label, "metrics": found,
                         "a_stats": stats[0], "b_stats": stats[1],
                         "difference_full_scale": DIFF_FULL_SCALE}
    with OutputSet({"--out": args.out, "--png": args.png, "--stats": args.stats}) as outs:
        write_exr(outs.temp("--out"), np.concatenate([a, b], axis=1))
        if args.png:
            from app.io.images import write_png
            write_png(outs.temp("--png"), sheet(a, b, values["view.exposure"],
                                                values["view.tonemap"]))
        if args.stats:
            write_json(outs.temp("--stats"), report)
    err = found.get("rel_rmse")
    pooled = found.get("rel_rmse_4x4")
    print(f"compared {sides[0].label} (A) with {sides[1].label} (B) at {camera.width}x"
          f"{camera.height}: " + ("no pixel covered by both" if err is None else
                                   f"relative RMSE {err:.1%}"
                                   + (f", 4x4-pooled {pooled:.1%}" if pooled is not None else "")
                                   + f", mean luminance B/A {found['mean_luminance_ratio']:.3f}")
          + f": {args.out}" + (f", {args.png}" if args.png else ""))
    return 0


__all__ = ["KINDS", "Side", "parse_side", "side_values", "input_files", "load_side_inputs",
           "render_side", "run_compare", "metrics", "difference", "ramp", "sheet",
           "DIFF_FULL_SCALE"]
