"""Argument types the benches share, so that every list flag reaches ``scanlight bench``'s range
check (app/commands/bench.py: NUMBER_RANGES) as numbers and a malformed one is a usage error
naming the flag, never an internal error."""

from __future__ import annotations

import argparse


def int_list(text: str) -> list[int]:
    """'128,256' -> [128, 256] (an argparse ``type``: a bad item is exit 2 with argparse's
    message naming the flag; '1e6' is accepted, as ``--points 1e6`` is)."""
    try:
        out = [int(float(t)) for t in str(text).split(",") if t.strip()]
    except (ValueError, OverflowError):
        raise argparse.ArgumentTypeError(f"a comma-separated list of integers, got {text!r}") \
            from None
    if not out:
        raise argparse.ArgumentTypeError("an empty list")
    return out


__all__ = ["int_list"]
