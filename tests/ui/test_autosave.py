"""The autosave's timing (debounce and maximum wait, on a fake clock), what a crash leaves, and
restoring / discarding it (app/ui/autosave.py). The real kill-and-restore in the window is
tests/ui/test_ui_e2e.py."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from app.cloud import PointCloud
from app.settings import load_session
from app.ui import autosave
from app.ui.autosave import DELAY_S, MAX_WAIT_S, POLL_S, Autosaver


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


@pytest.fixture
def session():
    from tests.support.viewer import small_session
    return small_session()


def _tick_for(saver, clock, session, seconds, step=0.05, change=None):
    saved = []
    end = clock.t + seconds
    while clock.t < end:
        if change:
            change()
        if saver.tick(session, session.camera):
            saved.append(clock.t)
        clock.t += step
    return saved


def test_saves_once_the_session_is_quiet(tmp_path, session):
    clock = Clock()
    saver = Autosaver(tmp_path, clock)
    assert _tick_for(saver, clock, session, 1.0) == []          # nothing changed: no write
    assert not saver.path.exists()
    session.settings.set("pbgi.microbuffer", 12)
    saved = _tick_for(saver, clock, session, DELAY_S + 1.0)
    assert len(saved) == 1 and saver.path.is_file()
    assert json.loads(saver.path.read_text())["settings"]["pbgi.microbuffer"] == 12
    assert _tick_for(saver, clock, session, 5.0) == []          # unchanged since: no rewrite


def test_a_long_drag_is_saved_by_the_maximum_wait(tmp_path, session):
    clock = Clock()
    saver = Autosaver(tmp_path, clock)
    values = iter(np.linspace(0.0, 1.0, 10000))
    saved = _tick_for(saver, clock, session, MAX_WAIT_S + 1.0,
                      change=lambda: session.settings.set("view.exposure", next(values)))
    assert len(saved) == 1                                     # while the drag never stopped
    assert saved[0] - 100.0 == pytest.approx(MAX_WAIT_S, abs=POLL_S + 0.1)


def test_an_in_memory_hdr_cloud_is_written_beside_once(tmp_path, session):
    clock = Clock()
    saver = Autosaver(tmp_path, clock)
    hdr = PointCloud(np.zeros((4, 3)), np.tile([0.0, 1.0, 0.0], (4, 1)),
                     np.full((4, 3), 3.5, np.float32), hdr=True)
    session.settings.set("pbgi.microbuffer", 12)
    for _ in range(int((DELAY_S + 1) / 0.05)):
        saver.tick(session, session.camera, hdr)
        clock.t += 0.05
    ply = saver.path.with_suffix(".hdr.ply")
    doc = json.loads(saver.path.read_text())
    assert ply.is_file() and doc["files"]["hdr_cloud"] == str(ply.resolve())
    assert session.hdr_cloud is None                           # the live session is untouched


def test_leftovers_are_only_those_of_dead_windows(tmp_path, session):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    session.settings.set("pbgi.mode", "envmap")
    doc = session.to_dict(None)
    doc["autosave"] = {"pid": int(dead), "saved_at": 1e9}
    (tmp_path / f"autosave-{dead}.json").write_text(json.dumps(doc))
    alive = dict(doc, autosave={"pid": os.getppid(), "saved_at": 1e9})
    (tmp_path / f"autosave-{os.getppid()}.json").write_text(json.dumps(alive))
    (tmp_path / "autosave-junk.json").write_text("{")
    found = autosave.leftovers(tmp_path)
    assert [f.path.name for f in found] == [f"autosave-{dead}.json"]
    assert "mode envmap" in found[0].describe()
    restored = autosave.recover(found[0], tmp_path)
    assert not (tmp_path / f"autosave-{dead}.json").exists()
    assert restored.parent.parent == tmp_path / "recovered"
    assert load_session(restored).mode == "envmap"
    assert autosave.leftovers(tmp_path) == []


def test_a_normal_close_leaves_nothing(tmp_path, session):
    clock = Clock()
    saver = Autosaver(tmp_path, clock)
    session.settings.set("pbgi.microbuffer", 12)
    _tick_for(saver, clock, session, DELAY_S + 1)
    assert saver.path.exists()
    saver.close()
    assert not list(tmp_path.glob("autosave-*"))
