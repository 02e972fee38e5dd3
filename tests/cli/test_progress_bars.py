"""Progress bars on the long CLI jobs besides turntable (tests/cli/test_turntable.py has the
helper's own test): ``render`` counts its passes and silhouette samples on a terminal, ``expand``
shows its fraction and stage; neither draws anything into a pipe."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from app.io.pointcloud import save_cloud
from tests.support import scenes as S
from tests.support.terminal import read_terminal


def _render_args(d):
    save_cloud(S.box_room(0.1), d / "room.ply")
    (d / "obj.json").write_text(json.dumps({"mesh": "sphere", "translate": [0, 0.8, 0],
                                            "scale": 0.6}))
    (d / "cam.json").write_text(json.dumps({"position": [0.3, 1.0, 0.9], "look_at": [0, 0.8, 0],
                                            "fov_y_deg": 40, "width": 16, "height": 12}))
    return [sys.executable, "-m", "app", "render", "--cloud", str(d / "room.ply"),
            "--object", str(d / "obj.json"), "--camera", str(d / "cam.json"),
            "--microbuffer", "8", "--passes", "3", "--edge-samples", "1",
            "--out", str(d / "o.exr")]


def test_render_draws_a_bar_of_its_passes_on_a_terminal(tmp_path):
    args = _render_args(tmp_path)
    master, slave = os.openpty()
    try:
        res = subprocess.run(args, stderr=slave, stdout=subprocess.PIPE, timeout=600)
        os.close(slave)
        drawn = read_terminal(master)
    finally:
        os.close(master)
    assert res.returncode == 0, drawn
    assert "render" in drawn and "3/3" in drawn
    piped = subprocess.run(args, capture_output=True, text=True, timeout=600)
    assert piped.returncode == 0 and "pass 3/3" in piped.stderr     # the log lines stay
    assert "|" not in piped.stderr and "\r" not in piped.stderr        # no bar in a pipe


def test_expand_progress_is_a_bar_on_a_terminal_and_lines_elsewhere(monkeypatch, capsys):
    from app.commands.expand import _StderrProgress
    from app.commands.progress import progress
    master, slave = os.openpty()
    with os.fdopen(slave, "w") as tty:
        monkeypatch.setattr(sys, "stderr", tty)
        with progress(100, "expand", unit="%") as bar:
            show = _StderrProgress(bar=bar)
            show(0.25, "patchmatch")
            show(1.0, "poisson")
        tty.flush()
        drawn = read_terminal(master)
    os.close(master)
    monkeypatch.undo()
    assert "expand" in drawn and "100/100" in drawn and "poisson" in drawn
    show = _StderrProgress()                          # not a terminal: lines
    show(0.25, "patchmatch")
    show(0.26, "patchmatch")                          # the same 10% step: no new line
    show(1.0, "poisson")
    assert capsys.readouterr().err.splitlines() == ["expand:  25% patchmatch",
                                                     "expand: 100% poisson"]
