"""When the machine refuses a write - a full disk, a file-size limit, a name at the length limit
or with bytes that are not UTF-8 - a command still ends in one line naming the output (exit 3)
or simply works, and leaves nothing half-written. A fuzzing pass found each of these as an
"internal error" (exit 1), a commit of half an output set, or a valid file refused.

The file-size limit (RLIMIT_FSIZE, what ``ulimit -f`` sets) is the real kernel refusal, the same
EFBIG path a full disk takes (ENOSPC), and needs no root; it is set in the child process only.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from app.errors import ScanlightError
from tests.cli.test_outputs import _leftovers, _render, inputs  # noqa: F401 - the fixture

ROOT = Path(__file__).resolve().parents[2]


def _limited(argv, max_bytes: int) -> subprocess.CompletedProcess:
    """``scanlight argv`` in a child whose files may not grow past ``max_bytes``."""
    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (max_bytes, max_bytes))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "app", *argv], env=env, cwd=ROOT,
                          preexec_fn=limit, capture_output=True, text=True, timeout=600)


def _one_line(err: str) -> str:
    lines = [t for t in err.strip().splitlines() if t.startswith("scanlight ")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_a_file_size_limit_is_one_line_naming_the_output(inputs):
    """render's EXR over the limit: exit 3, the line names --out (not a hidden temporary) and
    says why; nothing is left under any name. It was "internal error: RuntimeError: Failed to
    write pixel data to image file .../..o.xxxx.yyyy.exr", exit 1."""
    out = inputs / "sub" / "o.exr"
    run = _limited(_render(inputs, "--out", str(out), "--png", str(out.with_suffix(".png")),
                           "--size", "64x48", "--microbuffer", "8"), 2048)
    assert run.returncode == 3, run.stderr
    line = _one_line(run.stderr)
    assert str(out) in line or str(out.with_suffix(".png")) in line
    assert "could not be written" in line and "File too large" in line
    assert list((inputs / "sub").iterdir()) == []


def test_bench_json_into_a_folder_it_cannot_write_is_refused_before_the_run(tmp_path, capsys):
    """It ran the whole benchmark and then failed with an OSError (exit 1)."""
    (tmp_path / "file").write_text("x")
    assert main(["bench", "bsh", "--points", "2000", "--json",
                 str(tmp_path / "file" / "b.json")]) == 3
    err = capsys.readouterr()
    assert "--json" in err.err and err.out == ""          # no table: nothing ran


def test_an_output_that_becomes_a_folder_commits_none_of_the_set(tmp_path):
    """--stats replaced by a folder while the command ran: the EXR and PNG were already renamed
    into place when the JSON's rename failed (IsADirectoryError, exit 1). Now the set is checked
    before its first rename."""
    from app.io.outputs import OutputSet
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    with pytest.raises(ScanlightError, match="became a folder"):
        with OutputSet({"--out": a, "--stats": b}) as outs:
            outs.temp("--out").write_text("{}")
            outs.temp("--stats").write_text("{}")
            b.mkdir()
    assert not a.exists() and b.is_dir() and list(b.iterdir()) == []
    assert _leftovers(tmp_path) == []


def test_a_writer_failure_inside_a_set_names_the_users_file(tmp_path):
    """A writer reports the file it wrote, the set's hidden temporary: the error names the
    output the user asked for instead."""
    from app.io.files import WriteError, atomic_output
    from app.io.outputs import OutputSet
    target = tmp_path / "relit.exr"
    with pytest.raises(ScanlightError) as e:
        with OutputSet({"--out": target}) as outs:
            with atomic_output(outs.temp("--out")):
                raise WriteError("No space left on device.")
    assert e.value.path == str(target) and "No space left" in e.value.reason
    assert _leftovers(tmp_path) == [] and not target.exists()


def test_a_long_output_name_that_fits_is_written(inputs, capsys):
    """A 240-byte name is legal (255 is the limit); its temporaries, named after it with two
    prefixes, were not (File name too long, exit 1, after the whole render)."""
    out = inputs / ("c" * 236 + ".exr")
    assert main(_render(inputs, "--out", str(out), "--microbuffer", "8")) == 0
    assert out.is_file() and _leftovers(inputs) == []


def test_names_that_are_not_utf8_are_written_and_read(tmp_path):
    """Bytes that are not UTF-8 in a file name (Python hands them on as surrogate escapes):
    OpenEXR refused to write such a name ("use write(path: str)") and to read one, which was
    reported as a corrupt EXR."""
    from app.io.exr import read_exr, write_exr
    p = tmp_path / os.fsdecode(b"ph\xff.exr")
    img = np.linspace(0.0, 4.0, 4 * 6 * 3, dtype=np.float32).reshape(4, 6, 3)
    write_exr(p, img)
    assert os.fsencode(p.name) in os.listdir(os.fsencode(tmp_path))
    np.testing.assert_array_equal(read_exr(p).rgb, img)


def test_an_error_about_a_name_with_a_newline_stays_one_line():
    err = ScanlightError("/tmp/a\nb" + os.fsdecode(b"\xff") + ".exr", "cannot write")
    assert "\n" not in str(err) and "a\\nb\\xff.exr" in str(err)


def test_a_screenshot_is_its_png_and_exr_or_nothing(tmp_path):
    """view --screenshot writes a PNG and the EXR beside it; with room for the PNG only, the PNG
    was left alone (exit 1). Now: exit 3 and neither."""
    out = tmp_path / "v.png"
    argv = ["view", "--offscreen", "--frames", "2", "--size", "96x64", "--screenshot", str(out)]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    free = subprocess.run([sys.executable, "-m", "app", *argv], env=env, cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert free.returncode == 0, free.stderr
    png, exr = out.stat().st_size, out.with_suffix(".exr").stat().st_size
    out.unlink()
    out.with_suffix(".exr").unlink()
    if not png < exr:
        pytest.skip(f"this screenshot's PNG ({png} B) is not smaller than its EXR ({exr} B)")
    run = _limited(argv, (png + exr) // 2)
    assert run.returncode == 3, run.stderr
    assert "could not be written" in _one_line(run.stderr)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_the_viewer_reports_what_the_machine_refuses_in_one_line(ctx, tmp_path, caplog):
    """A write into a folder that is a file (what a read-only or full config folder gives) in
    the viewer: one message naming the file, no traceback in the log - the environment, not a
    bug ("saving the last session failed" printed a traceback at every exit)."""
    import logging

    from app.pbgi.renderer import Relighter
    from app.ui.engine import ViewerEngine
    from tests.support.viewer import small_session
    (tmp_path / "config").write_text("a file where a folder belongs")
    e = ViewerEngine(ctx, small_session(), size=(64, 48), relighter=Relighter)
    with caplog.at_level(logging.DEBUG, logger="app.ui.engine"):
        e.guard("saving the last session", Path(tmp_path / "config" / "last.json").write_text,
                "{}")
    text = e.messages[-1].text
    assert text.startswith("saving the last session: ") and "config/last.json" in text
    assert "\n" not in text and not any(r.exc_info for r in caplog.records)


def test_the_machine_s_refusals_read_as_one_line():
    """What cli, the job runner and the viewer print for an OSError or a MemoryError: the file
    (escaped) and the system's reason; an empty MemoryError (numpy's in the viewer gave
    "out of memory ()") still says what happened; anything else is not a refusal."""
    from app.errors import refusal
    assert refusal(OSError(28, "No space left on device", "/out/a\nb.exr")) == \
        "/out/a\\nb.exr: No space left on device"
    assert refusal(MemoryError()).startswith("out of memory (an allocation failed)")
    assert refusal(ValueError("x")) is None


def test_an_allocation_the_machine_refuses_is_one_line_and_exit_3():
    """A real MemoryError from inside a command (numpy, under an address-space limit set in the
    child only) reaches the command line's last guard: one line saying so, exit 3, no traceback
    - not "internal error" (exit 1), which is kept for bugs."""
    def limit():
        cap = int(0.8 * 2 ** 30)
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    run = subprocess.run([sys.executable, "-m", "app", "bench", "bsh", "--points", "1500000",
                          "--repeat", "1"], env=env, cwd=ROOT, preexec_fn=limit,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 3, run.stderr
    assert "out of memory" in _one_line(run.stderr)
