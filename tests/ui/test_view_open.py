"""``scanlight view [CLOUD] [ASSET]`` and drag-and-drop of a mesh: the mesh stands on the scan's
floor (app/io/placement.py), as ``render --object`` places it.

The test room (tests/support/scenes.py: box_room) has its floor at y = 0 and its x/z centre at
(0, 0); the demo room's floor is y = 0 too (app/demo/room.py)."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from app.io.pointcloud import save_cloud
from tests.support import scenes as S

ROOT = Path(__file__).resolve().parents[2]
BUNNY = ROOT.parent / "shared" / "data" / "bunny.glb"
PROBE = '''
import json
from pathlib import Path
import numpy as np

def on_frame(viewer, frame):
    e = viewer.engine
    out = dict(a.split("=", 1) for a in viewer.script_args)["out"]
    lo, hi = e.mesh.bounds()
    Path(out).write_text(json.dumps({
        "frame": frame, "cloud": e.session.cloud, "asset": e.session.asset,
        "points": len(e.cloud.ldr), "bounds": [lo.tolist(), hi.tolist()],
        "floor_y": e.room().floor_y,
        "coverage": int((e.view.read_linear()[..., 3] > 0).sum()),
        "messages": [m.text for m in e.messages if m.level == "error"]}))
'''
TRIANGLE_OBJ = "v 0 0 0\nv 2 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("view_open")
    save_cloud(S.box_room(0.1), d / "room.ply")
    (d / "probe.py").write_text(PROBE)
    (d / "tet.obj").write_text(TRIANGLE_OBJ)
    (d / "bad.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
    return d


def test_view_cloud_asset_offscreen_opens_both_on_the_floor(files, tmp_path):
    """The documented command in a fresh process: the scan and the bunny (fitted to 0.5 m)
    standing on its floor below its centre, framed in the picture."""
    if not BUNNY.is_file():
        pytest.skip("no ../shared/data/bunny.glb")
    d = files
    out = tmp_path / "probe.json"
    env = dict(os.environ, PYTHONPATH=str(ROOT), SCANLIGHT_CONFIG=str(tmp_path / "cfg"))
    cmd = [sys.executable, "-m", "app", "view", str(d / "room.ply"), str(BUNNY), "--fit", "0.5",
           "--offscreen", "--frames", "2", "--size", "48x48", "--script", str(d / "probe.py"),
           "--script-arg", f"out={out}"]
    res = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    got = json.loads(out.read_text())
    assert got["frame"] == 1 and not got["messages"]
    assert got["cloud"] == str((d / "room.ply").resolve())
    assert got["asset"] == str(BUNNY.resolve())
    lo, hi = (np.array(v) for v in got["bounds"])
    assert got["floor_y"] == pytest.approx(0.0, abs=1e-6)
    assert lo[1] == pytest.approx(got["floor_y"], abs=1e-6)           # standing on the floor
    assert np.max(hi - lo) == pytest.approx(0.5, abs=1e-6)            # --fit 0.5
    np.testing.assert_allclose(((lo + hi) / 2)[[0, 2]], (0.0, 0.0), atol=0.03)
    assert got["coverage"] > 0.1 * 48 * 48                            # framed: in the picture


def test_dropping_a_mesh_stands_it_on_the_floor(ctx, files):
    """Drag-and-drop (window.open_path -> open_into with the engine's room): the OBJ in its own
    units (2 m wide), on the demo room's floor below its centre; an object JSON keeps its own
    placement (tests/ui/test_ui_engine.py: test_opening_files_by_kind)."""
    from app.pbgi.renderer import Relighter
    from app.ui.engine import ViewerEngine
    from app.ui.files import open_into
    from tests.support.viewer import small_session
    e = ViewerEngine(ctx, small_session(), size=(48, 36), relighter=Relighter)
    e.frame()
    room = e.room()
    assert room.floor_found and room.floor_y == pytest.approx(0.0, abs=1e-6)
    assert open_into(e.session, files / "tet.obj", room=e.room) == "asset"
    e.frame()
    assert not [m for m in e.messages if m.level == "error"]
    lo, hi = e.mesh.bounds()
    np.testing.assert_allclose(hi - lo, (2.0, 1.0, 1.0), atol=1e-9)
    assert lo[1] == pytest.approx(room.floor_y, abs=1e-9)
    np.testing.assert_allclose(((lo + hi) / 2)[[0, 2]], room.centre_xz, atol=1e-9)


@pytest.mark.parametrize("paths, extra, code, text", [
    (("missing.ply",), (), 3, "input file not found"),
    (("room.ply", "room.ply"), (), 3, "a second cloud"),
    (("notes.txt",), (), 3, "don't know how to open"),
    ((), ("--fit", "1"), 2, "place an ASSET or CLOUD"),
    (("tet.obj",), ("--fit", "-1"), 2, "--fit must be a size in metres"),
    (("room.ply", "bad.glb"), (), 3, "bad.glb"),
])
def test_bad_view_files_are_one_line(files, capsys, paths, extra, code, text):
    d = files
    (d / "notes.txt").write_text("hello")
    capsys.readouterr()
    args = ["view", *[str(d / p) for p in paths], *extra, "--offscreen", "--frames", "1",
            "--size", "32x32"]
    assert main(args) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and text in err[0], err


def test_a_large_asset_is_framed_from_inside_the_room(ctx, files):
    """The bunny in its own units (1.83 m) in the 2 m box room: framing it whole would put the
    eye behind a wall (its back filling the view); the eye comes closer and stays inside."""
    if not BUNNY.is_file():
        pytest.skip("no ../shared/data/bunny.glb")
    from app.ui.app import OffscreenViewer, open_session
    from app.ui.files import open_at_start
    session = open_session(argparse.Namespace(session=None, last=False),
                           str(files / "room.ply"), str(BUNNY))
    viewer = OffscreenViewer(session, (40, 40))
    open_at_start(viewer.engine, str(BUNNY))
    eye = viewer.engine.nav.position
    assert np.all(np.abs(eye[[0, 2]]) < 0.9) and 0.1 < eye[1] < 1.9, eye   # room: +-1, 0..2
    viewer.run(1)
    assert viewer.engine.mesh.bounds()[0][1] == pytest.approx(0.0, abs=1e-6)
    assert (viewer.engine.view.read_linear()[..., 3] > 0).mean() > 0.2    # the bunny fills it


DROP = '''
import json
from pathlib import Path

def on_frame(viewer, frame):
    args = dict(a.split("=", 1) for a in viewer.script_args)
    e = viewer.engine
    if frame == 0:
        viewer._on_drop(10, 10, [args["drop"]])     # what the window's drop event calls
    elif frame == 2:
        lo, hi = e.mesh.bounds()
        Path(args["out"]).write_text(json.dumps({
            "asset": e.session.asset, "bounds": [lo.tolist(), hi.tolist()],
            "room": [e.room().floor_y, list(e.room().centre_xz)],
            "errors": [m.text for m in e.messages if m.level == "error"]}))
        viewer.quit()
'''


def test_a_mesh_dropped_on_the_window_stands_on_the_floor(files, tmp_path):
    """The real window (xvfb), its drop handler: the OBJ opens on the demo room's floor."""
    if not os.environ.get("DISPLAY"):
        pytest.skip("no display (run under xvfb-run)")
    (tmp_path / "drop.py").write_text(DROP)
    out = tmp_path / "drop.json"
    env = dict(os.environ, PYTHONPATH=str(ROOT), SCANLIGHT_CONFIG=str(tmp_path / "cfg"))
    cmd = [sys.executable, "-m", "app", "view", "--size", "320x240", "--frames", "20",
           "--script", str(tmp_path / "drop.py"), "--script-arg", f"out={out}",
           "--script-arg", f"drop={files / 'tet.obj'}", "--no-native-dialogs"]
    res = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    got = json.loads(out.read_text())
    assert not got["errors"] and got["asset"] == str((files / "tet.obj").resolve())
    lo, hi = (np.array(v) for v in got["bounds"])
    floor, centre = got["room"]
    assert floor == pytest.approx(0.0, abs=1e-6)                       # the demo room's floor
    np.testing.assert_allclose(hi - lo, (2.0, 1.0, 1.0), atol=1e-9)    # own units
    assert lo[1] == pytest.approx(floor, abs=1e-9)
    np.testing.assert_allclose(((lo + hi) / 2)[[0, 2]], centre, atol=1e-9)
