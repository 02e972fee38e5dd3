"""``scanlight turntable``: the frames' names and cameras, range splitting for a render farm, the
MP4, the progress helper, and the refusals (exit 2 usage, 3 bad input) before any rendering."""

from __future__ import annotations

import json
import math
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest
from PIL import Image

from tests.support import scenes as S
from tests.support.terminal import read_terminal
from app.cli import main
from app.io.exr import read_exr_layers
from app.io.pointcloud import save_cloud

ROOT = Path(__file__).resolve().parents[2]
W, H = 32, 24                  # not square: a swapped width/height would show
COUNT = 4
CENTRE = np.array([0.0, 0.8, 0.0])   # the knot's bounding-box centre: its object JSON translate
DISTANCE, ELEVATION, FOV = 1.4, 15.0, 40.0
RENDER_FLAGS = ["--mode", "hybrid", "--microbuffer", "8"]
FRAMES = [f"frame_{k:04d}.{ext}" for k in range(COUNT) for ext in ("exr", "png")]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("turntable")
    save_cloud(S.box_room(0.1), d / "room.ply")
    # the knot: not symmetric under the orbit's quarter turns, so a wrong angle shows
    (d / "obj.json").write_text(json.dumps({"mesh": "knot", "translate": CENTRE.tolist(),
                                            "scale": 0.6}))
    return d


def _args(d, out, *extra, count=COUNT):
    return ["turntable", "--cloud", str(d / "room.ply"), "--object", str(d / "obj.json"),
            "--out", str(out), "--size", f"{W}x{H}", "--distance", str(DISTANCE),
            "--elevation", str(ELEVATION), "--fov", str(FOV), *RENDER_FLAGS,
            *(["--count", str(count)] if count else []), *extra]


def _orbit_camera(k: int, n: int = COUNT) -> dict:
    """Frame k's camera written out by hand from the documented orbit (not the code's)."""
    t, e = 2 * math.pi * k / n, math.radians(ELEVATION)
    pos = CENTRE + DISTANCE * np.array([math.cos(e) * math.sin(t), math.sin(e),
                                        math.cos(e) * math.cos(t)])
    return {"position": pos.tolist(), "look_at": CENTRE.tolist(), "up": [0, 1, 0],
            "fov_y_deg": FOV, "width": W, "height": H}


def _rgba(path) -> np.ndarray:
    return read_exr_layers(path)[""]


def _listing(folder) -> list[str]:
    return sorted(p.name for p in Path(folder).iterdir())


def _video(path) -> tuple[tuple[int, int], list[np.ndarray]]:
    gen = imageio_ffmpeg.read_frames(str(path))
    meta = next(gen)
    w, h = meta["size"]
    frames = [np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in gen]
    return (w, h), frames


@pytest.fixture(scope="module")
def full(scene):
    """One full run of the 4-frame orbit."""
    out = scene / "full"
    assert main(_args(scene, out)) == 0
    return out


def test_full_run_writes_every_frame_and_the_video(full, capsys):
    assert _listing(full) == sorted(FRAMES + ["turntable.mp4"])    # no temporaries left
    for k in range(COUNT):
        img = _rgba(full / f"frame_{k:04d}.exr")
        assert img.shape == (H, W, 4) and np.isfinite(img).all()
        assert 0 < img[..., 3].sum() < H * W          # the asset covers part of the frame
        with Image.open(full / f"frame_{k:04d}.png") as png:
            assert png.size == (W, H) and png.mode == "RGBA"
    size, frames = _video(full / "turntable.mp4")
    assert size == (W, H) and len(frames) == COUNT
    # the video's frames are the PNGs in order (over black): each is nearest its own PNG
    pngs = [np.asarray(Image.open(full / f"frame_{k:04d}.png").convert("RGB"), np.float64)
            for k in range(COUNT)]
    for k, f in enumerate(frames):
        err = [np.abs(f.astype(np.float64) - p).mean() for p in pngs]
        assert int(np.argmin(err)) == k and err[k] < 6.0, err    # H.264 at CRF 10, 4:2:0


def test_frames_are_the_orbit_cameras(scene, full, tmp_path):
    """Frame k equals ``render`` with the camera at 360 k / N degrees about +y (counter-
    clockwise from above, starting on the +z side), computed here from the documentation."""
    renders = {}
    for k in (1, 2):
        (tmp_path / f"cam{k}.json").write_text(json.dumps(_orbit_camera(k)))
        assert main(["render", "--cloud", str(scene / "room.ply"), "--object",
                     str(scene / "obj.json"), "--camera", str(tmp_path / f"cam{k}.json"),
                     "--out", str(tmp_path / f"r{k}.exr"), *RENDER_FLAGS]) == 0
        renders[k] = _rgba(tmp_path / f"r{k}.exr")
        frame = _rgba(full / f"frame_{k:04d}.exr")
        assert np.abs(frame - renders[k]).max() < 1e-4, k
    # the comparison has teeth: the quarter turn the other way (frame 3) and frame 0 are not
    # the frame-1 camera's picture
    for k in (0, 3):
        assert np.abs(_rgba(full / f"frame_{k:04d}.exr") - renders[1]).max() > 0.05, k
    f0, f2 = (_rgba(full / f"frame_{k:04d}.exr") for k in (0, 2))
    assert np.abs(f0 - f2).max() > 0.05


def test_a_glossy_metal_frame_averages_its_passes(scene, tmp_path, capsys):
    """A gold knot's frame averages pbgi.glossy_passes (4) passes, as ``render`` of the same
    camera does (app/pbgi/upsample.py: render_passes_of), and the summary says so; one pass
    (--glossy-passes 1) is another picture."""
    (tmp_path / "gold.json").write_text(json.dumps({"base_color": [1.0, 0.71, 0.29],
                                                    "metallic": 1.0, "roughness": 0.2}))
    # one sample on the silhouettes: nearly every pixel of this small knot is on one, and 8
    # edge samples there would hide the passes (app/pbgi/renderer.py: render_passes)
    gold = ["--material", str(tmp_path / "gold.json"), "--edge-samples", "1"]
    out = tmp_path / "gold"
    assert main(_args(scene, out, *gold, "--range", "1-1", "--no-video")) == 0
    assert "4 passes each" in capsys.readouterr().out
    (tmp_path / "cam.json").write_text(json.dumps(_orbit_camera(1)))
    render = ["render", "--cloud", str(scene / "room.ply"), "--object", str(scene / "obj.json"),
              "--camera", str(tmp_path / "cam.json"), *RENDER_FLAGS, *gold]
    assert main([*render, "--out", str(tmp_path / "r4.exr")]) == 0
    assert "4 passes" in capsys.readouterr().out
    assert main([*render, "--out", str(tmp_path / "r1.exr"), "--glossy-passes", "1"]) == 0
    frame = _rgba(out / "frame_0001.exr")
    assert np.abs(frame - _rgba(tmp_path / "r4.exr")).max() < 1e-4
    assert np.abs(frame - _rgba(tmp_path / "r1.exr")).max() > 1e-3


def test_background_frame_is_render_background(scene, tmp_path):
    """With --background the asset's shadow on the scan is gathered once for the sequence; a
    frame still equals ``render --background`` (which gathers it for its one frame)."""
    out = tmp_path / "bg"
    assert main(_args(scene, out, "--background", "--range", "1-1")) == 0
    (tmp_path / "cam.json").write_text(json.dumps(_orbit_camera(1)))
    assert main(["render", "--cloud", str(scene / "room.ply"), "--object",
                 str(scene / "obj.json"), "--camera", str(tmp_path / "cam.json"),
                 "--out", str(tmp_path / "r.exr"), "--background", *RENDER_FLAGS]) == 0
    frame, ref = _rgba(out / "frame_0001.exr"), _rgba(tmp_path / "r.exr")
    assert (frame[..., 3] > 0.99).mean() > 0.9           # the room fills (nearly) the frame
    assert np.abs(frame - ref).max() < 1e-4


def test_range_splits_the_work_and_the_last_part_writes_the_video(scene, full, capsys):
    out = scene / "farm"
    assert main(_args(scene, out, "--range", "1-2")) == 0
    assert _listing(out) == ["frame_0001.exr", "frame_0001.png", "frame_0002.exr",
                             "frame_0002.png"]                    # no video yet
    assert "waits for 2 frame(s)" in capsys.readouterr().out
    assert main(_args(scene, out, "--range", "0-0")) == 0
    assert "turntable.mp4" not in _listing(out)
    assert main(_args(scene, out, "--range", "3")) == 0
    assert _listing(out) == sorted(FRAMES + ["turntable.mp4"])
    size, frames = _video(out / "turntable.mp4")
    assert size == (W, H) and len(frames) == COUNT
    # the machines of a farm render what one run renders
    for k in range(COUNT):
        assert np.abs(_rgba(out / f"frame_{k:04d}.exr") -
                      _rgba(full / f"frame_{k:04d}.exr")).max() < 1e-5, k


def test_camera_path(scene, full, tmp_path):
    cams = [_orbit_camera(1), _orbit_camera(1, 3)]
    (tmp_path / "path.json").write_text(json.dumps(cams))
    out = tmp_path / "path"
    assert main(["turntable", "--cloud", str(scene / "room.ply"), "--object",
                 str(scene / "obj.json"), "--path", str(tmp_path / "path.json"), "--out",
                 str(out), *RENDER_FLAGS]) == 0
    assert _listing(out) == ["frame_0000.exr", "frame_0000.png", "frame_0001.exr",
                             "frame_0001.png", "turntable.mp4"]
    # the path's first camera is the orbit's frame 1
    assert np.abs(_rgba(out / "frame_0000.exr") - _rgba(full / "frame_0001.exr")).max() < 1e-4
    assert np.abs(_rgba(out / "frame_0001.exr") - _rgba(full / "frame_0001.exr")).max() > 0.05
    size, frames = _video(out / "turntable.mp4")
    assert size == (W, H) and len(frames) == 2


def test_odd_size_video_is_padded_to_even(scene, tmp_path):
    out = tmp_path / "odd"
    assert main(_args(scene, out, "--size", "15x9", "--count", "2", count=None)) == 0
    size, frames = _video(out / "turntable.mp4")
    assert size == (16, 10) and len(frames) == 2
    with Image.open(out / "frame_0000.png") as png:
        assert png.size == (15, 9)                                 # the frames keep theirs


def _one_line_error(capsys, code_expected, code, *words):
    err = capsys.readouterr().err.strip()
    assert code == code_expected, err
    assert len(err.splitlines()) == 1 and err.startswith("scanlight turntable: error:"), err
    for w in words:
        assert w in err, err


def test_range_outside_the_frames_is_a_usage_error(scene, tmp_path, capsys):
    out = tmp_path / "bad"
    code = main(_args(scene, out, "--range", "5-9"))
    _one_line_error(capsys, 2, code, "--range 5-9", "0-3")
    assert not out.exists()
    for bad in ("2-1", "x", "1-2-3"):
        assert main(_args(scene, out, "--range", bad)) == 2
    assert not out.exists()


def test_existing_frame_is_refused_without_force(scene, full, tmp_path, capsys):
    out = tmp_path / "again"
    out.mkdir()
    (out / "frame_0002.png").write_bytes((full / "frame_0002.png").read_bytes())
    (out / "notes.txt").write_text("a shared folder may hold other files")
    code = main(_args(scene, out))
    _one_line_error(capsys, 3, code, "frame_0002.png", "--force")
    assert _listing(out) == ["frame_0002.png", "notes.txt"]        # nothing rendered
    # another range of the same folder is fine; --force overwrites
    assert main(_args(scene, out, "--range", "0-1")) == 0
    assert main(_args(scene, out, "--range", "2-3", "--force")) == 0
    assert _listing(out) == sorted(FRAMES + ["turntable.mp4", "notes.txt"])


def test_bad_inputs(scene, tmp_path, capsys):
    out = tmp_path / "none"
    args = _args(scene, out)
    args[args.index("--cloud") + 1] = str(tmp_path / "missing.ply")
    _one_line_error(capsys, 3, main(args), "missing.ply")
    (tmp_path / "path.json").write_text(json.dumps([_orbit_camera(0)]))
    _one_line_error(capsys, 2, main(_args(scene, out, "--path", str(tmp_path / "path.json"))),
                    "--elevation")
    (tmp_path / "sizes.json").write_text(json.dumps([_orbit_camera(0),
                                                     {**_orbit_camera(1), "width": 8}]))
    _one_line_error(capsys, 3, main(["turntable", "--cloud", str(scene / "room.ply"),
                                     "--object", str(scene / "obj.json"), "--path",
                                     str(tmp_path / "sizes.json"), "--out", str(out)]),
                    "sizes.json", "different image sizes")
    _one_line_error(capsys, 2, main(_args(scene, out, count=None)), "--count")
    # the output folder may not be the cloud, nor a file
    _one_line_error(capsys, 3, main(_args(scene, scene / "room.ply")), "not a folder")
    assert not out.exists()


def test_ctrl_c_leaves_only_complete_frames(scene, tmp_path):
    """SIGINT in the middle of a long sequence: exit 130, every frame there has both files
    and reads back, no temporaries."""
    out = tmp_path / "interrupted"
    proc = subprocess.Popen([sys.executable, "-m", "app", *_args(scene, out, count=2000)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not (out / "frame_0003.png").exists() and time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "none partial" in err, err
    names = _listing(out)
    assert not [n for n in names if n.startswith(".")], names      # no temporaries
    exrs = [n for n in names if n.endswith(".exr")]
    assert 4 <= len(exrs) < 2000 and "turntable.mp4" not in names
    assert sorted(names) == sorted(exrs + [n[:-4] + ".png" for n in exrs])
    assert _rgba(out / exrs[-1]).shape == (H, W, 4)


def test_progress_bar_only_on_a_terminal(monkeypatch, caplog):
    """A real pseudo-terminal gets the bar (a fresh one reports a size of 0: tqdm's own
    sizing would draw nothing there); a pipe and -q do not."""
    import logging

    from app.commands.progress import bar_wanted, progress
    master, slave = os.openpty()
    with os.fdopen(slave, "w") as tty:
        monkeypatch.setattr(sys, "stderr", tty)
        assert bar_wanted() and not bar_wanted(quiet=True)
        with progress(3, "frames", unit="frame") as bar:
            for _ in range(3):
                bar.update(1)
        tty.flush()
        drawn = read_terminal(master)
        assert "frames" in drawn and "3/3" in drawn
        with progress(3, "hidden", quiet=True) as bar:
            bar.update(3)
        tty.flush()
        assert select.select([master], [], [], 0.2)[0] == []       # -q: nothing drawn
    os.close(master)
    monkeypatch.undo()
    assert not bar_wanted()                 # pytest's captured stderr is not a terminal
    with caplog.at_level(logging.INFO), progress(2, "piped") as bar:
        logging.getLogger("app.test").info("a log line stays")
        bar.update(2)
    assert "a log line stays" in caplog.text
