"""The headless demo (``scanlight demo``): every stage of Scanlight on the built-in room.

1. the scene as real files (LDR scan and ground truth as PLY, the HDR photo as EXR, object,
   views and capture cameras as JSON) - the same files the other commands take;
2. HDR expansion of the LDR scan from the photo (PatchMatch, colour transfer), with point RMS
   against the ground truth;
3. the sphere relit by the LDR, expanded and ground-truth clouds (Hybrid PBGI, or Classic where
   Hybrid is unavailable), composited over the room, with the relit-render error (Table 2);
4. the room itself as point splats: LDR, HDR, ground truth and the difference map (paper
   Fig. 1);
5. the asset (diffuse and glossy) lit by the expanded cloud in every render mode, and
   ``contact_sheet.png``: all of the above on one labelled sheet (app/demo/contact_sheet.py).

Every PNG goes through ``run_demo``'s ``tonemapper`` (one of app.render.tonemap.TONEMAPPERS;
default Khronos PBR Neutral, the viewer's default), named in the report; the EXRs are linear.
"""

from __future__ import annotations

import logging
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from app.demo import room
from app.demo.cache import load_demo
from app.io.files import write_json
from app.render.tonemap import DEFAULT as DEFAULT_TONEMAP, get as tonemap_get

log = logging.getLogger(__name__)

DEFAULT_SIZE = 192        # px of the renders: legible on the contact sheet (README: timings)
SIZE_RANGE = (16, 4096)   # `demo --size`: 16 px still shows the sphere; 4096 is within every
                          # camera limit (app.io.limits)
# `demo --points`: below 10,000 points the photo sees too few scan points to register (the
# expansion then refuses it as another room's); 5 M is five times the expansion bench's 1 M case
POINTS_RANGE = (10_000, 5_000_000)
HDR_ROOM_EXPOSURE = -2.0  # EV of the HDR and ground-truth room PNGs: lights 4-6 stops over 1

_last_stage = [None]


def _progress(fraction: float, stage: str) -> None:
    """A live percentage on a terminal; one line per stage in a log file."""
    if sys.stderr.isatty():
        print(f"\r  expanding: {stage:<12s} {100 * fraction:5.1f}%", end="", file=sys.stderr, flush=True)
    elif stage != _last_stage[0]:
        _last_stage[0] = stage
        print(f"  expanding: {stage} ({100 * fraction:.0f}%)", file=sys.stderr, flush=True)


def _save_png(path: Path, linear_rgb: np.ndarray, exposure: float = 0.0,
              tonemapper: str = DEFAULT_TONEMAP) -> None:
    from app.io.images import write_png
    from app.render.tonemap import tonemap_to_srgb8
    write_png(path, tonemap_to_srgb8(linear_rgb, exposure, tonemapper))


def _over(rgba: np.ndarray, background: np.ndarray) -> np.ndarray:
    """The asset's render (A = coverage) over the room behind it."""
    return rgba[..., :3] * rgba[..., 3:] + background * (1 - rgba[..., 3:])


def _mode_renders(relighter, cloud, cam) -> tuple[dict, dict]:
    """({(material kind, mode): linear image over the room}, {material kind: passes}): the
    asset lit by ``cloud`` in every render mode, for the contact sheet's material rows, each
    the mean of the passes `scanlight render` gives that material by default
    (app/pbgi/upsample.py: render_passes_of - the gold's lobe noise averaged over 4)."""
    from app.demo.contact_sheet import ASSET_MATERIALS
    from app.material import PRESETS, material_from_dict
    from app.params import BY_KEY, RENDER_MODES
    from app.pbgi.renderer import RenderParams
    from app.pbgi.upsample import render_passes_of
    relighter.set_cloud(cloud)              # same points as the last cloud: recolours the BSH
    background = relighter.splat_renderer().render(cam)[..., :3]
    defaults = {k: param.default for k, param in BY_KEY.items()}
    out, passes = {}, {}
    for kind, preset in ASSET_MATERIALS.items():
        mat = material_from_dict({"name": preset, **PRESETS[preset]})
        passes[kind] = render_passes_of(defaults, [mat])
        for mode in RENDER_MODES:
            img = relighter.render_passes(cam, [mat], RenderParams(mode=mode, microbuffer=16),
                                          passes[kind]).image
            out[(kind, mode)] = _over(img, background)
    return out, passes


def write_scene_files(out: Path, scene: room.DemoScene, size: int) -> dict:
    """The demo as the files the CLI commands take; returns their paths."""
    from app.io.exr import write_exr
    from app.io.pointcloud import save_cloud
    files = {"ldr": out / "room_ldr.ply", "gt": out / "room_gt.ply", "photo": out / "photo.exr",
             "object": out / "object.json", "capture": out / "capture_cameras.json"}
    save_cloud(scene.ldr, files["ldr"])
    save_cloud(scene.gt, files["gt"])
    write_exr(files["photo"], scene.photo)
    write_json(files["object"], room.default_object("sphere"))
    write_json(files["capture"], [{"position": list(p)} for p in scene.capture_positions])
    for name, cam in room.default_views(size, size).items():
        files[f"camera_{name}"] = out / f"camera_{name}.json"
        write_json(files[f"camera_{name}"], cam.to_dict())
    return files


def run_demo(out: Path, size: int = DEFAULT_SIZE, n_points: int = 200_000,
             face_size: int | None = None, tonemapper: str = DEFAULT_TONEMAP) -> dict:
    """Every stage on the demo scene; ``face_size`` None: the table's ``hdr.face_size``;
    ``tonemapper``: the PNGs' tone mapper (default PBR Neutral)."""
    from app.hdr.evaluate import expansion_errors
    from app.hdr.pipeline import ExpandParams, run_expansion
    from app.io.formats import object_from_dict, placed_mesh
    from app.pbgi.compare import relit_errors, scaled
    from app.pbgi.renderer import Relighter

    tonemap_get(tonemapper)                       # an unknown name fails before any work
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    timings, summary = {}, []
    t = time.perf_counter()
    scene = load_demo(n_points)
    files = write_scene_files(out, scene, size)
    timings["scene_s"] = time.perf_counter() - t

    t = time.perf_counter()
    params = ExpandParams(method="pmatch-rgb")     # the demo's (documented) method
    if face_size is not None:
        params = replace(params, face_size=face_size)
    exp = run_expansion(scene.ldr, scene.photo, list(scene.capture_positions), params=params,
                        progress=_progress)
    if sys.stderr.isatty():
        print(file=sys.stderr)
    timings["expand_s"] = time.perf_counter() - t
    from app.io.pointcloud import save_cloud
    save_cloud(exp.cloud, out / "room_hdr.ply")
    point_err = expansion_errors(exp.cloud, scene.gt, scene.ldr, exposure=scene.alpha)
    summary.append(f"exposure found {exp.report.get('alpha', float('nan')):.3f} "
                   f"(scan used {scene.alpha:.3f})")
    summary.append(f"point RMS on overexposed points: expanded {point_err['rms_overexposed']:.3f}, "
                   f"LDR {point_err['ldr_rms_overexposed']:.3f} (ground-truth units)")

    t = time.perf_counter()
    mode = "hybrid"
    mesh = placed_mesh(object_from_dict(room.default_object("sphere"), out, "demo object"))
    clouds = {"expanded": scaled(exp.cloud, scene.alpha), "ldr": scaled(scene.ldr, scene.alpha)}
    relighter = Relighter()
    renders, backgrounds, closeups = {}, {}, {}
    for view, cam in room.default_views(size, size).items():
        errs, images = relit_errors(clouds, scene.gt, mesh, cam, mode=mode, relighter=relighter)
        renders[view] = errs
        background = backgrounds[view] = relighter.splat_renderer().render(cam)[..., :3]
        if view == "closeup":
            closeups = images
        for name, img in images.items():
            comp = _over(img, background)
            from app.io.exr import write_exr
            write_exr(out / f"relit_{view}_{name}.exr", img)   # RGBA: A = coverage
            _save_png(out / f"relit_{view}_{name}.png", comp, tonemapper=tonemapper)
    timings["relight_s"] = time.perf_counter() - t
    for view, errs in renders.items():
        summary.append(f"relit {view} ({mode}), relative RMS vs ground-truth lighting: "
                       f"expanded {errs['expanded']['render_rel_rms']:.3f}, "
                       f"LDR {errs['ldr']['render_rel_rms']:.3f}")

    # The room itself: LDR / HDR / ground truth / difference (paper Fig. 1), seen from a top
    # corner so that the clipped ceiling light and window are in view.
    from app.render.splat import SplatRenderer
    cam = room.overview_camera(size, size)
    splat = SplatRenderer(exp.cloud)
    hdr_img = splat.render(cam)[..., :3] / scene.alpha
    splat.set_colors(scene.ldr.colors)
    ldr_img = splat.render(cam)[..., :3] / scene.alpha
    splat.set_colors(scene.gt.colors)
    gt_img = splat.render(cam)[..., :3]
    _save_png(out / "room_ldr.png", ldr_img, tonemapper=tonemapper)
    _save_png(out / "room_hdr.png", hdr_img, exposure=HDR_ROOM_EXPOSURE, tonemapper=tonemapper)
    _save_png(out / "room_gt.png", gt_img, exposure=HDR_ROOM_EXPOSURE, tonemapper=tonemapper)
    _save_png(out / "room_difference.png", np.abs(hdr_img - ldr_img), tonemapper=tonemapper)
    splat.release()

    t = time.perf_counter()
    modes, mode_passes = _mode_renders(relighter, clouds["expanded"],
                                       room.default_views(size, size)["closeup"])
    timings["modes_s"] = time.perf_counter() - t
    from app.demo.contact_sheet import demo_sheet
    from app.io.images import write_png
    relit = {name: _over(img, backgrounds["closeup"]) for name, img in closeups.items()}
    sheet, layout = demo_sheet({"ldr": ldr_img, "hdr": hdr_img, "gt": gt_img}, relit, modes,
                               tonemapper, HDR_ROOM_EXPOSURE, mode, size, mode_passes)
    write_png(out / "contact_sheet.png", sheet)

    return {"scene": {k: str(v) for k, v in files.items()}, "points": len(scene.gt),
            "alpha": scene.alpha, "expansion": exp.report, "point_errors": point_err,
            "render_mode": mode, "render_errors": renders, "mode_passes": mode_passes,
            "timings": timings, "summary": summary,
            "tonemapper": tonemap_get(tonemapper).title, "tonemap": tonemapper,
            "contact_sheet": {"file": str(out / "contact_sheet.png"), "size": layout.size,
                              "tiles": layout.tiles, "lines": layout.lines}}
