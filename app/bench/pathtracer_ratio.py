"""``scanlight bench pathtracer-ratio``: how much faster PBGI is than Mitsuba 3 path tracing at
equal per-pixel error (issue 19).

Cases: room (``demo``, ``apartment``: the trade-off bench's rooms, app/bench/tradeoff.py) x
asset (``sphere``: each room's own; ``bunny``: ../shared/data/bunny.glb, centred where the
sphere is and as wide as its diameter) x material (diffuse, rough metal 0.6: the trade-off's)
x view (``closeup``: the room's trade-off camera; ``whole``: the object and its surroundings)
x setting (the quality presets preview / balanced / final of app/params.py, and the modes
Classic and Hybrid at M = 16), at ``--viewport`` (256).

Ours: the median of ``--frames`` warm frames (tradeoff.measure: the micro-buffers never reused)
and the relative RMSE per pixel (app/bench/image_metrics.py) over the asset's pixels, its
silhouette eroded by one pixel, against a high-spp Mitsuba reference of the same scene
(app/bench/mitsuba_scene.py; ``max_depth`` 2 for the convex sphere, 3 for the bunny, whose one
diffuse inter-reflection our surfels carry), cached on disk with the trade-off's references.

The path tracer: the same Mitsuba scene (``scalar_rgb``, all cores, scene loading excluded,
one 1-spp render first to start its threads) at each spp of ``--sweep`` (4, 16, 64), each
image's per-pixel error against the reference measured on the same pixels. The fit
(``fit_noise``): a Monte Carlo image of s samples per pixel has squared error a^2 / s exactly in
expectation, and measured against a reference of S samples (independent noise, same renderer,
no bias) err^2 = a^2 (1/s + 1/S): the reference's own noise a / sqrt(S) is the only floor, and
it is subtracted in quadrature instead of fitted as a free floor (three points cannot spare a
degree of freedom for a quantity the model already gives). The one parameter a^2 is fitted in
log space (the geometric mean of err^2 / (1/s + 1/S)): every err^2 is a mean over the same
pixels, so each has about the same *relative* uncertainty; least squares on err^2 itself would
let the 4-spp point, 16x larger, decide alone. The free log-log slope of the corrected errors
is recorded as a check (``pt_slope``, -0.5 expected), and so is the reference's noise measured
from its two independent halves (``ref_noise_halves``), which the model's a / sqrt(S) should
match.

Equal error (``equal_error``): our error is measured against the same noisy reference, so its
true part is e = sqrt(err^2 - a^2/S); the path tracer reaches it at s = a^2 / e^2 samples, in
s x (measured seconds per spp) seconds; ratio = that / our frame time. Past S samples this is
an extrapolation of an exact law, and how far it can go is decided by the data: the pixels are
resampled (a bootstrap of ``DRAWS``, the same pixels for our image and every sweep image, as
they share the reference's noise), the fit and the solve redone on each, and the row gets a
ratio only where the 16th-84th percentile interval of s spans at most a factor ``RESOLVE``
(2); the table shows that interval. Elsewhere our error is too close to the reference's own
noise for the subtraction to say how small it is: the row has no ratio, only a lower bound
(the interval's low end, or the reference's own S spp where even that is infinite), marked
"below what the fit resolves"; a deeper ``--ref-spp`` turns such rows into ratios.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.bench import tradeoff as T
from app.bench.records import record
from app.errors import UsageError

log = logging.getLogger(__name__)

ROOMS = T.ROOMS
ASSETS = ("sphere", "bunny")
MATERIALS = ("diffuse", "rough_metal")
VIEWS = ("closeup", "whole")
BUNNY = "../shared/data/bunny.glb"
VIEWPORT = 256
SWEEP = (4, 16, 64)
QUICK_REF_SPP = 1024
QUICK_SIZE = 96
DEPTH = {"sphere": 2, "bunny": 3}        # path tracer depth: a convex asset needs 2
MODE_M = 16                              # the mode rows' micro-buffer (the presets have theirs)
# the apartment's whole-object camera, from the sphere's centre: inside the 4 x 2.8 x 4 m box
# (the demo's own "whole" view, scaled to this sphere, would stand outside the wall)
APARTMENT_WHOLE = ((0.7, 0.75, 1.85), 50.0)
SEED = 1000                              # the sweep's seeds: not the reference's 0 and 1
BELOW = "below what the fit resolves"
DRAWS = 200                              # bootstrap resamples of the pixels
RESOLVE = 2.0                            # a ratio only where its 68% interval is within 2x


# -- the fit (pure: tests/pbgi/test_pathtracer_ratio.py checks it on synthetic data) -----------

@dataclass(frozen=True)
class NoiseFit:
    """err(s)^2 = a^2 (1/s + 1/ref_spp): see the module docstring."""
    a: float                 # per-pixel relative RMSE of a 1-spp image
    ref_spp: float
    slope: float             # free log-log slope of the corrected errors (-0.5 expected)

    @property
    def ref_noise(self) -> float:
        return self.a / math.sqrt(self.ref_spp)

    def error(self, spp: float) -> float:
        """The true error (against the converged image) at ``spp``."""
        return self.a / math.sqrt(spp)


def fit_noise(spp, errors, ref_spp: float) -> NoiseFit:
    """Fit a to errors measured at ``spp`` against a reference of ``ref_spp`` samples."""
    s = np.asarray(spp, np.float64)
    e = np.asarray(errors, np.float64)
    if s.shape != e.shape or len(s) < 2 or (s <= 0).any() or not (e > 0).all() \
            or not np.isfinite(e).all():
        raise ValueError(f"fit_noise needs two or more positive errors, got {errors!r}")
    a2 = float(np.exp(np.mean(np.log(e * e / (1.0 / s + 1.0 / ref_spp)))))
    corrected = e * e - a2 / ref_spp
    ok = corrected > 0
    slope = (float(np.polyfit(np.log(s[ok]), 0.5 * np.log(corrected[ok]), 1)[0])
             if ok.sum() >= 2 else float("nan"))
    return NoiseFit(math.sqrt(a2), float(ref_spp), slope)


def true_error(measured: float, fit: NoiseFit) -> float:
    """``measured`` (against the reference) without the reference's noise; NaN at or below it."""
    d = measured * measured - fit.ref_noise ** 2
    return math.sqrt(d) if d > 0 else float("nan")


def error_terms(image, reference, mask) -> np.ndarray:
    """Per pixel of ``mask``: the mean over RGB of (image - reference)^2 over the reference's
    mean luminance there squared. Their mean is image_metrics.relative_rmse(...)^2: the
    bootstrap resamples these."""
    from app.bench.image_metrics import LUMA
    m = np.asarray(mask, bool)
    ref = np.asarray(reference, np.float64)[..., :3][m]
    d = np.asarray(image, np.float64)[..., :3][m] - ref
    mean = float((ref @ LUMA).mean())
    return (d * d).mean(axis=1) / max(mean * mean, 1e-60)


def spp_interval(our_terms, sweep_terms, sweep, ref_spp: float, draws: int = DRAWS,
                 seed: int = 0) -> tuple[float, float]:
    """The 16th and 84th percentiles of the equal-error spp over ``draws`` bootstrap resamples
    of the pixels (the same pixels for our image and every sweep image: they share the
    reference's noise). inf where a resample puts our error at or below the reference's
    noise."""
    terms = np.vstack([np.asarray(sweep_terms, np.float64), np.asarray(our_terms)[None]])
    n = terms.shape[1]
    rng = np.random.default_rng(seed)
    out = np.empty(draws)
    for k in range(draws):
        sq = terms[:, rng.integers(0, n, n)].mean(axis=1)
        fit = fit_noise(sweep, np.sqrt(sq[:-1]), ref_spp)
        e2 = sq[-1] - fit.ref_noise ** 2
        out[k] = fit.a ** 2 / e2 if e2 > 0 else np.inf
    lo, hi = np.percentile(out, (16, 84), method="nearest")     # inf - inf: no interpolation
    return float(lo), float(hi)


def equal_error(fit: NoiseFit, our_error: float, our_seconds: float, seconds_per_spp: float,
                interval: tuple[float, float]) -> dict:
    """The path tracer's spp and time at our (measured) error, and the ratio, with their 68%
    interval (``interval``: spp_interval's). Resolved when that interval spans at most a
    factor RESOLVE; otherwise NaN for those and ``ratio_lower`` instead, from the interval's
    low end (or the reference's own spp where even that is infinite: our error is then within
    the reference's noise, which a path tracer reaches only past ``ref_spp``)."""
    nan = float("nan")
    if not math.isfinite(our_error):            # a NaN/Inf image: no ratio, no bound
        return {"error_true": nan, "spp_needed": nan, "spp_lo": nan, "spp_hi": nan,
                "pt_seconds": nan, "ratio": nan, "ratio_lo": nan, "ratio_hi": nan,
                "ratio_lower": nan, "resolved": 0.0}
    e = true_error(our_error, fit)
    spp = fit.a ** 2 / e ** 2 if math.isfinite(e) else nan
    lo, hi = interval
    resolved = math.isfinite(spp) and 0 < lo and math.isfinite(hi) and hi <= RESOLVE * lo
    # below 1 spp the path tracer cannot go: its 1-spp image already beats ours
    secs = lambda n: max(n, 1.0) * seconds_per_spp / our_seconds      # noqa: E731
    if not resolved:
        return {"error_true": e, "spp_needed": nan, "spp_lo": lo, "spp_hi": hi,
                "pt_seconds": nan, "ratio": nan, "ratio_lo": nan, "ratio_hi": nan,
                "ratio_lower": secs(lo if math.isfinite(lo) else fit.ref_spp), "resolved": 0.0}
    return {"error_true": e, "spp_needed": spp, "spp_lo": lo, "spp_hi": hi,
            "pt_seconds": max(spp, 1.0) * seconds_per_spp, "ratio": secs(spp),
            "ratio_lo": secs(lo), "ratio_hi": secs(hi), "ratio_lower": nan, "resolved": 1.0}


def note(metrics: dict, sweep) -> str:
    """What the table says beside a row's ratio."""
    if not metrics["resolved"] and math.isnan(metrics["ratio_lower"]):
        return "our image is not finite"
    if not metrics["resolved"]:
        return f"{BELOW}: ratio > {metrics['ratio_lower']:.3g}"
    if metrics["spp_needed"] < 1:
        return "the path tracer's 1 spp already beats it"
    if metrics["spp_needed"] < min(sweep):
        return f"extrapolated below {min(sweep)} spp"
    return ""


# -- scenes -----------------------------------------------------------------------------------

def settings() -> list:
    """The presets (app/params.py QUALITY_PRESETS: their render keys, and their render scales
    as the Setting's) and the two modes. A preset's viewer-only keys (the idle passes) are not a
    render's."""
    from app.params import QUALITY_PRESETS, RENDER_KEYS
    out = []
    for name, values in QUALITY_PRESETS.items():
        p = tuple((k, v) for k, v in values.items() if k in RENDER_KEYS)
        scale = float(values["pbgi.render_scale"])
        rough = float(values["pbgi.rough_render_scale"])    # gi_scale takes the lower
        out.append(T.Setting(name, p, scale, rough))
    return out + [T.make_setting(mode, m=MODE_M) for mode in ("classic", "hybrid")]


def asset_mesh(asset: str, sphere):
    """The room's sphere, or the bunny centred on it and as wide as its diameter."""
    from app.io.formats import object_from_dict, placed_mesh
    if asset == "sphere":
        return sphere
    if asset != "bunny":
        raise ValueError(asset)
    if not Path(BUNNY).is_file():
        raise UsageError(Path(BUNNY), "the bunny needs ../shared/data (run from the project "
                                      "root), or pass --assets sphere")
    lo, hi = (np.asarray(b, np.float64) for b in sphere.bounds())
    return placed_mesh(object_from_dict({"mesh": BUNNY, "translate": (0.5 * (lo + hi)).tolist(),
                                         "scale": float(np.max(hi - lo))}, "."))


def view_camera(room: str, view: str, sphere, closeup, size: int):
    """``closeup``: the room's trade-off camera; ``whole``: the demo's own whole-object view,
    or APARTMENT_WHOLE around the apartment's sphere."""
    from app.camera import Camera
    if view == "closeup":
        return closeup
    if view != "whole":
        raise ValueError(view)
    if room == "demo":
        from app.demo.room import default_views
        return default_views(size, size)["whole"]
    lo, hi = (np.asarray(b, np.float64) for b in sphere.bounds())
    centre = 0.5 * (lo + hi)
    offset, fov = APARTMENT_WHOLE
    return Camera(centre + offset, centre, fov_y_deg=fov, width=size, height=size)


def reference_key(room: str, asset: str, view: str) -> str:
    """The reference's name stem: the trade-off's own for its case (the sphere close-up), so
    the two benches share those renders."""
    return room if (asset, view) == ("sphere", "closeup") else f"{room}_{asset}_{view}"


def pt_sweep(scene, sweep, reference: np.ndarray, mask: np.ndarray) -> tuple[list, float]:
    """(error_terms of the image at each spp of ``sweep``, seconds per spp over the sweep)."""
    from app.bench.mitsuba_scene import _mitsuba
    mi = _mitsuba()
    np.asarray(mi.render(scene, spp=1, seed=SEED - 1))          # start its threads
    terms, seconds = [], 0.0
    for k, spp in enumerate(sweep):
        t0 = time.perf_counter()
        img = np.asarray(mi.render(scene, spp=int(spp), seed=SEED + k), np.float32)[..., :3]
        seconds += time.perf_counter() - t0
        terms.append(error_terms(img, reference, mask))
    return terms, seconds / float(sum(sweep))


# -- the command ------------------------------------------------------------------------------

def add_arguments(parser) -> None:
    parser.add_argument("--quick", action="store_true",
                        help=f"demo, sphere, diffuse, close-up, {QUICK_SIZE} px, 2 frames, "
                             f"reference {QUICK_REF_SPP} spp")
    parser.add_argument("--rooms", help=f"comma-separated among {', '.join(ROOMS)}")
    parser.add_argument("--assets", help=f"comma-separated among {', '.join(ASSETS)}")
    parser.add_argument("--materials", help=f"comma-separated among {', '.join(MATERIALS)}")
    parser.add_argument("--views", help=f"comma-separated among {', '.join(VIEWS)}")
    parser.add_argument("--viewport", type=int, help=f"image side (default {VIEWPORT})")
    parser.add_argument("--frames", type=int,
                        help="timed warm frames per setting, the median kept (default 5)")
    parser.add_argument("--ref-spp", type=int,
                        help="the reference's samples per pixel (default: demo "
                             f"{T.SPP['demo']}, apartment {T.SPP['apartment']})")
    parser.add_argument("--sweep", default=",".join(map(str, SWEEP)),
                        help="the path tracer's spp, comma-separated (default 4,16,64)")
    parser.add_argument("--references", metavar="DIR",
                        help="where the references are cached (default <cache>/tradeoff)")
    parser.add_argument("--settings", metavar="SUBSTR",
                        help="only the settings whose name contains this")


def _given(value, default):
    return default if value is None else value


def _options(args) -> dict:
    quick = bool(args.quick)
    o = {"rooms": T._names(args.rooms or ("demo" if quick else ",".join(ROOMS)), ROOMS,
                           "--rooms"),
         "assets": T._names(args.assets or ("sphere" if quick else ",".join(ASSETS)), ASSETS,
                            "--assets"),
         "materials": T._names(args.materials or ("diffuse" if quick else ",".join(MATERIALS)),
                               MATERIALS, "--materials"),
         "views": T._names(args.views or ("closeup" if quick else ",".join(VIEWS)), VIEWS,
                           "--views"),
         "size": _given(args.viewport, QUICK_SIZE if quick else VIEWPORT),
         "frames": _given(args.frames, 2 if quick else 5),
         "ref_spp": _given(args.ref_spp, QUICK_REF_SPP if quick else None)}
    try:
        o["sweep"] = tuple(sorted({int(v) for v in args.sweep.split(",") if v.strip()}))
    except ValueError:
        raise UsageError(None, f"--sweep must list whole numbers, got {args.sweep!r}") from None
    if len(o["sweep"]) < 2 or o["sweep"][0] < 1:
        raise UsageError(None, f"--sweep needs two or more spp >= 1, got {args.sweep!r}")
    if not 16 <= o["size"] <= 2048:
        raise UsageError(None, f"--viewport must be in 16 .. 2048, got {o['size']}")
    if o["frames"] < 1:
        raise UsageError(None, "--frames must be >= 1")
    if o["ref_spp"] is not None and o["ref_spp"] <= 2 * o["sweep"][-1]:
        raise UsageError(None, f"--ref-spp must be more than twice the sweep's largest spp "
                               f"({o['sweep'][-1]}), got {o['ref_spp']}")
    grid = settings()
    if args.settings:
        grid = [s for s in grid if args.settings in s.name]
        if not grid:
            raise UsageError(None, f"no setting's name contains {args.settings!r}")
    o["settings"] = grid
    return o


def _case(rl, scene, key: tuple, kind: str, o, refdir) -> list[dict]:
    """Every setting's row of one case: ``scene`` (cloud, mesh, camera) already in ``rl``,
    ``key`` (room, asset, view)."""
    from app.bench import image_metrics as im
    from app.bench import mitsuba_scene as ms
    cloud, mesh, cam = scene
    room, asset, view = key
    mat = T.material(kind)
    spp_ref = o["ref_spp"] or T.SPP[room]
    ref = T.reference(reference_key(room, asset, view), kind, rl, cloud, mesh, cam, spp_ref,
                      refdir, DEPTH[asset])
    ours = [(st, *T.measure(rl, cam, mat, st, o["frames"])) for st in o["settings"]]
    mask = im.erode(ours[0][1][..., 3] > 0.5, T.MASK_ERODE)
    mi_scene = ms.build_scene(cloud, mesh, mat, cam, ms.square_side(cloud),
                              max_depth=DEPTH[asset])
    sweep_terms, sec_spp = pt_sweep(mi_scene, o["sweep"], ref.image, mask)
    errors = [math.sqrt(t.mean()) for t in sweep_terms]
    fit = fit_noise(o["sweep"], errors, spp_ref)
    log.info("%s %s %s %s: a = %.3g, slope %.2f, %.3g ms/spp", room, asset, view, kind, fit.a,
             fit.slope, 1e3 * sec_spp)
    rows = []
    for st, image, m in ours:
        finite = bool(np.isfinite(image).all())
        terms = error_terms(image, ref.image, mask) if finite else None
        err = math.sqrt(terms.mean()) if finite else float("inf")
        interval = (spp_interval(terms, sweep_terms, o["sweep"], spp_ref) if finite
                    else (float("nan"),) * 2)
        eq = equal_error(fit, err, m["ms"] / 1e3, sec_spp, interval)
        d = st.describe()
        rows.append(record("pathtracer-ratio",
                           {"room": room, "asset": asset, "material": kind, "view": view,
                            "setting": st.name, "mode": d["mode"], "microbuffer": d["microbuffer"],
                            "scale": d["scale"], "viewport": o["size"]},
                           {**m, "rel_rmse": err,
                            "rel_rmse_4x4": (im.relative_rmse(image, ref.image, mask, 4)
                                             if finite else float("inf")),
                            **eq, "pt_a": fit.a, "pt_slope": fit.slope,
                            "pt_ms_per_spp": 1e3 * sec_spp, "ref_spp": spp_ref,
                            "ref_noise": fit.ref_noise, "ref_noise_halves": ref.noise,
                            **{f"pt_err_{s}spp": e for s, e in zip(o["sweep"], errors)}}))
        log.info("%s", markdown_row(rows[-1], o["sweep"]))     # a long run's table so far
    return rows


MARKDOWN_HEAD = ("| room | asset | material | view | setting | ours ms | our error (true) "
                 "| PT spp needed | PT s | ratio (68%) | note |\n"
                 "|---|---|---|---|---|---|---|---|---|---|---|")


def markdown_row(r: dict, sweep=SWEEP) -> str:
    """One record as a row of the table the README quotes."""
    c, m = r["case"], r["metrics"]
    spp = "-" if math.isnan(m["spp_needed"]) else f"{m['spp_needed']:.3g}"
    true = "-" if math.isnan(m["error_true"]) else f"{100 * m['error_true']:.1f}%"
    pt = "-" if math.isnan(m["pt_seconds"]) else f"{m['pt_seconds']:.3g}"
    ratio = ("-" if math.isnan(m["ratio"]) else
             f"{m['ratio']:.3g}x ({m['ratio_lo']:.3g}-{m['ratio_hi']:.3g})")
    return (f"| {c['room']} | {c['asset']} | {c['material']} | {c['view']} | {c['setting']} | "
            f"{m['ms']:.0f} | {100 * m['rel_rmse']:.1f}% ({true}) | {spp} | {pt} | {ratio} | "
            f"{note(m, sweep)} |")


def markdown(records: list[dict], sweep=SWEEP) -> str:
    return "\n".join([MARKDOWN_HEAD] + [markdown_row(r, sweep) for r in records])


def summary(records: list[dict]) -> str:
    """The ratios alone: a row per (room, asset, view, material), a column per setting; a
    ratio is "N x", a bound "> N x", a non-finite image "-"."""
    settings_ = list(dict.fromkeys(r["case"]["setting"] for r in records))
    cases: dict = {}
    for r in records:
        c = r["case"]
        cases.setdefault((c["room"], c["asset"], c["view"], c["material"]), {})[c["setting"]] = \
            r["metrics"]

    def cell(m) -> str:
        if m is None or (not m["resolved"] and math.isnan(m["ratio_lower"])):
            return "-"
        return f"{m['ratio']:.3g}x" if m["resolved"] else f"> {m['ratio_lower']:.3g}x"
    lines = ["| room | asset | view | material | " + " | ".join(settings_) + " |",
             "|---|---|---|---|" + "---|" * len(settings_)]
    for key, ms in cases.items():
        lines.append("| " + " | ".join(key) + " | "
                     + " | ".join(cell(ms.get(st)) for st in settings_) + " |")
    return "\n".join(lines)


def run(args) -> list[dict]:
    from app.pbgi.renderer import Relighter
    o = _options(args)
    refdir = Path(args.references) if args.references else T.reference_dir()
    records = []
    t0 = time.perf_counter()
    for room in o["rooms"]:
        cloud, sphere, closeup = T.scene(room, o["size"])
        rl = Relighter()
        rl.set_cloud(cloud)
        for asset in o["assets"]:
            mesh = asset_mesh(asset, sphere)
            rl.set_asset(mesh)
            for view in o["views"]:
                cam = view_camera(room, view, sphere, closeup, o["size"])
                for kind in o["materials"]:
                    records += _case(rl, (cloud, mesh, cam), (room, asset, view), kind, o,
                                     refdir)
                    log.info("%d rows, %.0f s", len(records), time.perf_counter() - t0)
        rl.release()
    print(markdown(records, o["sweep"]))
    print()
    print(summary(records))
    return records
