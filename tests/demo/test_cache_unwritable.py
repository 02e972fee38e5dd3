"""The demo's disk cache (app/demo/cache.py) only saves time: a cache folder that cannot be
written (a path under a regular file, a file-size limit standing in for a full disk, a folder in
a cache file's place) costs a one-line warning, never the scene, the expansion or the command,
and leaves no temporary behind. ``scanlight demo`` failing on its own outputs leaves no empty
``--out`` folder of its own."""

from __future__ import annotations

import logging
import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np

from tests.support import scenes as S
from app.demo import cache
from app.hdr.job import ExpandRequest
from app.hdr.result import Expansion

ROOT = Path(__file__).resolve().parents[2]
POINTS = 10_000               # the smallest demo scene: ~7 s to generate


def _unwritable(tmp_path) -> Path:
    """A folder that cannot be made, without root: its parent is a regular file."""
    (tmp_path / "afile").write_text("x")
    return tmp_path / "afile" / "sub"


def _env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "SCANLIGHT_CACHE"}
    return dict(env, PYTHONPATH=str(ROOT), **extra)


def _limit_file_size(limit=32 * 1024):
    def apply():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return apply


def _request_and_result():
    cloud = S.box_room(0.2)
    req = ExpandRequest(cloud, None, [(0.0, 1.0, 0.0)])
    n = len(cloud)
    result = Expansion(cloud, {"alpha": 1.0}, np.zeros(n, np.uint8), [],
                       np.linspace(0, 1, n, dtype=np.float32))
    return req, result


def test_the_demo_scene_is_built_when_the_cache_folder_cannot_be_made(tmp_path, monkeypatch,
                                                                      caplog):
    monkeypatch.delenv("SCANLIGHT_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(_unwritable(tmp_path)))
    with caplog.at_level(logging.WARNING, logger="app.demo.cache"):
        scene = cache.load_demo(POINTS)
    assert len(scene.gt) == POINTS and len(scene.ldr) == POINTS
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warned) == 1 and "cannot write the cache" in warned[0], warned


def test_a_full_cache_disk_leaves_no_temporary_and_the_run_goes_on(tmp_path):
    """The file-size limit fails the cache's write as a full disk does (EFBIG, not ENOSPC)."""
    folder = tmp_path / "cache"
    code = f"from app.demo.cache import load_demo; print(len(load_demo({POINTS}).gt))"
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          timeout=120, env=_env(SCANLIGHT_CACHE=str(folder)),
                          preexec_fn=_limit_file_size())
    assert proc.returncode == 0 and proc.stdout.strip() == str(POINTS), proc.stderr
    assert "Traceback" not in proc.stderr
    assert proc.stderr.count("cannot write the cache") == 1, proc.stderr
    assert list(folder.iterdir()) == []                 # no stray *.tmp.npz


def test_the_demo_expansion_is_kept_in_memory_when_it_cannot_be_stored(tmp_path, monkeypatch,
                                                                       caplog):
    """The viewer's demo light (app/ui/demo_light.py) stores and loads through these two."""
    monkeypatch.delenv("SCANLIGHT_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(_unwritable(tmp_path)))
    req, result = _request_and_result()
    with caplog.at_level(logging.WARNING, logger="app.demo.cache"):
        cache.store_demo_expansion(req, result)          # no exception
        assert cache.load_demo_expansion(req) is None    # a miss, not an error
    assert len([r for r in caplog.records if "cannot write the cache" in r.getMessage()]) == 1


def test_a_folder_in_the_cache_files_place_is_skipped(tmp_path, monkeypatch, caplog):
    monkeypatch.setenv("SCANLIGHT_CACHE", str(tmp_path / "cache"))
    req, result = _request_and_result()
    blocker = cache._expansion_path(req)
    blocker.mkdir(parents=True)
    with caplog.at_level(logging.WARNING, logger="app.demo.cache"):
        assert cache.load_demo_expansion(req) is None
        cache.store_demo_expansion(req, result)
    said = [r.getMessage() for r in caplog.records]
    assert any("unreadable demo expansion cache" in m for m in said), said
    assert any("cannot write the cache" in m for m in said), said
    assert blocker.is_dir() and sorted(p.name for p in blocker.parent.iterdir()) == [blocker.name]
    # a cache that works again is used again
    monkeypatch.setenv("SCANLIGHT_CACHE", str(tmp_path / "cache2"))
    cache.store_demo_expansion(req, result)
    back = cache.load_demo_expansion(req)
    assert back is not None and np.array_equal(back.scores, result.scores)


def test_demo_with_no_cache_that_fails_on_its_outputs_leaves_no_empty_out_folder(tmp_path):
    """The cache folder cannot be made (a warning) and the file-size limit stops the first of
    demo's own files: one error naming that file, exit 3, and the --out folder this run made
    is gone again."""
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "app", "demo", "--size", "16", "--points",
                           str(POINTS), "--out", str(out)], cwd=ROOT, capture_output=True,
                          text=True, timeout=120,
                          env=_env(XDG_CACHE_HOME=str(_unwritable(tmp_path))),
                          preexec_fn=_limit_file_size())
    assert proc.returncode == 3, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if not ln.startswith("INFO")]
    assert len(lines) == 2, lines
    assert lines[0].startswith("WARNING") and "cannot write the cache" in lines[0], lines
    assert "error" in lines[1] and str(out) in lines[1], lines
    assert not out.exists()
