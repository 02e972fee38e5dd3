"""`expand --photo DAMAGED.exr`: one line on stderr, nothing on stdout, in every worker mode.

OpenEXR prints its own messages about a damaged file: its core "(EXR_ERR_BAD_CHUNK_LEADER) ..."
on file descriptor 2, its Python binding "Warning: Exception raised reading pixel data ..." on
stdout. app.io.exr folds them into the one error line, but only on the main thread, and the
default worker (a thread) read the photo on its own thread: both leaked beside the error line.
The command now reads the photo on its main thread before a thread worker starts
(ExpandRequest.with_photo_read); a worker process reads it on its own main thread. Run as a
real process, since the leak was at the level of file descriptors.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """A small valid LDR cloud and cube-map capture, and two damaged copies of a 256 x 256
    ZIP-compressed EXR (16 scanlines per chunk): cut at 60% (a chunk's leader points past the
    end) and with 4,000 bytes of one chunk's compressed data scrambled (it fails to inflate)."""
    from app.cloud import PointCloud
    from app.io.exr import write_exr
    from app.io.pointcloud import save_cloud

    root = tmp_path_factory.mktemp("noise")
    rng = np.random.default_rng(3)
    pos = rng.uniform(-1.0, 1.0, (2000, 3))
    nrm = pos / np.linalg.norm(pos, axis=1, keepdims=True)
    save_cloud(PointCloud(pos, nrm, rng.uniform(0, 1, (2000, 3)).astype(np.float32), False,
                          "small"), root / "ldr.ply")
    (root / "cams.json").write_text(json.dumps([{"position": [0.0, 0.0, 0.0]}]))
    write_exr(root / "full.exr", rng.uniform(0.0, 4.0, (256, 256, 3)).astype(np.float32))
    data = (root / "full.exr").read_bytes()
    (root / "trunc.exr").write_bytes(data[:len(data) * 6 // 10])
    scrambled = bytearray(data)
    mid = len(data) // 2
    scrambled[mid:mid + 4000] = bytes((b * 7 + 13) & 255 for b in data[mid:mid + 4000])
    (root / "corrupt.exr").write_bytes(bytes(scrambled))
    return root


@pytest.mark.parametrize("worker", [None, "sync", "process"],
                         ids=["default-thread", "sync", "process"])
@pytest.mark.parametrize("photo", ["trunc.exr", "corrupt.exr"])
def test_damaged_photo_is_one_line_and_nothing_on_stdout(inputs, tmp_path, photo, worker):
    cmd = [sys.executable, "-m", "app", "expand", "--cloud", str(inputs / "ldr.ply"),
           "--photo", str(inputs / photo), "--cameras", str(inputs / "cams.json"),
           "--out", str(tmp_path / "out.ply"), "--report", str(tmp_path / "rep.json")]
    if worker:
        cmd += ["--worker", worker]
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 3, res.stderr
    assert res.stdout == ""
    lines = res.stderr.splitlines()
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("scanlight expand: error: ")
    assert str(inputs / photo) in lines[0] and "corrupt or truncated EXR" in lines[0]
    assert "Traceback" not in res.stderr and "internal error" not in res.stderr
    assert list(tmp_path.iterdir()) == []            # nothing written, no temporaries
