"""``scanlight evaluate WHAT``: errors against ground truth.

    scanlight evaluate expansion --cloud hdr.ply --gt gt.ply [--ldr scan.ply] [--tl 0.9]
                                 [--alpha A] [--object obj.json] [--renderer hybrid|classic]
                                 [--render-size 128] [--no-render] [--json metrics.json]

``--tl`` and ``--alpha`` are the parameter table's ``hdr.threshold_ldr`` and ``hdr.alpha``
(app/params.py; the same defaults as ``scanlight expand`` and the viewer). ``--exposure`` is the
deprecated spelling of ``--alpha``: the scale of the cloud relative to the ground truth, measured
when not given.
"""

from __future__ import annotations

from app.commands.options import add_param_options, param_values
from app.errors import UsageError

RENDER_SIZE = (16, 2048)    # --render-size: the relit comparison renders three clouds at it


def add_arguments(parser) -> None:
    sub = parser.add_subparsers(dest="what", required=True, parser_class=type(parser))
    p = sub.add_parser("expansion", help="HDR expansion vs ground truth: point RMS and the "
                                         "relit-render error (paper Table 2 protocol)")
    add_expansion_arguments(p)


def add_expansion_arguments(parser) -> None:
    parser.add_argument("--cloud", required=True, help="expanded HDR cloud")
    parser.add_argument("--gt", required=True, help="ground-truth HDR cloud")
    parser.add_argument("--ldr", help="the LDR cloud the expansion started from: defines the "
                                      "overexposed points and adds the LDR baseline")
    parser.add_argument("--object", help="object JSON for the relit-render error")
    parser.add_argument("--renderer", choices=("hybrid", "classic"), default="hybrid",
                        help="PBGI renderer for the relit-render error")
    parser.add_argument("--render-size", type=int, default=128,
                        help="image size of the relit-render comparison (default 128; "
                             f"{RENDER_SIZE[0]} .. {RENDER_SIZE[1]})")
    parser.add_argument("--no-render", action="store_true",
                        help="skip the relit-render error (point errors only)")
    parser.add_argument("--json", metavar="PATH", help="write the metrics as JSON here")
    add_param_options(parser, "evaluate")


def run(args) -> int:
    return run_expansion(args)


def run_expansion(args) -> int:
    """``scanlight evaluate expansion``: point RMS (overall, overexposed, well exposed, and the
    LDR baseline with --ldr) and the relit-render error, printed and optionally as JSON."""
    from app.hdr.evaluate import expansion_errors, render_errors
    from app.io.files import write_json
    from app.io.outputs import check_outputs
    from app.io.pointcloud import load_cloud

    values = param_values(args, "evaluate")
    if not args.no_render and not RENDER_SIZE[0] <= args.render_size <= RENDER_SIZE[1]:
        raise UsageError(None, f"--render-size must be {RENDER_SIZE[0]} .. {RENDER_SIZE[1]}, "
                               f"got {args.render_size}")
    check_outputs({"--cloud": args.cloud, "--gt": args.gt, "--ldr": args.ldr,
                   "--object": getattr(args, "object", None)}, {"--json": args.json})
    tl, alpha = values["hdr.threshold_ldr"], values["hdr.alpha"]
    cloud = load_cloud(args.cloud)
    gt = load_cloud(args.gt)
    ldr = load_cloud(args.ldr) if args.ldr else None

    m = expansion_errors(cloud, gt, ldr, tl, alpha, source=args.cloud)
    rend = None
    if not args.no_render:
        rend = render_errors(cloud, gt, ldr, {"object": args.object, "renderer": args.renderer,
                                              "scale": m["scale"], "size": args.render_size})
    print(f"points {m['points']} ({m['correspondence']}), overexposed {m['overexposed']} "
          f"({m['overexposed_from']}), scale {m['scale']:.4g}")
    print(f"point RMS: all {m['rms_all']:.4g}, overexposed {m['rms_overexposed']:.4g}, "
          f"well exposed {m['rms_well_exposed']:.4g}")
    if "ldr_rms_all" in m:
        print(f"LDR baseline: all {m['ldr_rms_all']:.4g}, "
              f"overexposed {m['ldr_rms_overexposed']:.4g}")
    if rend is not None:
        m["render"] = rend
        print("relit-render error: " + ", ".join(f"{k} {v:.4g}" for k, v in rend.items()))
    if args.json:
        write_json(args.json, m)
    return 0


__all__ = ["add_arguments", "run", "add_expansion_arguments", "run_expansion"]
