"""Outputs never destroy inputs (app/io/outputs.py), through the real command line: each case
is refused before any work with one line naming the file (exit 3), the inputs keep their bytes,
and no output appears."""

from __future__ import annotations

import hashlib
import json
import os
import stat

import pytest

from tests.support import scenes as S
from app.cli import main


@pytest.fixture
def inputs(tmp_path):
    from app.io.exr import write_exr
    from app.io.pointcloud import save_cloud
    import numpy as np
    d = tmp_path
    save_cloud(S.box_room(0.1), d / "room.ply")
    save_cloud(S.box_room(0.1), d / "gt.ply")
    (d / "obj.json").write_text(json.dumps({"mesh": "sphere", "translate": [0, 0.8, 0],
                                            "scale": 0.6}))
    (d / "cam.json").write_text(json.dumps({"position": [0.3, 1.0, 0.9], "look_at": [0, 0.8, 0],
                                            "fov_y_deg": 40, "width": 8, "height": 6}))
    write_exr(d / "photo.exr", np.full((16, 16, 3), 2.0, np.float32))
    (d / "cams.json").write_text(json.dumps([{"position": [0.0, 1.0, 0.0]}]))
    return d


def _hashes(d):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in d.iterdir()
            if p.is_file()}


def _render(d, *extra):
    return ["render", "--cloud", str(d / "room.ply"), "--object", str(d / "obj.json"),
            "--camera", str(d / "cam.json"), *extra]


def _expand(d, *extra):
    return ["expand", "--cloud", str(d / "room.ply"), "--photo", str(d / "photo.exr"),
            "--cameras", str(d / "cams.json"), "--face-size", "16", *extra]


CASES = {
    "render --stats is the cloud": (lambda d: _render(d, "--out", str(d / "o.exr"), "--stats",
                                                      str(d / "room.ply")), "room.ply", "--cloud"),
    "render --stats is the camera": (lambda d: _render(d, "--out", str(d / "o.exr"), "--stats",
                                                       str(d / "cam.json")), "cam.json", "--camera"),
    "render --stats equals --out": (lambda d: _render(d, "--out", str(d / "o.exr"), "--stats",
                                                      str(d / "o.exr")), "o.exr", "same file"),
    "render --out is a hard link to the cloud": (
        lambda d: (os.link(d / "room.ply", d / "alias.exr"),
                   _render(d, "--out", str(d / "alias.exr")))[1], "alias.exr", "--cloud"),
    "expand --out is the input cloud": (lambda d: _expand(d, "--out", str(d / "room.ply")),
                                        "room.ply", "--cloud"),
    "expand --report is the input cloud": (lambda d: _expand(d, "--out", str(d / "h.ply"),
                                                             "--report", str(d / "room.ply")),
                                           "room.ply", "--cloud"),
    "evaluate --json is the ground truth": (
        lambda d: ["evaluate", "expansion", "--cloud", str(d / "room.ply"), "--gt", str(d / "gt.ply"),
                   "--no-render", "--json", str(d / "gt.ply")], "gt.ply", "--gt"),
    "render --out is a folder": (lambda d: (os.mkdir(d / "dir.exr"),
                                            _render(d, "--out", str(d / "dir.exr")))[1],
                                 "dir.exr", "folder"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_an_output_that_would_destroy_an_input_is_refused(case, inputs, capsys):
    make, name, words = CASES[case]
    argv = make(inputs)
    before = _hashes(inputs)
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 3, err
    assert len(err.splitlines()) == 1 and name in err and words in err, err
    assert _hashes(inputs) == before                       # every input byte unchanged
    assert not [p for p in inputs.iterdir() if p.name.startswith((".o", "o.", "h.", ".h"))]


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_output_folder_is_refused_up_front(inputs, capsys):
    ro = inputs / "ro"
    ro.mkdir()
    ro.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        code = main(_render(inputs, "--out", str(ro / "o.exr")))
    finally:
        ro.chmod(stat.S_IRWXU)
    err = capsys.readouterr().err.strip()
    assert code == 3 and "permission denied" in err and len(err.splitlines()) == 1


def test_an_output_under_a_file_is_refused(inputs, capsys):
    code = main(_render(inputs, "--out", str(inputs / "room.ply" / "o.exr")))
    err = capsys.readouterr().err.strip()
    assert code == 3 and "not a folder" in err and len(err.splitlines()) == 1


def test_distinct_outputs_still_work(inputs, capsys):
    """The checks refuse only what they should: a missing output folder is created."""
    code = main(_render(inputs, "--out", str(inputs / "new" / "o.exr"), "--stats",
                        str(inputs / "new" / "o.json"), "--microbuffer", "8"))
    assert code == 0, capsys.readouterr().err
    assert (inputs / "new" / "o.exr").is_file() and (inputs / "new" / "o.json").is_file()
