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
        super().__init__(f"{self.path}: {self.reason}" if self.path else self.reason)


class UsageError(ScanlightError):
    """Wrong command-line arguments (exit 2)."""

    exit_code = 2
