"""``scanlight render``: relight an asset with a point cloud (PBGI or the environment-map
baseline) and write a linear EXR, optionally a tone-mapped PNG and a stats JSON.

    scanlight render --cloud room.ply --object obj.json|model.glb|model.obj [--fit S]
                     [--translate X,Y,Z] [--rotate X,Y,Z] [--material mat.json] --camera cam.json
                     [--mode classic|mipmapped|hybrid|envmap] [--microbuffer 24] --out img.exr
                     [--png img.png --exposure 0 --tonemap pbr-neutral|aces|agx|clamp]
                     [--stats stats.json] [--size WxH]
                     [--background [--eye-dome on]] [--budget-mb 1024] [--omega-tr-factor 32]
                     [--parallax-tolerance 1] [--envmap-face 128] [--glossy-below 0.5]
                     [--passes 1] [--quality preview|balanced|final] [--render-scale 1]

``--object`` is a mesh opened directly (.glb/.gltf/.obj, or the built-in sphere/knot): in the
file's own units (glTF metres; OBJ read as metres) unless ``--fit S`` scales its largest extent to
S metres, rotated by ``--rotate``, stood on the scan's floor below the room's centre, then moved
by ``--translate`` (app/commands/asset_args.py, app/io/placement.py: how the floor is found); or
an object JSON with its own placement, for scripted use. The stats JSON's ``asset`` says where it
went (floor height, scale, bounds).

The rendering options and their defaults are the parameter table's (app/params.py, the same as
the viewer's; app/commands/options.py maps the flags).

PNG: exposure in stops, then the tone mapper of --tonemap (default Khronos PBR Neutral; aces,
agx, clamp: app.render.tonemap) and sRGB.
``--background`` composites the object over the room's point splats seen from the same camera,
with the asset's shadow and bounce on the scan (``--differential``, on by default:
app/pbgi/asset_scene.py); without it the background is black (alpha is in the PNG).
The ``--out`` EXR carries that alpha too (channels R, G, B, A; A = coverage, RGB premultiplied;
with ``--background``, the max of the object's and the splats' coverage).
``--layers L.exr`` also writes one multi-layer EXR for a compositor (``render_layers``): beauty,
asset, background, shadow, indirect, channels ``<layer>.R/G/B/A``, premultiplied linear. ``--passes N`` averages N renders
whose pixels sample N points inside each pixel, centred on it (app/pbgi/gbuffer.py:
pass_jitter), so edges and mirror images are anti-aliased and the glossy lobes' jitter averages
out; the radiance is then
premultiplied by the covered fraction (alpha). ``--render-scale S`` relights the asset at S of
the resolution and brings it back with the viewer's joint bilateral upsampling, guided by the
asset's full-resolution G-buffer (app/pbgi/upsample.py); alpha stays the full-resolution
coverage. ``--quality NAME`` sets the preset's values (app/params.py: QUALITY_PRESETS), explicit
flags winning. ``--material`` overrides every
material of the asset; without it the asset's own (glTF/MTL) materials are used.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from app.camera import MAX_PIXELS, parse_size
from app.commands.asset_args import add_object_arguments, check_object_args, load_placed_asset
from app.commands.options import add_param_options, param_values
from app.errors import UsageError
from app.render.alpha import over
from app.render.tonemap import get as tonemapper_named, tonemap_to_srgb8

log = logging.getLogger(__name__)


def add_arguments(parser) -> None:
    parser.add_argument("--cloud", required=True, metavar="C.ply", help="point cloud (PLY/PCD/XYZ)")
    add_object_arguments(parser)
    parser.add_argument("--material", metavar="M.json",
                        help="Disney material JSON for the whole asset (default: its own)")
    parser.add_argument("--camera", required=True, metavar="CAM.json", help="camera JSON")
    parser.add_argument("--out", required=True, metavar="IMG.exr", help="linear EXR output")
    parser.add_argument("--png", metavar="IMG.png", help="also a tone-mapped PNG")
    parser.add_argument("--stats", metavar="STATS.json", help="write timings and sizes as JSON")
    parser.add_argument("--size", metavar="WxH", help="override the camera's image size")
    parser.add_argument("--background", action="store_true",
                        help="composite over the room's point splats")
    parser.add_argument("--layers", metavar="LAYERS.exr",
                        help="also a multi-layer EXR for compositing: beauty, asset, background, "
                             "shadow (the asset's shadow/bounce on the scan), indirect (the "
                             "asset's light from itself); channels <layer>.R/G/B/A")
    parser.add_argument("--hdri", metavar="PANO.exr",
                        help="light the asset with this equirectangular HDR panorama instead of "
                             "the scan (distant light, gathered through the environment map; the "
                             "background shows it)")
    parser.add_argument("--hdri-rotation", type=float, default=0.0, metavar="DEG",
                        help="turn the HDRI about +y, counter-clockwise seen from above "
                             "(default 0: its centre column looks along -z)")
    parser.add_argument("--compare", nargs=2, metavar=("A", "B"),
                        help="render twice and write A | B side by side (--out), with the "
                             "difference and its legend (--png) and the metrics of B against A "
                             "(--stats); A and B are mode:NAME, quality:NAME, cloud:FILE or "
                             "hdri:FILE (app/commands/compare.py)")
    add_param_options(parser, "render")


def _check_args(args) -> dict:
    """The table's parameters from the command line (checked), after the file-name checks."""
    if Path(args.out).suffix.lower() != ".exr":
        raise UsageError(None, f"--out must name an .exr file, got {args.out!r}")
    if args.png and Path(args.png).suffix.lower() != ".png":
        raise UsageError(None, f"--png must name a .png file, got {args.png!r}")
    if args.layers and Path(args.layers).suffix.lower() != ".exr":
        raise UsageError(None, f"--layers must name an .exr file, got {args.layers!r}")
    if args.size:
        w, h = parse_size(args.size)
        if w * h > MAX_PIXELS:
            raise UsageError(None, f"--size {w}x{h} is larger than the limit of {MAX_PIXELS:,} "
                                   "pixels (8192x8192)")
    if not math.isfinite(args.hdri_rotation):
        raise UsageError(None, f"--hdri-rotation must be a finite angle, got {args.hdri_rotation}")
    values = param_values(args, "render")
    if args.compare:
        from app.commands.compare import parse_side
        for text in args.compare:
            parse_side(text)
        if args.layers:
            raise UsageError(None, "--layers and --compare cannot be combined: --compare writes "
                                   "its own side-by-side image")
    check_object_args(args)          # before the cloud loads: the flags, then the file
    return values


def run(args) -> int:
    from app.camera import load_camera
    from app.io.exr import write_exr
    from app.io.files import write_json
    from app.io.outputs import OutputSet, check_outputs
    from app.io.pointcloud import load_cloud
    from app.material import load_material
    from app.pbgi.renderer import Relighter, RenderParams, render_steps
    from app.pbgi.upsample import gi_scale_of, render_passes_of, render_upsampled
    from app.render.memory import check_render_memory

    values = _check_args(args)
    from app.commands.compare import input_files, parse_side
    check_outputs({"--cloud": args.cloud, "--object": args.object, "--material": args.material,
                   "--camera": args.camera, "--hdri": args.hdri,
                   **input_files([parse_side(t) for t in args.compare or ()])},
                  {"--out": args.out, "--png": args.png, "--stats": args.stats,
                   "--layers": args.layers})
    exposure = values["view.exposure"]
    tonemapper = values["view.tonemap"]
    camera = load_camera(args.camera)
    if args.size:
        w, h = parse_size(args.size)
        camera = replace(camera, width=w, height=h)
    check_render_memory(camera.width * (2 if args.compare else 1), camera.height)
    materials = [load_material(args.material)] if args.material else None
    cloud = load_cloud(args.cloud)
    mesh, asset = load_placed_asset(args, cloud)

    r = Relighter()
    r.set_cloud(cloud)
    r.set_asset(mesh)
    if args.hdri:
        from app.pbgi.hdri import load_hdri
        r.set_hdri(load_hdri(args.hdri, args.hdri_rotation))
    if args.compare:
        from app.commands.compare import run_compare
        from app.commands.options import given_values
        return run_compare(args, r, camera, materials, values, given_values(args, "render"),
                           {"cloud": str(args.cloud), "object": str(args.object),
                            "asset": asset, "camera": camera.to_dict(),
                            "renderer": r.ctx.info.get("GL_RENDERER"),
                            "tonemapper": tonemapper_named(tonemapper).title,
                            "exposure": exposure})
    params = RenderParams.from_settings(values)
    passes = render_passes_of(values, r.materials_for(materials))
    scale = gi_scale_of(values, r.materials_for(materials))
    edge_samples = int(values["pbgi.edge_samples"])
    steps = render_steps(passes, edge_samples if scale >= 1 else passes)

    def step(k, n, bar):
        bar.update()
        if passes > 1:
            log.info("pass %d/%d", k, n)

    from app.commands.progress import progress, quiet_of
    with progress(steps, "render", unit="pass", quiet=quiet_of(args)) as bar:
        res = render_upsampled(r, camera, materials, params, passes, scale,
                               edge_samples=edge_samples,
                               progress=lambda k, n: step(k, n, bar))
    img = res.image
    st = res.stats
    if not st.completed:
        log.warning("the render did not complete for every pixel (see stats: %s)",
                    {"incomplete_receivers": st.incomplete_receivers,
                     "gather_cut_short": st.gather_cut_short,
                     "nonfinite_pixels": st.nonfinite_pixels})
    rgba = img.copy()
    diff = None
    if (args.background or args.layers) and values["pbgi.differential"] and \
            params.mode != "envmap" and not args.hdri:
        t = time.perf_counter()
        diff = r.differential(materials, params)
        log.info("the asset's shadow and bounce on %d scan points: %.1f s", len(diff.index),
                 time.perf_counter() - t)
    if args.background:
        rgba = over(img, r.background(camera, diff, eye_dome=values["view.eye_dome"]))
    layers = None
    if args.layers:
        layers = render_layers(r, camera, materials, params, passes, img, diff, scale,
                               edge_samples)

    stats_diff = None if diff is None else {"points": int(len(diff.index)),
                                            "seconds": round(diff.seconds, 3)}

    stats = st.to_dict()                  # app.pbgi.stats.RenderStats, plus the run's inputs
    stats.update({"cloud": str(args.cloud), "points": len(cloud), "object": str(args.object),
                  "asset": asset,
                  "triangles": int(mesh.n_faces), "camera": camera.to_dict(),
                  "renderer": r.ctx.info.get("GL_RENDERER"),
                  "tonemapper": tonemapper_named(tonemapper).title, "exposure": exposure,
                  "differential": stats_diff,
                  "bsh": {k: v for k, v in r.hierarchy.stats.items()
                          if isinstance(v, (int, float, str))}})
    # every output to a temporary, then all renamed together (app/io/outputs.py)
    with OutputSet({"--out": args.out, "--png": args.png, "--stats": args.stats,
                    "--layers": args.layers}) as outs:
        write_exr(outs.temp("--out"), rgba)
        if args.png:
            from app.io.images import write_png
            write_png(outs.temp("--png"), tonemap_to_srgb8(rgba, exposure, tonemapper))
        if args.stats:
            write_json(outs.temp("--stats"), stats)
        if layers is not None:
            from app.io.exr import write_exr_layers
            write_exr_layers(outs.temp("--layers"), layers)
    if st.envmap_instead_of:
        log.info("the environment map rendered this frame instead of %s: the asset is %.1f "
                 "radii from every scan point (pbgi.envmap_beyond %g; 0 keeps the near field)",
                 st.envmap_instead_of, st.clearance, params.envmap_beyond)
    print(f"rendered {camera.width}x{camera.height} ({st.mode}"
          + (f" for {st.envmap_instead_of}" if st.envmap_instead_of else "")
          + f", M={params.microbuffer}"
          + (f", {passes} passes" if passes > 1 else "")
          + (f", GI at {scale:g} of the resolution" if scale < 1 else "") + ") in "
          f"{st.ms:.0f} ms: {args.out}" + (f", {args.png}" if args.png else ""))
    return 0


def render_layers(r, camera, materials, params, passes: int, asset: np.ndarray,
                  diff, scale: float = 1.0, edge_samples: int = 1) -> dict:
    """The compositing layers (premultiplied RGBA, linear; see the module docstring):
    beauty = asset over the background with the asset's shadow; asset = the relit asset alone
    (alpha = coverage); background = the scan's splats as scanned; shadow = what the asset
    does to them (signed: negative in its shadow, positive where its bounce lands; alpha = the
    splats' coverage); indirect = the part of the asset's light that came from itself (its
    surfels' bounce; a second render of the same cut without the bounce, zero when the bounce
    is off)."""
    plate = r.background(camera)
    lit = r.background(camera, diff) if diff is not None else plate
    shadow = lit.copy()
    shadow[..., :3] = lit[..., :3] - plate[..., :3]
    indirect = np.zeros_like(asset)
    indirect[..., 3] = asset[..., 3]
    if params.asset_bounces > 0 and r.walks_asset(params):   # else no bounce to take out
        from app.pbgi.upsample import render_upsampled
        dark = render_upsampled(r, camera, materials, replace(params, asset_bounces=0), passes,
                                scale, edge_samples=edge_samples)
        indirect[..., :3] = asset[..., :3] - dark.image[..., :3]
    return {"beauty": over(asset, lit), "asset": asset, "background": plate,
            "shadow": shadow, "indirect": indirect}


__all__ = ["add_arguments", "run", "over", "render_layers"]
