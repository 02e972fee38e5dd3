"""``scanlight turntable`` when ffmpeg cannot finish the MP4 (a full disk, a file-size limit):
ffmpeg stops and leaves a truncated, unplayable file, which must not be committed as the video.
The run says so in one line naming the video and exits 3; the frames stay."""

from __future__ import annotations

import json
import resource
import subprocess
import sys
from pathlib import Path

from tests.support import scenes as S
from app.io.pointcloud import save_cloud

ROOT = Path(__file__).resolve().parents[2]
COUNT = 48                # 16x16 frames of ~2.6 KB each; their MP4 is ~10 KB
FILE_LIMIT = 6000         # bytes: every frame file fits, the MP4 does not


def _limit_file_size():
    """``ulimit -f`` for the child: its writes past the limit fail (Python ignores SIGXFSZ,
    ffmpeg, its own child, is killed by it)."""
    resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_LIMIT, FILE_LIMIT))


def test_a_video_cut_short_by_the_file_size_limit_is_an_error_and_not_committed(tmp_path):
    save_cloud(S.box_room(0.1), tmp_path / "room.ply")
    (tmp_path / "obj.json").write_text(json.dumps({"mesh": "knot", "translate": [0, 0.8, 0],
                                                   "scale": 0.6}))
    out = tmp_path / "out"
    args = ["turntable", "--cloud", str(tmp_path / "room.ply"), "--object",
            str(tmp_path / "obj.json"), "--out", str(out), "--count", str(COUNT),
            "--size", "16x16", "--mode", "hybrid", "--microbuffer", "8"]
    proc = subprocess.run([sys.executable, "-m", "app", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=120, preexec_fn=_limit_file_size)
    assert proc.returncode == 3, proc.stderr
    assert "Traceback" not in proc.stderr, proc.stderr
    # one line for the problem (the BSH cache's own warning may come before it)
    said = [ln for ln in proc.stderr.splitlines() if not ln.startswith(("INFO", "WARNING"))]
    assert len(said) == 1 and "turntable.mp4" in said[0], proc.stderr
    assert "file too large" in said[0].lower(), said
    names = sorted(p.name for p in out.iterdir())
    assert "turntable.mp4" not in names and not [n for n in names if n.startswith(".")], names
    assert len(names) == 2 * COUNT            # the frames are complete and stay
