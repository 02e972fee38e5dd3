"""``scanlight evaluate WHAT``: errors against ground truth."""

from __future__ import annotations


def add_arguments(parser) -> None:
    sub = parser.add_subparsers(dest="what", required=True, parser_class=type(parser))
    p = sub.add_parser("expansion", help="HDR expansion vs ground truth: point RMS and the "
                                         "relit-render error (paper Table 2 protocol)")
    from app.hdr.commands import add_evaluate_arguments
    add_evaluate_arguments(p)


def run(args) -> int:
    from app.hdr.commands import run_evaluate_expansion
    return run_evaluate_expansion(args)
