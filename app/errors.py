"""The one error type for bad input: it names the file and the reason in one line."""

from __future__ import annotations

from pathlib import Path


class ScanlightError(Exception):
    """Bad input or a failed step the user can act on.

    The CLI prints ``str(err)`` as a single line and exits with ``exit_code``
    (3 for bad input); the viewer shows the same line in a message box.
    """

    exit_code = 3

    def __init__(self, path: str | Path | None, reason: str):
        self.path = None if path is None else str(path)
        self.reason = " ".join(str(reason).split())  # always one line
        shown = None if self.path is None else printable(self.path)
        super().__init__(f"{shown}: {self.reason}" if shown else self.reason)


def printable(name: str) -> str:
    """``name`` with control characters (a newline in a file name) and bytes that are not
    UTF-8 (surrogate escapes) written as escapes, so the error stays one line."""
    if name.isprintable():
        return name
    out = []
    for c in name:
        if c.isprintable():
            out.append(c)
        elif 0xDC80 <= ord(c) <= 0xDCFF:         # a byte that is not UTF-8, as Python keeps it
            out.append(f"\\x{ord(c) - 0xDC00:02x}")
        else:
            out.append(c.encode("unicode_escape").decode("ascii"))
    return "".join(out)


class UsageError(ScanlightError):
    """Wrong command-line arguments (exit 2)."""

    exit_code = 2


def refusal(exc: BaseException) -> str | None:
    """The one line for the machine refusing what a command asked of it - a full disk, a
    file-size or open-files limit, a read-only folder (OSError), no memory left (MemoryError):
    the environment, not a bug - or None when ``exc`` is something else."""
    if isinstance(exc, MemoryError):
        return (f"out of memory ({str(exc) or 'an allocation failed'}): the input is too large "
                "for the memory this process may use")
    if isinstance(exc, OSError):
        where = f"{printable(str(exc.filename))}: " if exc.filename else ""
        return f"{where}{exc.strerror or exc}"
    return None

