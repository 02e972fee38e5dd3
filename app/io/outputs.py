"""A command's output paths checked against its inputs and each other before any work.

A careless command line must not destroy data: ``render --stats room.ply`` used to overwrite the
cloud it had just read, ``expand --out`` naming the input cloud replaced it, ``evaluate --json``
naming the ground truth wrote JSON over it, and ``--stats`` equal to ``--out`` left one of the
two. ``check_outputs`` refuses all of these up front, with one line naming the file (exit 3):

- an output that is the same file as an input: the same resolved path (symbolic links followed)
  or, when both exist, the same device and inode (hard links);
- two outputs naming the same file;
- an output that is an existing folder;
- an output whose folder cannot be written: the nearest existing folder above it (missing
  folders are created when the output is written) must be a folder the user may write into.

The writing itself stays atomic per file (app/io/files.py ``atomic_output``).
"""

from __future__ import annotations

import os
from pathlib import Path

from app.errors import ScanlightError


def _same_file(a: Path, b: Path) -> bool:
    if a.resolve() == b.resolve():
        return True
    try:
        sa, sb = a.stat(), b.stat()
    except OSError:
        return False
    return (sa.st_dev, sa.st_ino) == (sb.st_dev, sb.st_ino)


def _writable_folder(p: Path, flag: str) -> None:
    parent = p.resolve().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise ScanlightError(p, f"{flag}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ScanlightError(p, f"{flag}: cannot write into the folder {parent} "
                                "(permission denied)")


def check_outputs(inputs: dict, outputs: dict) -> None:
    """``inputs`` and ``outputs`` map a flag name (``--cloud``) to a path or None (not given).
    Raises a ScanlightError naming the first problem."""
    ins = [(flag, Path(v)) for flag, v in inputs.items() if v]
    outs = [(flag, Path(v)) for flag, v in outputs.items() if v]
    for i, (flag, p) in enumerate(outs):
        if p.is_dir():
            raise ScanlightError(p, f"{flag} names a folder, not a file")
        for in_flag, q in ins:
            if q.exists() and _same_file(p, q):
                raise ScanlightError(p, f"{flag} is the same file as the input {in_flag}: "
                                        "refusing to overwrite an input")
        for other_flag, q in outs[:i]:
            if p.resolve() == q.resolve() or (p.exists() and q.exists() and _same_file(p, q)):
                raise ScanlightError(p, f"{flag} and {other_flag} name the same file")
        _writable_folder(p, flag)
