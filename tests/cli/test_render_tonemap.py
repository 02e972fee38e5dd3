"""``scanlight render --tonemap``: the PNG goes through the named tone mapper and the stats name
it; the EXR (linear) does not depend on it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.cli import main
from app.io.exr import read_exr
from app.io.pointcloud import save_cloud
from app.render import tonemap as T
from tests.support import scenes as S


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """One tiny render per tone mapper (16x12, M=8): {name: (png uint8, exr, stats)}."""
    from PIL import Image
    d = tmp_path_factory.mktemp("render_tonemap")
    save_cloud(S.box_room(0.1), d / "room.ply")
    (d / "obj.json").write_text(json.dumps({"mesh": "sphere", "translate": [0, 0.8, 0],
                                            "scale": 0.6}))
    (d / "cam.json").write_text(json.dumps({"position": [0.3, 1.0, 0.9], "look_at": [0, 0.8, 0],
                                            "fov_y_deg": 40, "width": 16, "height": 12}))
    out = {}
    for name in ("pbr-neutral", "aces"):
        args = ["render", "--cloud", str(d / "room.ply"), "--object", str(d / "obj.json"),
                "--camera", str(d / "cam.json"), "--microbuffer", "8", "--exposure", "1.5",
                "--out", str(d / f"{name}.exr"), "--png", str(d / f"{name}.png"),
                "--stats", str(d / f"{name}.json"), "--tonemap", name]
        assert main(args) == 0
        with Image.open(d / f"{name}.png") as png:
            img = np.asarray(png)
        out[name] = (img, read_exr(d / f"{name}.exr").rgb,
                     json.loads((d / f"{name}.json").read_text()))
    return out


def test_png_uses_the_named_tone_mapper_and_stats_name_it(rendered):
    png_n, exr_n, stats_n = rendered["pbr-neutral"]
    png_a, exr_a, stats_a = rendered["aces"]
    assert stats_n["tonemapper"] == "Khronos PBR Neutral"
    assert stats_a["tonemapper"] == T.TONEMAPPERS["aces"].title and "Hill" in stats_a["tonemapper"]
    np.testing.assert_array_equal(exr_n, exr_a)             # the linear render is the same
    assert png_a.shape == png_n.shape == (12, 16, 4)
    assert np.abs(png_a[..., :3].astype(int) - png_n[..., :3].astype(int)).max() > 10
    # each PNG is exactly its tone mapper applied to the EXR (RGB; alpha is coverage)
    for name, (png, exr, _) in rendered.items():
        expect = T.tonemap_to_srgb8(exr, 1.5, name)
        assert np.abs(png[..., :3].astype(int) - expect.astype(int)).max() <= 1


def test_unknown_tone_mapper_is_a_usage_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:      # argparse's choice check: exit 2, one line
        main(["render", "--cloud", "x.ply", "--object", "sphere", "--camera", "c.json",
              "--out", str(tmp_path / "o.exr"), "--tonemap", "filmic"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "filmic" in err and "aces" in err
