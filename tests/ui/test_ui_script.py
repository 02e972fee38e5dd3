"""`scanlight view --script FILE`: the documented automation option (the window tests and the
README screenshot use it). Offscreen here; tests/ui/test_ui_window.py drives the real window."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

SCRIPT = '''
import json
from pathlib import Path
seen = []

def on_frame(viewer, frame_index):
    seen.append([frame_index, viewer.engine.renderer_available])
    if frame_index == 2:
        out = Path(dict(a.split("=", 1) for a in viewer.script_args)["out"])
        out.write_text(json.dumps({"seen": seen, "args": viewer.script_args}))
        viewer.quit()
'''


def _view(*args, env=None):
    env = dict(os.environ if env is None else env, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "app", "view", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)


def test_script_runs_after_each_frame_with_its_arguments(tmp_path):
    """on_frame(viewer, i) after frames 0, 1, 2 (then the script quits before --frames)."""
    from tests.support.viewer import small_session

    from app.ui.app import run_viewer
    script = tmp_path / "shots.py"
    script.write_text(SCRIPT)
    out = tmp_path / "out.json"
    session = small_session().save(tmp_path / "s.json")
    args = argparse.Namespace(session=str(session), last=False, offscreen=True, frames=10,
                              screenshot=None, size="64x48", script=str(script),
                              script_arg=[f"out={out}", "mode=test"])
    assert run_viewer(args) == 0
    got = json.loads(out.read_text())
    assert got["seen"] == [[0, True], [1, True], [2, True]]
    assert got["args"] == [f"out={out}", "mode=test"]


@pytest.mark.parametrize("content, reason", [
    (None, "script not found"),
    ("x = 1\n", "no on_frame(viewer, frame_index) function"),
    ("def on_frame(viewer, i):\n  return (\n", "failed to load: SyntaxError"),
])
def test_a_bad_script_is_one_line_naming_the_file(tmp_path, content, reason):
    script = tmp_path / "bad_script.py"
    if content is not None:
        script.write_text(content)
    res = _view("--offscreen", "--frames", "1", "--size", "32x32", "--script", str(script))
    assert res.returncode == 3, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    assert str(script) in lines[0] and reason in lines[0], lines


def test_a_script_without_a_display_says_so(tmp_path):
    """No DISPLAY: the demo fallback cannot run a script, so the command says what to do."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = _view("--script", str(tmp_path / "x.py"), env=env)
    assert res.returncode == 2 and "--offscreen" in res.stderr and "Traceback" not in res.stderr


def test_save_window_png_does_not_overwrite_what_the_viewer_reads(tmp_path):
    """viewer.save_window_png has --screenshot's checks: a script that saved the window over the
    session's cloud used to overwrite it with PNG bytes (exit 0). Now that call is one line naming
    the file (exit 3, via on_frame's own line) and the cloud is untouched; a .png name elsewhere
    still works, and a name that is not .png is refused too."""
    from tests.support import scenes as S

    from app.errors import ScanlightError
    from app.io.pointcloud import save_cloud
    from app.ui.app import run_viewer
    cloud = tmp_path / "room.ply"
    save_cloud(S.box_room(spacing=0.25), cloud)
    before = cloud.read_bytes()
    for target, ok in ((str(cloud), False), (str(tmp_path / "shot.jpg"), False),
                       (str(tmp_path / "shot.png"), True)):
        script = tmp_path / "save.py"
        script.write_text(f"def on_frame(viewer, i):\n    viewer.save_window_png({target!r})\n"
                          "    viewer.quit()\n")
        args = argparse.Namespace(cloud=str(cloud), session=None, last=False, offscreen=True,
                                  frames=3, screenshot=None, size="64x48", script=str(script),
                                  script_arg=[])
        if ok:
            assert run_viewer(args) == 0 and Path(target).read_bytes()[:4] == b"\x89PNG"
        else:
            with pytest.raises(ScanlightError) as err:
                run_viewer(args)
            assert "save.py" in str(err.value) and len(str(err.value).splitlines()) == 1
    assert cloud.read_bytes() == before
