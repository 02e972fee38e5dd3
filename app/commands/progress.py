"""Progress bars for the long command-line jobs: ``turntable`` (frames), ``render`` (passes and
silhouette samples) and ``expand`` (fraction done, with the stage beside the bar).

One bar on stderr (stdout stays for the command's result lines), drawn by tqdm, and only where
someone watches it: not when stderr is not a terminal (a render farm's log, a pipe, the tests)
and not with ``-q``. The log lines do not depend on the bar: they are written either way, through
tqdm while a bar is showing (``logging_redirect_tqdm``) so that a line never lands inside it.
"""

from __future__ import annotations

import contextlib
import os
import sys


def bar_wanted(quiet: bool = False, stream=None) -> bool:
    """Draw a bar? Only on a terminal and without ``-q``."""
    stream = sys.stderr if stream is None else stream
    try:
        return not quiet and stream.isatty()
    except (AttributeError, ValueError):       # a closed or odd stream
        return False


class _NoBar:
    """What ``progress`` yields when no bar is drawn: the same calls, doing nothing."""

    def update(self, n: int = 1) -> None:
        pass

    def set_postfix_str(self, text: str = "", refresh: bool = True) -> None:
        pass


@contextlib.contextmanager
def progress(total: int, desc: str, unit: str = "it", quiet: bool = False):
    """``with progress(n, "frames", unit="frame", quiet=args.quiet) as bar: ... bar.update()``.

    A tqdm bar on stderr when ``bar_wanted``; otherwise an object with the same ``update`` and
    ``set_postfix_str`` that draws nothing. Logging goes around the bar while it is shown."""
    if not bar_wanted(quiet):
        yield _NoBar()
        return
    from tqdm import tqdm
    from tqdm.contrib.logging import logging_redirect_tqdm
    # tqdm draws nothing on a terminal that reports a size of 0 (a fresh pseudo-terminal, some
    # CI runners): 80 x 24 there
    try:
        sized = os.get_terminal_size(sys.stderr.fileno()).columns > 0
    except (AttributeError, OSError, ValueError):
        sized = False
    with tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=True,
              ncols=None if sized else 80, nrows=None if sized else 24) as bar, \
            logging_redirect_tqdm():
        yield bar


def quiet_of(args) -> bool:
    """The top-level ``-q`` from a subcommand's parsed arguments (absent: not quiet)."""
    return bool(getattr(args, "quiet", False))


__all__ = ["progress", "bar_wanted", "quiet_of"]
