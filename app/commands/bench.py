"""``scanlight bench NAME``: print a table, optionally write JSON records."""

from __future__ import annotations

import importlib

from app.bench import BENCHES
from app.bench.records import table, write_json
from app.errors import UsageError


def add_arguments(parser) -> None:
    sub = parser.add_subparsers(dest="bench", required=True, parser_class=type(parser))
    for name, module in BENCHES.items():
        p = sub.add_parser(name, help=f"the {name} benchmark")
        p.add_argument("--json", metavar="PATH", help="write the records as JSON here")
        try:
            importlib.import_module(module).add_arguments(p)
        except ModuleNotFoundError:
            p.set_defaults(_missing=True)


# The numeric options the benches share, by argparse destination: (lowest, highest). A bench
# must not take a number it cannot use: --points -5 ended in a numpy error, 1e30 in an
# OverflowError, --points 0 silently ran the default, --viewport 0 reached the renderer,
# --timeout nan and --repeat 0 printed tables of NaN.
NUMBER_RANGES = {"points": (1000, 50_000_000), "size": (8, 8192), "viewport": (8, 8192),
                 "viewports": (8, 8192), "microbuffers": (8, 32), "repeat": (1, 1000),
                 "frames": (1, 1000), "spp": (1, 1 << 20), "ref_spp": (1, 1 << 20),
                 "timeout": (0.1, 86400.0), "tc": (1e-6, 1.0), "tn": (1e-6, 1.0)}


def _check_numbers(args) -> None:
    for dest, (lo, hi) in NUMBER_RANGES.items():
        value = getattr(args, dest, None)
        for v in (value if isinstance(value, (list, tuple)) else [value]):
            if v is not None and not lo <= v <= hi:      # NaN fails both comparisons
                raise UsageError(None, f"--{dest.replace('_', '-')} must be {lo:g} .. {hi:g}, "
                                       f"got {v:g}")


def run(args) -> int:
    if getattr(args, "_missing", False):
        raise UsageError(None, f"benchmark {args.bench!r} is not available in this build")
    _check_numbers(args)
    if args.json:      # a folder it cannot write into: say so now, not after the whole run
        from app.io.outputs import check_outputs
        check_outputs({}, {"--json": args.json})
    records = importlib.import_module(BENCHES[args.bench]).run(args)
    print(table(records))
    if args.json:
        write_json(records, args.json)
        print(f"wrote {len(records)} records to {args.json}")
    return 0
