"""Careless and hostile inputs to the viewer's command line, `expand` and `bench` that a fuzzing
pass found failing (internal errors, an input overwritten): each is now one line naming the file
or flag, exit 3 (usage: 2), the inputs unchanged."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from app.cli import main


@pytest.fixture
def session(tmp_path):
    """A session whose photo is an EXR (a screenshot photo.png writes photo.exr beside it)."""
    from tests.support.viewer import small_session

    from app.io.exr import write_exr
    write_exr(tmp_path / "photo.exr", np.full((16, 16, 3), 0.5, np.float32))
    s = small_session(8)
    s.photo = str(tmp_path / "photo.exr")
    return s.save(tmp_path / "s.json")


def _view(session, *extra):
    return ["view", "--offscreen", "--frames", "1", "--size", "32x24", "--session",
            str(session), *extra]


def _sha(p):
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _one_line(capsys, *words) -> str:
    """The one error line (expand's progress lines aside), holding every word."""
    lines = [t for t in capsys.readouterr().err.strip().splitlines()
             if not t.startswith("expand: ")]
    assert len(lines) == 1 and all(w in lines[0] for w in words), lines
    return lines[0]


def test_a_screenshot_never_overwrites_what_the_session_reads(session, capsys):
    """photo.png's EXR replaced the session's photo.exr; the session file itself could be the
    screenshot too."""
    photo = session.parent / "photo.exr"
    before = _sha(photo), _sha(session)
    assert main(_view(session, "--screenshot", str(session.parent / "photo.png"))) == 3
    _one_line(capsys, "photo.exr", "the session's photo", "refusing to overwrite")
    assert (_sha(photo), _sha(session)) == before
    assert not (session.parent / "photo.png").exists()


def test_a_screenshot_onto_a_folder_is_one_line(session, tmp_path, capsys):
    (tmp_path / "d.png").mkdir()
    assert main(_view(session, "--screenshot", str(tmp_path / "d.png"))) == 3
    _one_line(capsys, "d.png", "folder")


SCRIPTS = {
    "raises": ("def on_frame(viewer, i):\n    raise ValueError('boom')\n", "ValueError: boom"),
    "wrong signature": ("def on_frame(viewer):\n    pass\n", "TypeError"),
    "a NaN transform": ("from app.settings import AssetTransform\n"
                        "def on_frame(viewer, i):\n"
                        "    viewer.session.set_transform(AssetTransform((float('nan'), 0, 0),"
                        " (0, 0, 0), 1.0))\n", "finite"),
}


@pytest.mark.parametrize("case", sorted(SCRIPTS))
def test_a_failing_script_is_its_own_line(case, session, tmp_path, capsys):
    """README: a bad script is one line naming the file (exit 3); these were internal errors."""
    text, word = SCRIPTS[case]
    script = tmp_path / "script.py"
    script.write_text(text)
    assert main(_view(session, "--script", str(script))) == 3
    _one_line(capsys, str(script), "on_frame failed at frame 0", word)


@pytest.mark.parametrize("doc,word", [("42", "not a Scanlight session"),
                                      ("null", "not a Scanlight session"),
                                      ('{"scanlight_session": true}', "version True")])
def test_session_documents_of_the_wrong_kind(doc, word, tmp_path, capsys):
    """A bare 42 or null was a TypeError in the JSON depth check; true was taken for version 1."""
    p = tmp_path / "bad.json"
    p.write_text(doc)
    assert main(["view", "--offscreen", "--frames", "1", "--size", "32x24", "--session",
                 str(p)]) == 3
    _one_line(capsys, str(p), word)


def test_a_viewer_wider_than_any_screen_is_a_usage_error(session, capsys):
    """16383 x 16 passed --size and failed as an incomplete framebuffer (the splats' guard band
    overflowed llvmpipe's largest one)."""
    assert main(_view(session)[:-2] + ["--size", "16383x16", "--session", str(session)]) == 2
    _one_line(capsys, "--size", "8192")


@pytest.fixture
def expand_inputs(tmp_path):
    from tests.support import scenes as S

    from app.io.exr import write_exr
    from app.io.pointcloud import save_cloud
    save_cloud(S.box_room(0.1), tmp_path / "room.ply")
    ramp = np.geomspace(0.01, 8.0, 32, dtype=np.float32)
    write_exr(tmp_path / "photo.exr", np.repeat(np.tile(ramp, (32, 1))[..., None], 3, axis=-1))
    return tmp_path


@pytest.mark.parametrize("cams,word", [
    ("null", "non-empty list"),
    ('[{"position": [0, 1, 0], "look_at": [1, 1, 0], "width": 16384, "height": 1}]',
     "too thin"),
])
def test_expand_capture_cameras_of_the_wrong_kind(cams, word, expand_inputs, capsys):
    """A bare null was a TypeError; a 16384 x 1 view an internal error deep in the capture."""
    d = expand_inputs
    (d / "cams.json").write_text(cams)
    assert main(["expand", "--cloud", str(d / "room.ply"), "--photo", str(d / "photo.exr"),
                 "--cameras", str(d / "cams.json"), "--face-size", "16", "--worker", "sync",
                 "--out", str(d / "h.ply")]) == 3
    _one_line(capsys, "cams.json", word)
    assert not (d / "h.ply").exists()


def test_expand_params_that_are_not_an_object(expand_inputs, capsys):
    d = expand_inputs
    (d / "cams.json").write_text(json.dumps([{"position": [0, 1, 0]}]))
    assert main(["expand", "--cloud", str(d / "room.ply"), "--photo", str(d / "photo.exr"),
                 "--cameras", str(d / "cams.json"), "--out", str(d / "h.ply"),
                 "--params", "5"]) == 2
    _one_line(capsys, "--params")


@pytest.mark.parametrize("argv,flag", [
    (["bsh", "--points=-5"], "--points"),
    (["bsh", "--points", "99999999999999999999"], "--points"),
    (["bsh", "--points", "2000", "--tc", "nan"], "--tc"),
    (["expand", "--points", "0"], "--points"),
    (["profile", "--viewport", "0"], "--viewport"),
    (["table3", "--viewports", "0"], "--viewports"),
    (["classic", "--viewports", "4"], "--viewports"),
    (["profile", "--repeat", "0"], "--repeat"),
    (["viewer", "--timeout", "nan"], "--timeout"),
])
def test_bench_numbers_it_cannot_use(argv, flag, capsys):
    """A numpy error, an OverflowError, the default run instead of 0 points, a 0 x 0 camera
    reaching the renderer, tables of NaN: now usage errors naming the flag, before any work."""
    assert main(["bench", *argv]) == 2
    _one_line(capsys, flag)
