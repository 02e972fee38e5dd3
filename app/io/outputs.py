"""A command's output paths checked against its inputs and each other before any work.

A careless command line must not destroy data: ``render --stats room.ply`` used to overwrite the
cloud it had just read, ``expand --out`` naming the input cloud replaced it, ``evaluate --json``
naming the ground truth wrote JSON over it, and ``--stats`` equal to ``--out`` left one of the
two. ``check_outputs`` refuses all of these up front, with one line naming the file (exit 3):

- an output that is the same file as an input: the same resolved path (symbolic links followed)
  or, when both exist, the same device and inode (hard links);
- two outputs naming the same file;
- an output that is an existing folder, or a special file (a device, a pipe, a socket: the
  rename at the end replaced them with a regular file - as root, ``--report /dev/null`` replaced
  /dev/null);
- an output whose folder cannot be written: the nearest existing folder above it (missing
  folders are created when the output is written) must be a folder the user may write into.

``check_output_folder`` does the same for a command whose output is a folder (``demo --out``).

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


def check_output_folder(p: Path, flag: str) -> None:
    """An output *folder* (``demo --out``): an existing file there, or a folder the user may
    not write into, is one line naming it (exit 3), before any work - not an OSError after it."""
    p = Path(p)
    if p.exists() and not p.is_dir():
        raise ScanlightError(p, f"{flag} names a file, not a folder")
    if p.is_dir():
        if not os.access(p, os.W_OK | os.X_OK):
            raise ScanlightError(p, f"{flag}: cannot write into the folder (permission denied)")
        return
    _writable_folder(p, flag)


def check_outputs(inputs: dict, outputs: dict) -> None:
    """``inputs`` and ``outputs`` map a flag name (``--cloud``) to a path or None (not given).
    Raises a ScanlightError naming the first problem."""
    ins = [(flag, Path(v)) for flag, v in inputs.items() if v]
    outs = [(flag, Path(v)) for flag, v in outputs.items() if v]
    for i, (flag, p) in enumerate(outs):
        if p.is_dir():
            raise ScanlightError(p, f"{flag} names a folder, not a file")
        if p.exists() and not p.is_file():
            raise ScanlightError(p, f"{flag} names a special file (a device, pipe or socket), "
                                    "which the output would replace")
        for in_flag, q in ins:
            if q.exists() and _same_file(p, q):
                raise ScanlightError(p, f"{flag} is the same file as the input {in_flag}: "
                                        "refusing to overwrite an input")
        for other_flag, q in outs[:i]:
            if p.resolve() == q.resolve() or (p.exists() and q.exists() and _same_file(p, q)):
                raise ScanlightError(p, f"{flag} and {other_flag} name the same file")
        _writable_folder(p, flag)


COMMITTED: list[tuple[str, ...]] = []   # target sets committed by this process, in order


class OutputSet:
    """All outputs of one command, committed together or not at all.

    ``with OutputSet({"--out": path, "--stats": path2}) as outs:`` then write each output to
    ``outs.temp(flag)`` (a hidden temporary beside its target, same extension, so writers that
    pick the format from it still work). Leaving the block normally renames every temporary over
    its target, under an exclusive lock on the targets' folders, with Ctrl-C held off for those
    few renames: two runs into the same outputs cannot interleave (one run's cloud with the
    other's report), and an interrupted run never leaves half of its outputs. Leaving it by an
    exception (an error, Ctrl-C) deletes the temporaries: nothing is written, and the caller
    says so.
    """

    def __init__(self, outputs: dict):
        self.targets = {flag: Path(v) for flag, v in outputs.items() if v}
        self._temps: dict[str, Path] = {}

    def temp(self, flag: str) -> Path:
        if flag not in self._temps:
            from app.io.files import temp_beside
            self._temps[flag] = temp_beside(self.targets[flag])
        return self._temps[flag]

    def __enter__(self) -> "OutputSet":
        return self

    def __exit__(self, kind, exc, tb) -> bool:
        if kind is None:
            self._commit()
            return False
        targets = {str(t): self.targets[f] for f, t in self._temps.items()}
        self._discard()
        # a writer's failure names the temporary it wrote: say which output could not be
        # written instead (a full disk, a limit: app/io/files.py write_failure)
        if isinstance(exc, ScanlightError) and exc.path in targets:
            raise ScanlightError(targets[exc.path], exc.reason) from None
        if isinstance(exc, OSError) and str(exc.filename) in targets:
            from app.io.files import write_failure
            raise write_failure(targets[str(exc.filename)], exc) from None
        return False

    def discard(self) -> None:
        """Give up: delete the temporaries (leaving the block then commits nothing)."""
        self._discard()

    def _discard(self) -> None:
        for tmp in self._temps.values():
            try:
                tmp.unlink()
            except OSError:
                pass
        self._temps.clear()

    def _folders(self) -> list[Path]:
        """The targets' folders, sorted (every process takes them in the same order)."""
        return sorted({p.resolve().parent for p in self.targets.values()})

    def _commit(self) -> None:
        import fcntl
        import signal
        umask = os.umask(0)
        os.umask(umask)
        previous = signal.getsignal(signal.SIGINT)
        in_main = _main_thread()
        held: list[int] = []
        try:
            # The lock is an flock on each target's folder: a lock file per set of targets, in
            # the temporary folder, was never removed (one per output set ever written), and
            # removing it would race with a waiting process.
            for folder in self._folders():
                fd = os.open(folder, os.O_RDONLY)
                held.append(fd)
                fcntl.flock(fd, fcntl.LOCK_EX)
            if in_main:
                signal.signal(signal.SIGINT, signal.SIG_IGN)  # the renames are one step
            for flag in self._temps:          # a target that became a folder meanwhile:
                target = self.targets[flag]   # refuse before the first rename, not after
                if target.exists() and not target.is_file():
                    raise ScanlightError(target, f"{flag} became a folder or a special file "
                                                 "while the command ran; nothing written")
            for flag, tmp in self._temps.items():
                os.chmod(tmp, 0o666 & ~umask)   # mkstemp makes 0600: outputs are user files
                os.replace(tmp, self.targets[flag])
            COMMITTED.append(tuple(str(self.targets[f]) for f in self._temps))
            self._temps.clear()
        except BaseException as exc:
            self._discard()
            if isinstance(exc, OSError):     # a rename refused: name its target
                raise ScanlightError(exc.filename2 or exc.filename,
                                     f"could not be written: {exc.strerror or exc}") from None
            raise
        finally:
            for fd in held:
                os.close(fd)              # closing releases its flock
            if in_main:
                signal.signal(signal.SIGINT, previous)


def _main_thread() -> bool:
    import threading
    return threading.current_thread() is threading.main_thread()
