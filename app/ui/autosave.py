"""No lost work: the window's session is autosaved while it runs and offered back after a crash.

Each running window writes ``autosave-<pid>.json`` in the config folder (app/settings.py
``config_dir``) a short while after the session last changed (``DELAY_S``; at the latest
``MAX_WAIT_S`` after the first unsaved change, so a long slider drag is saved too). An HDR cloud
that exists only in memory (an expansion run in the window) is written beside it once, as
``autosave-<pid>.hdr.ply``. A normal exit removes both files (the session then lives on as
``last_session.json``); so files whose process is gone are what a crash or a kill left, and the
next window start offers to restore the newest of them. Restoring moves the files to
``recovered/<time>/`` first, so the restored session's HDR cloud keeps existing and nothing is
deleted behind the user's back; discarding deletes them. Offscreen runs never autosave and never
ask.

The snapshot compared and written is the session's JSON with the current view camera, taken at
most every ``POLL_S`` so that an idle window costs nothing.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import time
from dataclasses import dataclass, replace
from pathlib import Path

from app.errors import ScanlightError
from app.settings import Session, config_dir

log = logging.getLogger(__name__)

DELAY_S = 2.0       # quiet time after a change before saving
MAX_WAIT_S = 15.0   # an unsaved change is saved by then even while the user keeps editing
POLL_S = 0.25       # how often the session is compared with the last save
PREFIX = "autosave-"


def _alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:    # someone else's process: alive, not ours to restore
        return True
    return True


@dataclass(frozen=True)
class Leftover:
    """An autosave whose window is gone."""

    path: Path
    saved_at: float
    summary: str

    @property
    def hdr_path(self) -> Path:
        return self.path.with_suffix(".hdr.ply")

    def describe(self) -> str:
        when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(self.saved_at))
        return f"autosaved {when}: {self.summary}"


def _summary(doc: dict) -> str:
    files = doc.get("files") or {}
    cams = len(doc.get("capture_cameras") or [])

    def name(v):
        return "(none)" if not v else Path(str(v)).name
    hdr = "with its HDR cloud" if files.get("hdr_cloud") else "LDR only"
    return (f"cloud {name(files.get('cloud'))} ({hdr}), asset {name(files.get('asset'))}, "
            f"{cams} capture camera{'s' if cams != 1 else ''}, mode {doc.get('mode')}")


def leftovers(folder: Path | None = None) -> list[Leftover]:
    """Autosaves of windows that are not running any more, newest first."""
    folder = config_dir() if folder is None else Path(folder)
    out = []
    for p in folder.glob(f"{PREFIX}*.json"):
        try:
            pid = int(p.stem[len(PREFIX):])
        except ValueError:
            continue
        if pid == os.getpid() or _alive(pid):
            continue
        try:
            doc = json.loads(p.read_text(encoding="utf-8"))
            out.append(Leftover(p, float(doc.get("autosave", {}).get("saved_at", p.stat().st_mtime)),
                                _summary(doc)))
        except (OSError, ValueError, AttributeError) as exc:
            log.warning("%s: unreadable autosave (%s)", p, exc)
    return sorted(out, key=lambda x: -x.saved_at)


def recover(left: Leftover, folder: Path | None = None) -> Path:
    """Move ``left`` (and its HDR cloud) to ``recovered/<time>/``; returns the session file
    there, whose HDR cloud path points at the moved cloud."""
    folder = config_dir() if folder is None else Path(folder)
    stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(left.saved_at))
    dest = folder / "recovered" / stamp
    n = 1
    while dest.exists():
        n += 1
        dest = folder / "recovered" / f"{stamp}-{n}"
    dest.mkdir(parents=True)
    doc = json.loads(left.path.read_text(encoding="utf-8"))
    if left.hdr_path.is_file():
        shutil.move(str(left.hdr_path), dest / "session.hdr.ply")
        doc.setdefault("files", {})["hdr_cloud"] = str((dest / "session.hdr.ply").resolve())
    doc.pop("autosave", None)
    target = dest / "session.json"
    target.write_text(json.dumps(doc, indent=1), encoding="utf-8")
    left.path.unlink()
    return target


def discard(left: Leftover) -> None:
    for p in (left.path, left.hdr_path):
        if p.exists():
            p.unlink()


class Autosaver:
    """The running window's autosave (``tick`` once per frame, ``close`` on a normal exit)."""

    def __init__(self, folder: Path | None = None, clock=time.monotonic):
        self.folder = config_dir() if folder is None else Path(folder)
        self.path = self.folder / f"{PREFIX}{os.getpid()}.json"
        self.clock = clock
        self.saves = 0
        self.error: str | None = None
        self._saved = None          # the last snapshot written
        self._seen = None           # the last snapshot compared
        self._first_change = self._last_change = None
        self._last_poll = -1e9
        self._hdr_written = None    # id() of the in-memory HDR cloud already on disk

    def _snapshot(self, session: Session, camera, hdr_cloud) -> str:
        s = replace(session, camera=camera)
        if hdr_cloud is not None and not session.hdr_cloud:
            s = replace(s, hdr_cloud=str(self.path.with_suffix(".hdr.ply").resolve()))
        return json.dumps(s.to_dict(None), sort_keys=True)

    def tick(self, session: Session, camera, hdr_cloud=None) -> bool:
        """Compare the session with the last save (at most every POLL_S); save it when it has
        been quiet for DELAY_S or unsaved for MAX_WAIT_S. True when it saved."""
        now = self.clock()
        if now - self._last_poll < POLL_S:
            return self._save_if_due(now, session, hdr_cloud)
        self._last_poll = now
        snap = self._snapshot(session, camera, hdr_cloud)
        if snap != self._seen:
            self._seen = snap
            if snap != self._saved:
                self._last_change = now
                if self._first_change is None:
                    self._first_change = now
        return self._save_if_due(now, session, hdr_cloud)

    def _save_if_due(self, now, session, hdr_cloud) -> bool:
        if self._first_change is None:
            return False
        if now - self._last_change < DELAY_S and now - self._first_change < MAX_WAIT_S:
            return False
        self._first_change = self._last_change = None
        try:
            self._write(self._seen, session, hdr_cloud)
        except (OSError, ScanlightError) as exc:
            self.error = f"autosave to {self.path} failed: {exc}"
            log.warning("%s", self.error)
            return False
        self.error = None
        self._saved = self._seen
        self.saves += 1
        return True

    def _write(self, snap: str, session: Session, hdr_cloud) -> None:
        from app.io.files import atomic_output
        self.folder.mkdir(parents=True, exist_ok=True)
        if hdr_cloud is not None and not session.hdr_cloud and id(hdr_cloud) != self._hdr_written:
            from app.io.pointcloud import save_cloud
            save_cloud(hdr_cloud, self.path.with_suffix(".hdr.ply"))
            self._hdr_written = id(hdr_cloud)
        doc = json.loads(snap)
        doc["autosave"] = {"pid": os.getpid(), "saved_at": time.time()}
        with atomic_output(self.path) as tmp:
            Path(tmp).write_text(json.dumps(doc, indent=1), encoding="utf-8")

    def close(self) -> None:
        """A normal exit: nothing to restore next time."""
        for p in (self.path, self.path.with_suffix(".hdr.ply")):
            if p.exists():
                p.unlink()
