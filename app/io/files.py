"""File checks and atomic writes shared by every reader and writer in app.io.

Readers call ``require_file`` first so that a missing, empty or wrongly named file fails with one
ScanlightError line before any parser (some of which print C-level noise) sees it. Writers go
through ``atomic_output`` so that a crash or a full disk never leaves a half-written file under the
final name: the data goes to a temporary file in the same folder and is renamed over the target.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from app.errors import ScanlightError


def require_file(path, kind: str, extensions: tuple[str, ...] | None = None) -> Path:
    """The path as a Path once it names an existing, non-empty file with a known extension."""
    p = Path(path)
    if extensions is not None:
        ext = p.suffix.lower()
        if ext not in extensions:
            raise ScanlightError(p, f"unsupported {kind} file extension {p.suffix or '(none)'!r} "
                                    f"(supported: {', '.join(extensions)})")
    if not p.exists():
        raise ScanlightError(p, f"{kind} file not found")
    if not p.is_file():
        raise ScanlightError(p, f"{kind} path is not a file")
    if p.stat().st_size == 0:
        raise ScanlightError(p, f"{kind} file is empty")
    return p


@contextlib.contextmanager
def atomic_output(path):
    """Yield a temporary path beside ``path`` (same extension); rename it over ``path`` on success.

    The temporary file keeps the target's extension because some writers (OpenEXR, Pillow) choose
    the format from it.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.stem}.", suffix=p.suffix, dir=p.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; outputs are ordinary user files
        os.replace(tmp, p)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
