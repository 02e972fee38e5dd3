"""``scanlight expand``: HDR-expand an LDR point cloud from one HDR photo (app/hdr).

    scanlight expand --cloud scan.ply --photo photo.exr --cameras capture.json --out hdr.ply
                     [--report report.json] [--method pmatch-rgb] [--face-size 512]
                     [--tl 0.9] [--th 1] [--k 16] [--alpha A] [...every hdr.* parameter]
                     [--params JSON] [--worker thread|process|sync]

The expansion options and their defaults are the parameter table's ``hdr.*`` rows
(app/params.py, the same as the viewer's; app/commands/options.py maps the flags).
``--exposure`` is the deprecated spelling of ``--alpha`` (the scan's exposure, not EV).
``--params`` is a JSON object of more ExpandParams fields (by name or full key); a flag given
with a value other than its default wins over it.

The expansion runs as an app.jobs job (app.hdr.job: a thread by default, ``--worker process``
for a separate process); progress goes to stderr; Ctrl-C cancels it. Outputs are written by the
job only on success, atomically, so an interrupted run never leaves a half-written cloud or
report.
"""

from __future__ import annotations

import sys
from pathlib import Path

from app.commands.options import COMMAND_FLAGS, add_param_options, given_values, param_values
from app.errors import ScanlightError, UsageError
from app.params import BY_KEY


def add_arguments(parser) -> None:
    parser.add_argument("--cloud", required=True, help="LDR point cloud (.ply, .pcd, .xyz...)")
    parser.add_argument("--photo", required=True, help="HDR photo of the scene (.exr), unregistered")
    parser.add_argument("--cameras", required=True,
                        help='capture cameras JSON: [{"position": [x, y, z]}, ...] (cube maps) '
                             "or full camera objects")
    parser.add_argument("--out", required=True, help="output HDR cloud (.ply, float colours)")
    parser.add_argument("--report", help="write the report (alpha, counts, timings) as JSON here")
    parser.add_argument("--params", metavar="JSON",
                        help="ExpandParams fields as a JSON object, e.g. "
                             "'{\"pm_iterations\": 6}' or '{\"pm_scale_tolerance\": null}' "
                             "(null: not set); a flag given with another value wins")
    parser.add_argument("--worker", choices=("thread", "process", "sync"), default="thread",
                        help="where the job runs (default thread)")
    add_param_options(parser, "expand")


def expand_params(args):
    """The ExpandParams of the command line: the table's defaults, then ``--params``, then the
    flags given (they win); a bad value is one line naming the flag (exit 2)."""
    from app.hdr.pipeline import ExpandParams

    values = param_values(args, "expand")
    extra = {}
    if args.params:
        from app.io.schema import parse_json
        try:   # the one parser of JSON inputs, with its depth limit (app/io/schema.py)
            extra = parse_json(args.params, None, "JSON")
        except ScanlightError as err:
            raise UsageError(None, f"--params is {err.reason}") from None
        if not isinstance(extra, dict):
            raise UsageError(None, "--params must be a JSON object")
    # merged by field name: --params may name a field ("neighbours") or its key ("hdr.neighbours")
    by_name = lambda d: {BY_KEY[k].name if k in BY_KEY else k: v for k, v in d.items()}
    try:
        return ExpandParams.from_dict({**by_name(values), **by_name(extra),
                                       **by_name(given_values(args, "expand"))})
    except ScanlightError as err:   # a cross-field check (each flag alone was fine)
        if extra:
            raise UsageError(None, f"--params: {err.reason}") from None
        reason = err.reason
        for flag, key in COMMAND_FLAGS["expand"].items():
            reason = reason.replace(f"'{BY_KEY[key].name}'", flag)
        raise UsageError(None, reason) from None


class _StderrProgress:
    """On a terminal, a bar (app/commands/progress.py) with the stage beside it; elsewhere (a
    log, a pipe, -q) one line per stage and per 10% on stderr, with no carriage-return tricks,
    so logs stay readable."""

    def __init__(self, stream=None, bar=None):
        self.stream = stream or sys.stderr
        self.bar = bar
        self.stage = None
        self.step = -1

    def __call__(self, fraction: float, stage: str) -> None:
        if self.bar is not None:
            if stage != self.stage:
                self.stage = stage
                self.bar.set_postfix_str(stage)
            self.bar.update(max(0, int(round(fraction * 100)) - self.bar.n))
            return
        step = int(fraction * 10)
        if stage != self.stage or step > self.step:
            self.stage, self.step = stage, step
            print(f"expand: {fraction:4.0%} {stage}", file=self.stream, flush=True)


def run(args) -> int:
    from app.hdr.job import ExpandRequest, load_cameras, run_expand_request
    from app.io.files import require_file
    from app.io.outputs import OutputSet, check_outputs
    from app.commands.progress import bar_wanted, progress, quiet_of
    from app.jobs import Job, JobState

    params = expand_params(args)
    out = Path(args.out)
    if out.suffix.lower() != ".ply":
        raise UsageError(None, f"--out must be a .ply file, got {out}")
    check_outputs({"--cloud": args.cloud, "--photo": args.photo, "--cameras": args.cameras},
                  {"--out": args.out, "--report": args.report})
    # check the inputs here, so bad input fails before a worker starts
    require_file(args.cloud, "point cloud")
    require_file(args.photo, "photo")
    load_cameras(args.cameras)
    # the cloud and the report are written to temporaries and renamed together at the end
    # (app/io/outputs.py): a failure or Ctrl-C leaves neither, two runs never mix theirs
    with OutputSet({"--out": out, "--report": args.report}) as outs:
        req = ExpandRequest(args.cloud, args.photo, args.cameras, params,
                            str(outs.temp("--out")),
                            str(outs.temp("--report")) if args.report else None,
                            return_cloud=False, output_name=str(out))
        if args.worker != "process":
            # the photo is read here, on the main thread, where what OpenEXR prints about a
            # damaged file is folded into the one error line (ExpandRequest.with_photo_read)
            req = req.with_photo_read()
        job = Job(run_expand_request, req, args.worker)
        job.start()
        shown = 0
        with progress(100, "expand", unit="%", quiet=quiet_of(args)) as bar:
            show = _StderrProgress(bar=bar if bar_wanted(quiet_of(args)) else None)
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
            outs.discard()
            print("expand: cancelled; nothing written", file=sys.stderr)
            return 130
    rep = job.result.report
    for w in rep.get("warnings", []):
        print(f"expand: warning: {w}", file=sys.stderr)
    c = rep["counts"]
    alpha = rep.get("alpha")
    path = rep.get("path", "matching")
    how = "registered photo" if path == "registered" else params.method
    print(f"expanded {c['points']} points ({how}): {c['overexposed']} overexposed, "
          f"{c['projected_from_registered_photo']} from the registered photo, "
          f"{c['expanded_by_projection']} by matching, {c['filled_by_poisson']} by Poisson, "
          f"{c['unresolved']} unresolved; alpha = "
          f"{'n/a' if alpha is None else f'{alpha:.4g}'}; "
          f"{rep['timings']['seconds_total']:.1f} s -> {out}")
    return 0


__all__ = ["add_arguments", "run", "expand_params"]
