"""``scanlight bench glossy``: glossy and mirror materials against the path-traced references.

The scene (``glossy_scene``, also what tests/pbgi/make_references.py renders in Mitsuba and what
tests/pbgi/test_glossy_sweep.py checks): a room built from a real panorama (../shared/data, the
``box_points`` room of app/bench/panorama_rooms.py, lit only by its 100k points) and a sphere of
radius 0.6 in it, seen from 1 m at 96 x 96 px. Materials: a gold metal and a grey dielectric at
each roughness of ``ROUGHNESS``.

Per case (kind, roughness, mode): ``ms`` (one frame, the fastest of ``--repeat``, never a reuse of
the previous cut), ``ms_vs_diffuse`` (over the same mode's frame of the dielectric at roughness 1,
which needs no lobe micro-buffer: the cost of glossiness), ``ms_lobe``, and the reference
protocol's errors (app/bench/image_metrics.py) over the sphere's pixels (its silhouette eroded by
one pixel: a pixel on the rim mixes the room behind it in the reference): ``rel_rmse`` per pixel,
``rel_rmse_4x4`` pooled, ``flip`` (HDR-FLIP, NaN without ``flip-evaluator``), ``periodic_peak``
(the artefact detector) and ``peak_ratio`` (largest pixel over the reference's). ``--before``
adds the same cases with ``glossy_below`` 0: the cosine micro-buffer alone, the renderer before
the lobe micro-buffers. ``--images`` writes them side by side with the references (the README's
docs/glossy_sweep.png).
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from app.bench.records import record
from app.commands.options import add_param_options, param_values
from app.errors import UsageError

log = logging.getLogger(__name__)

ROOM = "../shared/data/apartment.exr"
SIZE = 96
POINTS = 100_000
ROUGHNESS = (0.0, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 1.0)
KINDS = ("metal", "dielectric")
SPHERE = {"radius": 0.6, "below_centre": 0.6}
REFERENCES = Path(__file__).resolve().parents[2] / "tests" / "pbgi" / "references"
INDEX = "references.json"
MASK_ERODE = 1


def material(kind: str, roughness: float):
    """The sweep's materials: gold metal (the built-in preset's colour) or a grey dielectric."""
    from app.material import Material
    if kind == "metal":
        return Material(base_color=(0.95, 0.64, 0.37), metallic=1.0, roughness=roughness)
    if kind == "dielectric":
        return Material(base_color=(0.6, 0.6, 0.6), metallic=0.0, roughness=roughness)
    raise ValueError(f"unknown material kind {kind!r}")


def glossy_scene(room_exr, size: int = SIZE, points: int = POINTS):
    """(cloud, mesh, camera) of the sweep: the panorama's colours on the room box's points."""
    from app.bench.panorama_rooms import CENTRE, box_points, sample_panorama
    from app.camera import Camera
    from app.cloud import PointCloud
    from app.io.exr import read_exr
    from app.io.formats import object_from_dict, placed_mesh

    pano = np.asarray(read_exr(room_exr).rgb, dtype=np.float32)
    pos, nrm = box_points(points, 0)
    cloud = PointCloud(pos, nrm, sample_panorama(pano, pos - CENTRE), hdr=True,
                       source=str(room_exr))
    c = np.asarray(CENTRE, float) - (0.0, SPHERE["below_centre"], 0.0)
    mesh = placed_mesh(object_from_dict({"mesh": "sphere", "translate": c.tolist(),
                                         "scale": SPHERE["radius"]}, "."))
    cam = Camera(c + np.array([0.0, 0.15, 1.0]), c, fov_y_deg=45, width=size, height=size)
    return cloud, mesh, cam


def reference_name(room: str, kind: str, roughness: float) -> str:
    return f"{room}_{kind}_r{roughness:.2f}.exr"


def load_index(directory=REFERENCES) -> dict:
    from app.bench.mitsuba_scene import read_index
    return read_index(directory, "tests/pbgi/make_references.py")


def load_reference(room: str, kind: str, roughness: float, directory=REFERENCES) -> np.ndarray:
    from app.bench.mitsuba_scene import read_reference
    return read_reference(Path(directory) / reference_name(room, kind, roughness))


def evaluate(image: np.ndarray, reference: np.ndarray) -> dict:
    """The protocol's errors of ``image`` (h, w, 4: radiance, coverage) over the sphere."""
    from app.bench import image_metrics as im
    mask = im.erode(image[..., 3] > 0.5, MASK_ERODE)
    flip = im.flip(image, reference, mask)
    return {"rel_rmse": im.relative_rmse(image, reference, mask, 1),
            "rel_rmse_4x4": im.relative_rmse(image, reference, mask, 4),
            "flip": float("nan") if flip is None else flip,
            "periodic_peak": im.periodic_peak(image, reference, mask),
            "peak_ratio": im.peak_ratio(image, reference, mask)}


def _floats(text: str, name: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UsageError(None, f"--{name} must be a comma-separated list of numbers, "
                               f"got {text!r}") from None
    if not vals or any(not 0.0 <= v <= 1.0 for v in vals):
        raise UsageError(None, f"--{name} must list numbers in [0, 1], got {text!r}")
    return vals


def add_arguments(parser) -> None:
    parser.add_argument("--room", default=ROOM, metavar="PANO.exr",
                        help=f"the panorama whose references exist (default {ROOM})")
    parser.add_argument("--references", default=str(REFERENCES), metavar="DIR",
                        help="the committed references (tests/pbgi/references)")
    parser.add_argument("--roughness", default=",".join(map(str, ROUGHNESS)),
                        help="comma-separated roughness values among the references'")
    parser.add_argument("--kinds", default=",".join(KINDS), help="metal,dielectric")
    parser.add_argument("--modes", default="classic,mipmapped,hybrid",
                        help="render modes (default classic,mipmapped,hybrid)")
    parser.add_argument("--repeat", type=int, default=2, help="runs per case, the fastest kept")
    parser.add_argument("--before", action="store_true",
                        help="also the cosine micro-buffer alone (glossy_below 0)")
    parser.add_argument("--images", metavar="PNG",
                        help="also write a contact sheet: per material kind, rows reference / "
                             "lobe (this renderer) / cosine only (before), columns roughness, "
                             "in the first mode")
    add_param_options(parser, "bench glossy")     # --microbuffer, --lobe-only-microbuffer


def run(args) -> list[dict]:
    from app.params import BY_KEY, RENDER_MODES
    from app.pbgi.renderer import Relighter, RenderParams

    rough = _floats(args.roughness, "roughness")
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    if not kinds or any(k not in KINDS for k in kinds):
        raise UsageError(None, f"--kinds must be among {', '.join(KINDS)}, got {args.kinds!r}")
    if not modes or any(m not in RENDER_MODES for m in modes):
        raise UsageError(None, f"--modes must be among {', '.join(RENDER_MODES)}, "
                               f"got {args.modes!r}")
    values = param_values(args, "bench glossy")
    m, lobe_only_m = values["pbgi.microbuffer"], values["pbgi.lobe_only_microbuffer"]
    if args.repeat < 1:
        raise UsageError(None, "--repeat must be >= 1")
    room = Path(args.room).stem
    index = load_index(args.references)
    for kind in kinds:
        for r in rough:
            if reference_name(room, kind, r) not in index.get("references", {}):
                raise UsageError(None, f"no reference for {room} {kind} roughness {r:g} in "
                                       f"{args.references}")

    cloud, mesh, cam = glossy_scene(args.room)
    rl = Relighter()
    rl.set_cloud(cloud)
    rl.set_asset(mesh)
    variants = [("lobe", BY_KEY["pbgi.glossy_below"].default)]
    if args.before:
        variants.append(("cosine only", 0.0))
    for mode in modes:                  # compile and warm every program before timing
        rl.render(cam, [material("metal", 0.1)], RenderParams(mode=mode, microbuffer=m))

    def frame(mode, mat, gb):
        best = None
        for _ in range(args.repeat):
            rl.forget_microbuffers()
            res = rl.render(cam, [mat], RenderParams(mode=mode, microbuffer=m,
                                                     glossy_below=gb,
                                                     lobe_only_microbuffer=lobe_only_m))
            if best is None or res.stats.ms < best.stats.ms:
                best = res
        return best

    records, sheet = [], {}
    for mode in modes:
        diffuse_ms = frame(mode, material("dielectric", 1.0), 0.0).stats.ms
        for name, gb in variants:
            for kind in kinds:
                for r in rough:
                    res = frame(mode, material(kind, r), gb)
                    ref = load_reference(room, kind, r, args.references)
                    if mode == modes[0]:
                        sheet[(kind, "reference", r)] = ref
                        sheet[(kind, name, r)] = res.image[..., :3]
                    err = evaluate(res.image, ref)
                    noise = index["references"][reference_name(room, kind, r)]
                    records.append(record("glossy", {"room": room, "variant": name,
                                                     "mode": mode, "kind": kind, "roughness": r},
                                          {"ms": res.stats.ms,
                                           "ms_vs_diffuse": res.stats.ms / diffuse_ms,
                                           "ms_lobe": res.stats.ms_lobe, **err,
                                           "ref_noise_4x4": noise["noise_rel_rmse_4x4"],
                                           "completed": float(res.stats.completed)}))
                    log.info("%s %s %s r=%g: %.0f ms, %.1f%% (4x4)", name, mode, kind, r,
                             res.stats.ms, 100 * err["rel_rmse_4x4"])
    rl.release()
    if args.images:
        write_sheet(args.images, sheet, kinds, [("reference", None)] + variants, rough)
    return records


def write_sheet(path, images: dict, kinds, variants, roughness) -> None:
    """One PNG: a row per (kind, variant), a column per roughness, tone mapped alike (PBR
    Neutral, exposure from the references' 99th percentile)."""
    from app.io.images import write_png
    from app.render.tonemap import tonemap_to_srgb8
    rows = []
    for kind in kinds:
        refs = [images[(kind, "reference", r)] for r in roughness]
        ev = -float(np.log2(max(np.percentile(np.concatenate([x.ravel() for x in refs]), 99),
                                1e-6)))
        for name, _ in variants:
            if (kind, name, roughness[0]) in images:
                rows.append(np.concatenate([tonemap_to_srgb8(images[(kind, name, r)], ev)
                                            for r in roughness], axis=1))
    write_png(path, np.concatenate(rows, axis=0))
