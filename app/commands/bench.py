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


def run(args) -> int:
    if getattr(args, "_missing", False):
        raise UsageError(None, f"benchmark {args.bench!r} is not available in this build")
    records = importlib.import_module(BENCHES[args.bench]).run(args)
    print(table(records))
    if args.json:
        write_json(records, args.json)
        print(f"wrote {len(records)} records to {args.json}")
    return 0
