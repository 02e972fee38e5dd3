"""The window saves the last session when it closes (app/ui/window.py ``_save_last``). A config
folder that cannot be written is no bug: one warning line naming the file, as the autosave's
failure, no traceback and no "failed" error - and the viewer still exits 0."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support import scenes as S
from app.errors import ScanlightError
from app.io.pointcloud import save_cloud
from app.settings import Session, save_last_session

ROOT = Path(__file__).resolve().parents[2]


def _unwritable(tmp_path) -> Path:
    """A config folder that cannot be made, without root: its parent is a regular file."""
    (tmp_path / "afile").write_text("x")
    return tmp_path / "afile" / "cfg"


def test_save_last_session_names_the_file_it_could_not_write(tmp_path, monkeypatch):
    monkeypatch.setenv("SCANLIGHT_CONFIG", str(_unwritable(tmp_path)))
    s = Session()
    with pytest.raises(ScanlightError, match="last_session.json"):
        save_last_session(s)
    assert s.path is None


@pytest.mark.window
def test_closing_the_window_with_an_unwritable_config_folder_is_one_warning(tmp_path):
    if not os.environ.get("DISPLAY"):
        pytest.skip("no X display (run the tests under xvfb-run, as packaging/test.sh does)")
    save_cloud(S.box_room(0.1), tmp_path / "room.ply")
    (tmp_path / "obj.json").write_text(json.dumps({"mesh": "sphere", "scale": 0.3}))
    cfg = _unwritable(tmp_path)
    env = dict(os.environ, PYTHONPATH=str(ROOT), SCANLIGHT_CONFIG=str(cfg))
    cmd = [sys.executable, "-m", "app", "view", str(tmp_path / "room.ply"),
           str(tmp_path / "obj.json"), "--frames", "3", "--size", "64x64"]
    res = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "Traceback" not in res.stderr and "ERROR" not in res.stderr, res.stderr[-3000:]
    said = [ln for ln in res.stderr.splitlines() if "last_session.json" in ln]
    assert len(said) == 1 and said[0].startswith("WARNING"), res.stderr[-3000:]
    assert str(cfg / "last_session.json") in said[0]
