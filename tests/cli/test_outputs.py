"""Outputs never destroy inputs (app/io/outputs.py), through the real command line: each case
is refused before any work with one line naming the file (exit 3), the inputs keep their bytes,
and no output appears."""

from __future__ import annotations

import hashlib
import json
import os
import stat
import time
from pathlib import Path

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
    ramp = np.geomspace(0.01, 8.0, 32, dtype=np.float32)        # a photo with dynamic range
    write_exr(d / "photo.exr", np.repeat(np.tile(ramp, (32, 1))[..., None], 3, axis=-1))
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
    "expand --report is the photo": (lambda d: _expand(d, "--out", str(d / "h.ply"),
                                                       "--report", str(d / "photo.exr")),
                                     "photo.exr", "--photo"),
    "expand --report is the capture cameras": (
        lambda d: _expand(d, "--out", str(d / "h.ply"), "--report", str(d / "cams.json")),
        "cams.json", "--cameras"),
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


def test_a_read_only_output_folder_is_refused_up_front(inputs, capsys):
    """As an ordinary user (root writes anywhere: under root the command runs as 'nobody'
    through setpriv, on world-readable copies of the inputs)."""
    import shutil
    import subprocess
    import sys
    import tempfile
    if os.geteuid() != 0:
        ro = inputs / "ro"
        ro.mkdir()
        ro.chmod(stat.S_IRUSR | stat.S_IXUSR)
        try:
            code = main(_render(inputs, "--out", str(ro / "o.exr")))
        finally:
            ro.chmod(stat.S_IRWXU)
        err = capsys.readouterr().err.strip()
    else:
        if not shutil.which("setpriv"):
            pytest.skip("running as root without setpriv to drop to an ordinary user")
        shared = Path(tempfile.mkdtemp(prefix="scanlight-ro-"))
        try:
            for name in ("room.ply", "obj.json", "cam.json"):
                shutil.copy(inputs / name, shared / name)
                (shared / name).chmod(0o644)
            shared.chmod(0o755)                 # readable by all, writable by root only
            env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]),
                       HOME="/tmp", SCANLIGHT_CACHE=str(Path(tempfile.gettempdir())))
            res = subprocess.run(["setpriv", "--reuid=65534", "--regid=65534",
                                  "--clear-groups", sys.executable, "-m", "app",
                                  *_render(shared, "--out", str(shared / "o.exr"))],
                                 capture_output=True, text=True, timeout=300, env=env,
                                 cwd="/tmp")
            code, err = res.returncode, res.stderr.strip()
            assert not (shared / "o.exr").exists()
        finally:
            shutil.rmtree(shared, ignore_errors=True)
    assert code == 3 and "cannot write into the folder" in err and len(err.splitlines()) == 1, err


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


def _leftovers(d):
    return sorted(p.name for p in d.iterdir() if p.name.startswith("."))


def test_a_failed_expansion_leaves_neither_output(inputs, capsys):
    """The job fails late (an all-black photo): no cloud, no report, no temporaries."""
    import numpy as np

    from app.io.exr import write_exr
    write_exr(inputs / "black.exr", np.zeros((16, 16, 3), np.float32))
    argv = ["expand", "--cloud", str(inputs / "room.ply"), "--photo", str(inputs / "black.exr"),
            "--cameras", str(inputs / "cams.json"), "--face-size", "16", "--worker", "sync",
            "--out", str(inputs / "h.ply"), "--report", str(inputs / "h.json")]
    assert main(argv) == 3
    assert "all black" in capsys.readouterr().err
    assert not (inputs / "h.ply").exists() and not (inputs / "h.json").exists()
    assert _leftovers(inputs) == []


def test_concurrent_renders_into_the_same_outputs_never_mix(inputs):
    """Two runs at different sizes into one --out/--stats, three times: the image and the stats
    that end up side by side always come from the same run."""
    import subprocess
    import sys

    from app.io.exr import read_exr
    env = dict(os.environ, PYTHONPATH=str(os.getcwd()))

    def start(size):
        return subprocess.Popen([sys.executable, "-m", "app", *_render(
            inputs, "--out", str(inputs / "o.exr"), "--stats", str(inputs / "o.json"),
            "--size", size, "--microbuffer", "8")], env=env, stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE, text=True)
    for _ in range(3):
        runs = [start("8x6"), start("12x9")]
        for r in runs:
            _, err = r.communicate(timeout=300)
            assert r.returncode == 0, err
        width = read_exr(inputs / "o.exr").rgb.shape[1]
        stats = json.loads((inputs / "o.json").read_text())
        # the output's width (out_width: the GI ran at a render scale below 1) or the GI's
        assert (stats["out_width"] or stats["width"]) == width
        assert _leftovers(inputs) == []


def test_ctrl_c_during_expand_writes_nothing_and_says_so(inputs):
    import signal
    import subprocess
    import sys
    env = dict(os.environ, PYTHONPATH=str(os.getcwd()))
    argv = [sys.executable, "-m", "app", "expand", "--cloud", str(inputs / "room.ply"),
            "--photo", str(inputs / "photo.exr"), "--cameras", str(inputs / "cams.json"),
            "--face-size", "2048", "--out", str(inputs / "h.ply"),
            "--report", str(inputs / "h.json")]
    proc = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True)
    seen = []
    for line in proc.stderr:        # interrupt while the job runs (its progress lines say so):
        seen.append(line)           # at once - a CI run once saw the job finish within a pause
        if "capture" in line:       # of 0.2 s here, and the signal found nothing to interrupt
            break
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    err = "".join(seen) + err
    assert proc.returncode == 130, err
    assert "nothing written" in err
    assert not (inputs / "h.ply").exists() and not (inputs / "h.json").exists()
    assert _leftovers(inputs) == []


@pytest.mark.parametrize("worker,sig,code", [("process", "SIGTERM", 143),
                                             ("sync", "SIGTERM", 143),
                                             ("sync", "SIGINT", 130)])
def test_sigterm_or_ctrl_c_with_any_worker_writes_nothing(inputs, worker, sig, code):
    """SIGTERM (``timeout``, a render farm) killed the command at once: the hidden temporaries
    stayed beside the targets and a worker process went on writing the full cloud. Ctrl-C with
    the sync worker was an internal error (exit 1). Now both stop like Ctrl-C: 143 and 130."""
    import signal
    import subprocess
    import sys
    env = dict(os.environ, PYTHONPATH=str(os.getcwd()))
    argv = [sys.executable, "-m", "app", "expand", "--cloud", str(inputs / "room.ply"),
            "--photo", str(inputs / "photo.exr"), "--cameras", str(inputs / "cams.json"),
            "--face-size", "2048", "--worker", worker, "--out", str(inputs / "h.ply"),
            "--report", str(inputs / "h.json")]
    proc = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True)
    # the hidden temporaries appear just before the job starts (the sync worker prints no live
    # progress: its whole run is inside Job.start), so the signal finds the work running
    deadline = time.monotonic() + 60
    while not _leftovers(inputs) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)
    proc.send_signal(getattr(signal, sig))
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err
    assert "nothing written" in err and "Traceback" not in err
    assert not (inputs / "h.ply").exists() and not (inputs / "h.json").exists()
    assert _leftovers(inputs) == []


def test_an_output_onto_a_pipe_or_device_is_refused(inputs, capsys):
    """The rename at the end replaced a named pipe (or, as root, /dev/null) with a regular
    file: `expand --report /dev/null` destroyed /dev/null on the test machine."""
    os.mkfifo(inputs / "pipe.json")
    assert main(_render(inputs, "--out", str(inputs / "o.exr"), "--stats",
                        str(inputs / "pipe.json"))) == 3
    err = capsys.readouterr().err
    assert "special file" in err and "pipe.json" in err and len(err.strip().splitlines()) == 1
    assert stat.S_ISFIFO(os.stat(inputs / "pipe.json").st_mode)
    assert not (inputs / "o.exr").exists()


def test_a_commit_leaves_no_lock_file_behind(inputs, monkeypatch, tmp_path_factory):
    """Each output set left a scanlight-outputs-<hash>.lock in the temporary folder, never
    removed (955 of them on the test machine); the lock is now on the targets' folders."""
    import tempfile
    tmp = tmp_path_factory.mktemp("tmpdir")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    assert main(_render(inputs, "--out", str(inputs / "o.exr"), "--stats",
                        str(inputs / "o.json"))) == 0
    assert list(tmp.iterdir()) == []
    assert (inputs / "o.exr").exists() and _leftovers(inputs) == []


def test_ctrl_c_after_the_commit_does_not_claim_nothing_was_written(tmp_path, monkeypatch,
                                                                    capsys):
    """The signal lands while the command reports, after its outputs were renamed into place:
    the line says they are complete (it used to say "interrupted" over finished outputs)."""
    from app.commands import evaluate
    from app.io.outputs import OutputSet
    target = tmp_path / "m.json"

    def run(args):
        with OutputSet({"--json": target}) as outs:
            outs.temp("--json").write_text("{}")
        raise KeyboardInterrupt
    monkeypatch.setattr(evaluate, "run", run)
    code = main(["evaluate", "expansion", "--cloud", "a.ply", "--gt", "b.ply"])
    err = capsys.readouterr().err
    assert code == 130 and "after its outputs were written" in err and str(target) in err
    assert target.read_text() == "{}"


def test_an_unreadable_input_names_the_users_file(inputs):
    """An input the user may not read: one line naming that file (it used to name a hidden
    temporary, or end as an internal error). Run as 'nobody' (root reads everything)."""
    import shutil
    import subprocess
    import sys
    import tempfile
    if not shutil.which("setpriv") or os.geteuid() != 0:
        pytest.skip("needs root with setpriv to run as an ordinary user")
    shared = Path(tempfile.mkdtemp(prefix="scanlight-unreadable-"))
    try:
        for name in ("room.ply", "obj.json", "cam.json"):
            shutil.copy(inputs / name, shared / name)
            (shared / name).chmod(0o644)
        (shared / "room.ply").chmod(0o600)      # root's only
        shared.chmod(0o777)
        env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[2]), HOME="/tmp")
        res = subprocess.run(["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups",
                              sys.executable, "-m", "app",
                              *_render(shared, "--out", str(shared / "o.exr"))],
                             capture_output=True, text=True, timeout=300, env=env, cwd="/tmp")
        err = res.stderr.strip()
        assert res.returncode == 3, err
        assert len(err.splitlines()) == 1 and str(shared / "room.ply") in err
        assert "permission denied" in err and not (shared / "o.exr").exists()
    finally:
        shutil.rmtree(shared, ignore_errors=True)
