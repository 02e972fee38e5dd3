"""`scanlight view --offscreen`: batch screenshots of the demo scene against reference images.

Metric and tolerance: tests/support/images.py (mean |diff| <= 0.5 of 255, <= 0.2% pixels off by > 16).
Regenerate on purpose with SCANLIGHT_UPDATE_REFERENCES=1 (tests/ui/references/README.md).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import pytest
from tests.support.images import MAX_BAD, MAX_MEAN, check_reference, difference, read_png

ROOT = Path(__file__).resolve().parents[2]
TESTS = Path(__file__).resolve().parent
MODES = ("classic", "mipmapped", "hybrid", "envmap")
SIZE = "128x128"
MICROBUFFER = 16     # the references' micro-buffer (set in the session, as a user would)


def _args(**kw):
    base = dict(session=None, last=False, offscreen=True, frames=2, screenshot=None, size=SIZE)
    base.update(kw)
    return argparse.Namespace(**base)


def _session_file(tmp_path, mode="classic") -> Path:
    from tests.support.viewer import small_session
    s = small_session(MICROBUFFER, **{"pbgi.mode": mode})
    return s.save(tmp_path / f"demo-{mode}.json")


@pytest.mark.parametrize("mode", MODES)
def test_offscreen_demo_matches_reference(mode, tmp_path, monkeypatch):
    """The demo scene, the asset relit by the PBGI renderer, one reference per mode."""
    from tests.support.viewer import spy_renders

    from app.render.context import get_context
    from app.settings import load_session
    from app.ui.app import OffscreenViewer
    calls = spy_renders(monkeypatch)
    viewer = OffscreenViewer(load_session(_session_file(tmp_path, mode)), (128, 128))
    assert viewer.ctx is get_context()
    out = tmp_path / f"{mode}.png"
    viewer.run(2, str(out))
    assert out.is_file() and out.with_suffix(".exr").is_file()
    errors = [m.text for m in viewer.engine.messages if m.level == "error"]
    assert not errors, errors
    assert calls and {(c.mode, c.microbuffer) for c in calls} == {(mode, MICROBUFFER)}
    assert all(c.completed for c in calls)          # no pass cut short by the loop budget
    img = read_png(out)
    asset = viewer.engine.view.read_linear()[..., 3] > 0
    assert asset.sum() > 300                        # the relit sphere is in the picture
    check_reference(f"ui_demo_{mode}.png", img)


def test_cli_offscreen_screenshot_is_what_the_engine_draws(tmp_path):
    """The documented command, end to end, in a fresh process: the classic reference again."""
    out = tmp_path / "cli.png"
    env = dict(os.environ, PYTHONPATH=str(ROOT), SCANLIGHT_CONFIG=str(tmp_path / "cfg"))
    cmd = [sys.executable, "-m", "app", "view", "--offscreen", "--session",
           str(_session_file(tmp_path)), "--frames", "3", "--screenshot", str(out), "--size", SIZE]
    res = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "screenshot:" in res.stdout and "scanlight view: error" not in res.stderr, res.stderr
    ref = TESTS / "references" / "ui_demo_classic.png"
    if not ref.is_file():
        pytest.skip("no classic reference yet (test_offscreen_demo_matches_reference writes it)")
    mean, bad = difference(read_png(out), read_png(ref))
    assert mean <= MAX_MEAN and bad <= MAX_BAD, (mean, bad)


def test_last_session_reopens(tmp_path, monkeypatch):
    from app.settings import save_last_session
    from app.ui.app import open_session
    from app.ui.engine import default_session
    monkeypatch.setenv("SCANLIGHT_CONFIG", str(tmp_path / "cfg"))
    s = default_session()
    s.settings.set("view.exposure", 2.5)
    save_last_session(s)
    assert open_session(_args(last=True)).settings["view.exposure"] == 2.5
    assert open_session(_args()).settings["view.exposure"] == 0.0     # no flag: the demo


def test_cli_reports_bad_arguments_in_one_line(tmp_path):
    from app.errors import UsageError
    from app.ui.app import parse_size, run_viewer
    assert parse_size("640x480") == (640, 480)
    for bad in ("640", "0x10", "axb"):
        with pytest.raises(UsageError, match="--size"):
            parse_size(bad)
    with pytest.raises(UsageError, match="either --session or --last"):
        run_viewer(_args(session="x.json", last=True))
    from app.errors import ScanlightError
    with pytest.raises(ScanlightError, match="session file not found"):
        run_viewer(_args(session=str(tmp_path / "nope.json")))


@pytest.mark.parametrize("broken", ["cloud", "asset"])
def test_offscreen_fails_with_exit_3_and_no_screenshot_when_a_file_does_not_load(broken,
                                                                                  tmp_path):
    """It used to print the errors, write a screenshot of the half-loaded scene and exit 0."""
    from tests.support.viewer import small_session
    s = small_session()
    bad = tmp_path / ("missing.ply" if broken == "cloud" else "corrupt.obj")
    if broken == "cloud":
        s.cloud, s.photo = str(bad), None
    else:
        bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
        s.asset = str(bad)
    session = s.save(tmp_path / "s.json")
    out = tmp_path / "shot.png"
    env = dict(os.environ, PYTHONPATH=str(ROOT), SCANLIGHT_CONFIG=str(tmp_path / "cfg"))
    res = subprocess.run([sys.executable, "-m", "app", "view", "--offscreen", "--session",
                          str(session), "--frames", "1", "--size", "32x24", "--screenshot",
                          str(out)], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=300)
    err = res.stderr.strip().splitlines()
    assert res.returncode == 3, res.stderr
    assert len(err) == 1 and bad.name in err[0], res.stderr
    assert not out.exists() and not out.with_suffix(".exr").exists()


def test_offscreen_screenshot_must_be_a_png(tmp_path):
    from app.errors import UsageError
    from app.ui.app import run_viewer
    with pytest.raises(UsageError, match=r"\.png"):
        run_viewer(_args(screenshot=str(tmp_path / "s.jpg")))
