"""``scanlight expand``: the HDR expansion pipeline (app/hdr) from the command line."""

from __future__ import annotations


def add_arguments(parser) -> None:
    from app.hdr.commands import add_expand_arguments
    add_expand_arguments(parser)


def run(args) -> int:
    from app.hdr.commands import run_expand
    return run_expand(args)
