"""The command-line skeleton: help for every subcommand, exit codes, one-line errors."""

from __future__ import annotations

import subprocess
import sys

import pytest

from app.cli import COMMANDS, main


def scanlight(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "app", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=600)


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_subcommand_has_help(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0
    assert "usage: scanlight " + command in capsys.readouterr().out


def test_bench_names_have_help(capsys):
    from app.bench import BENCHES
    for name in BENCHES:
        with pytest.raises(SystemExit) as exit_info:
            main(["bench", name, "--help"])
        assert exit_info.value.code == 0
        assert "--json" in capsys.readouterr().out


def test_usage_error_exits_2_with_one_line():
    res = scanlight("render", "--no-such-flag")
    assert res.returncode == 2
    assert len(res.stderr.strip().splitlines()) == 1 and "error" in res.stderr


def test_bad_input_exits_3_with_one_line_naming_the_file(tmp_path):
    missing = tmp_path / "nope.ply"
    res = scanlight("evaluate", "expansion", "--cloud", str(missing), "--gt", str(missing))
    assert res.returncode == 3, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and str(missing) in lines[0] and "Traceback" not in res.stderr


def test_demo_takes_a_tone_mapper_from_the_table():
    """``demo --tonemap`` is view.tonemap (choices from the registry); a wrong name is a usage
    error before any work (the full run is the test below)."""
    from app.cli import build_parser
    from app.commands.options import param_values
    from app.render.tonemap import DEFAULT
    assert param_values(build_parser().parse_args(["demo", "--tonemap", "agx"]),
                        "demo")["view.tonemap"] == "agx"
    assert param_values(build_parser().parse_args(["demo"]), "demo")["view.tonemap"] == DEFAULT
    res = scanlight("demo", "--tonemap", "reinhard")
    assert res.returncode == 2 and "reinhard" in res.stderr


def test_view_without_display_falls_back_to_demo(tmp_path, monkeypatch):
    """No DISPLAY: `scanlight view` says so and runs the headless demo instead of crashing."""
    import os
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = subprocess.run([sys.executable, "-m", "app", "view", "--out", str(tmp_path / "out"),
                          "--demo-size", "64"], capture_output=True, text=True, env=env, timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "no display" in res.stderr
    import json
    rep = json.loads((tmp_path / "out" / "report.json").read_text())
    # The whole pipeline did its job: expansion beats the LDR scan on the clipped points and the
    # asset lit by the expanded cloud is closer to ground-truth lighting than with the LDR scan.
    assert rep["point_errors"]["rms_overexposed"] < 0.5 * rep["point_errors"]["ldr_rms_overexposed"]
    for view in ("closeup", "whole"):
        errs = rep["render_errors"][view]
        assert errs["expanded"]["render_rel_rms"] < 0.5 * errs["ldr"]["render_rel_rms"]
    for name in ("room_ldr.ply", "room_hdr.ply", "photo.exr", "relit_closeup_expanded.png"):
        assert (tmp_path / "out" / name).is_file()
    import numpy as np

    from app.io.exr import read_exr_layers
    relit = read_exr_layers(tmp_path / "out" / "relit_closeup_expanded.exr")[""]
    assert relit.shape[-1] == 4 and set(np.unique(relit[..., 3])) == {0.0, 1.0}  # A = coverage
    # the contact sheet: the report says where each tile is; the asset in every render mode;
    # a tile is its PNG (64 px here) scaled to the sheet's tile size, tone-mapped with the
    # default tone mapper, which the report names
    from PIL import Image

    from app.demo.contact_sheet import TILE
    from app.params import RENDER_MODES
    from app.render.tonemap import DEFAULT, TONEMAPPERS
    assert rep["tonemap"] == DEFAULT and rep["tonemapper"] == TONEMAPPERS[DEFAULT].title
    sheet = np.asarray(Image.open(tmp_path / "out" / "contact_sheet.png").convert("RGB"))
    info = rep["contact_sheet"]
    assert info["file"] == str(tmp_path / "out" / "contact_sheet.png")
    assert tuple(info["size"]) == (sheet.shape[1], sheet.shape[0])
    tiles = info["tiles"]
    # the gold row averages the passes `render` gives a glossy metal (pbgi.glossy_passes), the
    # white diffuse one pass, and the sheet's header says so
    from app.params import BY_KEY
    assert rep["mode_passes"] == {"diffuse": 1, "glossy": BY_KEY["pbgi.glossy_passes"].default}
    assert any("glossy 4" in line for line in info["lines"])
    for kind in ("diffuse (white diffuse)", "glossy (gold)"):
        for mode in RENDER_MODES:
            x0, y0, x1, y1 = tiles[f"{kind}, {mode}"]
            assert (x1 - x0, y1 - y0) == (TILE, TILE) and sheet[y0:y1, x0:x1].std() > 5
    for name, label in (("relit_closeup_expanded", "hybrid, lit by expanded HDR"),
                        ("relit_closeup_ldr", "hybrid, lit by LDR scan")):
        png = Image.open(tmp_path / "out" / f"{name}.png").convert("RGB")
        want = np.asarray(png.resize((TILE, TILE), Image.Resampling.LANCZOS))
        x0, y0, x1, y1 = tiles[label]
        assert np.array_equal(sheet[y0:y1, x0:x1], want), label
