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
    if not os.access(p, os.R_OK):
        raise ScanlightError(p, f"cannot read the {kind} file (permission denied)")
    return p


def temp_beside(target: Path) -> Path:
    """A new empty hidden file in ``target``'s folder to write ``target`` into, then rename:
    a short ASCII name of its own (``.sl-XXXXXXXX`` plus the target's extension when that is
    plain ASCII, which writers such as OpenEXR and Pillow choose the format from). Named after
    the target, the temporaries of a long name (a set's temporary written through a writer's own
    ``atomic_output``: two prefixes) passed the 255-byte limit where the target itself fit, and
    OpenEXR cannot open a name holding bytes that are not UTF-8. Missing folders are made; a
    folder that cannot be is one ScanlightError line naming ``target`` (``write_failure``)."""
    suffix = target.suffix if target.suffix.isascii() and target.suffix.isprintable() else ""
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".sl-", suffix=suffix[:16], dir=target.parent)
    except OSError as exc:
        raise write_failure(target, exc) from None
    os.close(fd)
    return Path(tmp)


def write_failure(target, exc: BaseException) -> ScanlightError | None:
    """The one line for ``target`` that could not be written because of ``exc`` - a full disk,
    a file-size or open-files limit, a read-only mount, OpenEXR's own write error - or None
    when ``exc`` is not such a failure (a bug, Ctrl-C: raised as it is)."""
    if isinstance(exc, ScanlightError) or not isinstance(exc, (OSError, WriteError)):
        return None
    reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
    return ScanlightError(target, f"could not be written: {reason}")


class WriteError(Exception):
    """A writer library's failure to write its file (OpenEXR raises RuntimeError for a full
    disk), told apart from a bug so that ``atomic_output`` reports it as one line."""


@contextlib.contextmanager
def atomic_output(path):
    """Yield a temporary path beside ``path`` (``temp_beside``); rename it over ``path`` on
    success. A write that fails for want of room, a limit or permission is one ScanlightError
    line naming ``path`` (``write_failure``); the temporary is removed either way."""
    p = Path(path)
    if p.exists() and not p.is_file():     # a folder, /dev/null, a pipe: never replace it
        raise ScanlightError(p, "is a folder or a special file, not a file to write")
    tmp = temp_beside(p)
    try:
        yield tmp
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; outputs are ordinary user files
        os.replace(tmp, p)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        failure = write_failure(p, exc)
        if failure is not None:
            raise failure from None
        raise


def read_json(path, kind: str):
    """Parsed JSON of a ``kind`` file (camera, material, object, session...), or one error line
    (app.io.schema.parse_json: invalid, or nested too deep; larger than
    MAX_JSON_BYTES; unreadable)."""
    from app.io.limits import MAX_JSON_BYTES
    from app.io.schema import parse_json
    p = require_file(path, kind)
    size = p.stat().st_size
    if size > MAX_JSON_BYTES:
        raise ScanlightError(p, f"{kind} file of {size:,} bytes is larger than the limit of "
                                f"{MAX_JSON_BYTES:,} for a JSON file")
    try:
        data = p.read_bytes()
    except PermissionError:
        raise ScanlightError(p, f"cannot read the {kind} file (permission denied)") from None
    return parse_json(data, p, "JSON")


def jsonable(obj):
    """``obj`` with numpy scalars/arrays as Python values and non-finite floats as None (null),
    so reports never contain NaN, which JSON does not allow."""
    import math

    import numpy as np
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, (str, int, float, bool)) or obj is None:
        return obj
    return str(obj)


def write_json(path, obj) -> None:
    """``obj`` as indented JSON, atomically (see ``jsonable``)."""
    import json
    with atomic_output(path) as tmp:
        Path(tmp).write_text(json.dumps(jsonable(obj), indent=1, allow_nan=False))
