"""CLI glue for ``scanlight expand`` and ``scanlight evaluate expansion`` (app/cli.py calls these).

run_* return an exit code and raise ScanlightError for bad input. The expansion runs as an
app.jobs job (a thread by default, ``--worker process`` for a separate process); progress goes to
stderr; Ctrl-C cancels it. Outputs are written by the job only on success, atomically, so an
interrupted run never leaves a half-written cloud or report.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from app.camera import camera_from_dict
from app.errors import ScanlightError, UsageError
from app.hdr.pipeline import METHODS, ExpandParams, Expansion, run_expansion
from app.io.files import read_json, require_file, write_json


# ------------------------------------------------------------------------------------ inputs

def load_cameras(path) -> list:
    """Capture cameras from JSON: a list of ``{"position": [x, y, z]}`` (an axis-aligned cube
    map there) or full camera objects (with ``look_at``: one rendering with that camera);
    ``{"cameras": [...]}`` and a single object are accepted too."""
    p = require_file(path, "cameras", (".json",))
    data = read_json(p, "cameras")
    if isinstance(data, dict):
        data = data.get("cameras", [data])
    if not isinstance(data, list) or not data:
        raise ScanlightError(p, "expected a non-empty list of cameras")
    out = []
    for i, d in enumerate(data):
        if isinstance(d, (list, tuple)):
            d = {"position": d}
        if not isinstance(d, dict):
            raise ScanlightError(p, f"camera {i}: expected an object with 'position'")
        if "look_at" in d:
            out.append(camera_from_dict(d, f"{p} (camera {i})"))
            continue
        pos = d.get("position")
        try:
            arr = np.asarray(pos, dtype=np.float64)
        except (TypeError, ValueError):
            arr = np.zeros(0)
        if arr.shape != (3,) or not np.all(np.isfinite(arr)):
            raise ScanlightError(p, f"camera {i}: 'position' must be 3 finite numbers, got {pos!r}")
        out.append(arr)
    return out


def _params(req_params) -> ExpandParams:
    if req_params is None:
        params = ExpandParams()
    elif isinstance(req_params, ExpandParams):
        params = req_params
    else:
        params = ExpandParams.from_dict(dict(req_params))
    return params


def execute_request(req, progress=None, cancel=None) -> Expansion:
    """Load what the request names by path, run the pipeline, write the outputs atomically."""
    from app.io.exr import read_image
    from app.io.pointcloud import load_cloud, save_cloud

    names = {}
    cloud = req.cloud
    if isinstance(cloud, (str, Path)):
        names["cloud"] = str(cloud)
        cloud = load_cloud(cloud)
    photo = req.photo
    photo_warnings = []
    if isinstance(photo, (str, Path)):
        names["photo"] = str(photo)
        img = read_image(photo)
        if not img.hdr:
            photo_warnings.append(f"{photo}: an 8-bit image, not HDR: the expansion cannot "
                                  "recover radiance above its clipping point")
        photo = img.rgb
    cams = req.cameras
    if isinstance(cams, (str, Path)):
        names["cameras"] = str(cams)
        cams = load_cameras(cams)
    params = _params(req.params)
    res = run_expansion(cloud, photo, cams, req.method, params, progress, cancel, names)
    res.report["warnings"][:0] = photo_warnings
    res.report["inputs"] = {k: names.get(k) for k in ("cloud", "photo", "cameras")}
    if req.out_path:
        save_cloud(res.cloud, req.out_path)
        res.report["output"] = str(req.out_path)
    if req.report_path:
        write_report(res.report, req.report_path)
    if not req.return_cloud:
        res = Expansion(None, res.report, res.labels, [])
    return res


def write_report(report: dict, path) -> None:
    """JSON, atomically; NaN (e.g. an RMS over no points) is written as null."""
    write_json(path, report)


# ------------------------------------------------------------------------------------ expand

def add_expand_arguments(parser) -> None:
    parser.add_argument("--cloud", required=True, help="LDR point cloud (.ply, .pcd, .xyz...)")
    parser.add_argument("--photo", required=True, help="HDR photo of the scene (.exr), unregistered")
    parser.add_argument("--cameras", required=True,
                        help='capture cameras JSON: [{"position": [x, y, z]}, ...] (cube maps) '
                             "or full camera objects")
    parser.add_argument("--method", default="pmatch-rgb", choices=METHODS,
                        help="expansion strategy (default pmatch-rgb)")
    parser.add_argument("--out", required=True, help="output HDR cloud (.ply, float colours)")
    parser.add_argument("--report", help="write the report (alpha, counts, timings) as JSON here")
    parser.add_argument("--face-size", type=int, default=1024, help="cube-map face size (1024)")
    parser.add_argument("--tl", type=float, help="overexposure threshold on LDR luminance (0.9)")
    parser.add_argument("--th", type=float, help="PatchMatch SSD rejection threshold (1.0)")
    parser.add_argument("--k", type=int, help="Poisson k-nearest neighbours (16)")
    parser.add_argument("--exposure", type=float, help="skip the exposure search: use this alpha")
    parser.add_argument("--params", metavar="JSON",
                        help="more ExpandParams fields as a JSON object, e.g. '{\"pm_iterations\": 6}'")
    parser.add_argument("--worker", choices=("thread", "process", "sync"), default="thread",
                        help="where the job runs (default thread)")


def _cli_params(args) -> dict:
    d = {}
    if args.params:
        try:
            d = json.loads(args.params)
        except json.JSONDecodeError as exc:
            raise UsageError(None, f"--params is not valid JSON ({exc})") from None
        if not isinstance(d, dict):
            raise UsageError(None, "--params must be a JSON object")
    if not 16 <= args.face_size <= 8192:
        raise UsageError(None, f"--face-size must be in [16, 8192], got {args.face_size}")
    d["face_size"] = args.face_size
    for key in ("tl", "th", "k", "exposure"):
        v = getattr(args, key, None)
        if v is not None:
            d[key] = v
    if "tl" in d and not 0 < d["tl"] < 1:
        raise UsageError(None, f"--tl must be in (0, 1), got {d['tl']}")
    if "th" in d and not d["th"] > 0:
        raise UsageError(None, f"--th must be positive, got {d['th']}")
    if "k" in d and not 1 <= int(d["k"]) <= 256:
        raise UsageError(None, f"--k must be in [1, 256], got {d['k']}")
    ExpandParams.from_dict(d)  # unknown keys: one line now, not in the worker
    return d


class _StderrProgress:
    """One line per stage and per 10% on stderr (no carriage-return tricks: logs stay readable)."""

    def __init__(self, stream=None):
        self.stream = stream or sys.stderr
        self.stage = None
        self.step = -1

    def __call__(self, fraction: float, stage: str) -> None:
        step = int(fraction * 10)
        if stage != self.stage or step > self.step:
            self.stage, self.step = stage, step
            print(f"expand: {fraction:4.0%} {stage}", file=self.stream, flush=True)


def run_expand(args) -> int:
    from app.jobs import ExpandRequest, Job, JobState, run_expand_request

    params = _cli_params(args)
    out = Path(args.out)
    if out.suffix.lower() != ".ply":
        raise UsageError(None, f"--out must be a .ply file, got {out}")
    # check the inputs here, so bad input fails before a worker starts
    require_file(args.cloud, "point cloud")
    require_file(args.photo, "photo")
    load_cameras(args.cameras)
    req = ExpandRequest(args.cloud, args.photo, args.cameras, args.method, params,
                        str(out), args.report, return_cloud=False)
    show = _StderrProgress()
    job = Job(run_expand_request, req, args.worker)
    job.start()
    shown = 0
    try:
        while True:
            st = job.wait(timeout=0.2)
            for f, stage in job.history[shown:]:
                show(f, stage)
            shown = len(job.history)
            if job.done:
                break
    except KeyboardInterrupt:
        job.cancel()
        job.wait(timeout=job.kill_after + 1)
        raise
    if st.state is JobState.FAILED:
        if isinstance(job.error, ScanlightError):
            raise job.error
        raise RuntimeError(str(job.error))
    if st.state is JobState.CANCELLED:
        print("expand: cancelled; nothing written", file=sys.stderr)
        return 130
    rep = job.result.report
    for w in rep.get("warnings", []):
        print(f"expand: warning: {w}", file=sys.stderr)
    c = rep["counts"]
    alpha = rep.get("alpha")
    print(f"expanded {c['points']} points ({args.method}): {c['overexposed']} overexposed, "
          f"{c['expanded_by_projection']} by projection, {c['filled_by_poisson']} by Poisson, "
          f"{c['unresolved']} unresolved; alpha = "
          f"{'n/a' if alpha is None else f'{alpha:.4g}'}; "
          f"{rep['timings']['seconds_total']:.1f} s -> {out}")
    return 0


# ------------------------------------------------------------------------------------ evaluate

def add_evaluate_arguments(parser) -> None:
    parser.add_argument("--cloud", required=True, help="expanded HDR cloud")
    parser.add_argument("--gt", required=True, help="ground-truth HDR cloud")
    parser.add_argument("--ldr", help="the LDR cloud the expansion started from: defines the "
                                      "overexposed points and adds the LDR baseline")
    parser.add_argument("--tl", type=float, default=0.9, help="overexposure threshold (0.9)")
    parser.add_argument("--exposure", type=float,
                        help="scale of the cloud relative to the ground truth (default: measured)")
    parser.add_argument("--object", help="object JSON for the relit-render error")
    parser.add_argument("--renderer", choices=("hybrid", "classic"), default="hybrid",
                        help="PBGI renderer for the relit-render error")
    parser.add_argument("--render-size", type=int, default=128,
                        help="image size of the relit-render comparison (default 128)")
    parser.add_argument("--no-render", action="store_true",
                        help="skip the relit-render error (point errors only)")
    parser.add_argument("--json", metavar="PATH", help="write the metrics as JSON here")


def run_evaluate_expansion(args) -> int:
    from app.io.pointcloud import load_cloud

    cloud = load_cloud(args.cloud)
    gt = load_cloud(args.gt)
    ldr = load_cloud(args.ldr) if args.ldr else None
    if args.exposure is not None and not (math.isfinite(args.exposure) and args.exposure > 0):
        raise UsageError(None, f"--exposure must be a positive number, got {args.exposure}")
    if not 0 < args.tl < 1:
        raise UsageError(None, f"--tl must be in (0, 1), got {args.tl}")
    from app.hdr.evaluate import expansion_errors, render_errors

    m = expansion_errors(cloud, gt, ldr, args.tl, args.exposure, source=args.cloud)
    rend = None
    if not args.no_render:
        rend = render_errors(cloud, gt, ldr, {"object": args.object, "renderer": args.renderer,
                                              "scale": m["scale"], "size": args.render_size})
    print(f"points {m['points']} ({m['correspondence']}), overexposed {m['overexposed']} "
          f"({m['overexposed_from']}), scale {m['scale']:.4g}")
    print(f"point RMS: all {m['rms_all']:.4g}, overexposed {m['rms_overexposed']:.4g}, "
          f"well exposed {m['rms_well_exposed']:.4g}")
    if "ldr_rms_all" in m:
        print(f"LDR baseline: all {m['ldr_rms_all']:.4g}, overexposed {m['ldr_rms_overexposed']:.4g}")
    if rend is not None:
        m["render"] = rend
        print("relit-render error: " + ", ".join(f"{k} {v:.4g}" for k, v in rend.items()))
    if args.json:
        write_report(m, args.json)
    return 0
