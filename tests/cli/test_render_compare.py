"""``scanlight render --compare A B`` (app/commands/compare.py): sides parsed and refused, the
metrics against numpy, the sheet's layout, and the command end to end on a tiny render."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.cli import main
from app.commands import compare as C
from app.errors import UsageError
from app.io.exr import read_exr, read_exr_layers, write_exr
from app.io.pointcloud import save_cloud
from tests.support import scenes as S


@pytest.mark.parametrize("text, what", [("classic", "KIND:VALUE"), ("mode:fast", "unknown mode"),
                                        ("quality:ultra", "unknown quality"),
                                        ("light:x.exr", "KIND:VALUE"), ("cloud:", "KIND:VALUE")])
def test_bad_sides_are_usage_errors(text, what):
    with pytest.raises(UsageError, match=what):
        C.parse_side(text)


def test_a_preset_side_keeps_the_flags_given():
    values = {"pbgi.mode": "classic", "pbgi.microbuffer": 8, "pbgi.render_scale": 1.0}
    got = C.side_values(C.parse_side("quality:preview"), values, {"pbgi.microbuffer": 8})
    assert got["pbgi.mode"] == "hybrid" and got["pbgi.render_scale"] == 0.5
    assert got["pbgi.microbuffer"] == 8                     # given on the command line: kept
    assert C.side_values(C.parse_side("mode:envmap"), values, {})["pbgi.mode"] == "envmap"


def _image(rng, h=16, w=16):
    img = np.zeros((h, w, 4), np.float32)
    img[..., :3] = rng.uniform(0.2, 1.0, (h, w, 3))
    img[..., 3] = 1.0
    return img


def test_metrics_against_numpy():
    """B = A + noise: relative RMSE = rms(noise) / mean luminance of A (numpy, here), per pixel
    and over 4x4 means; identical images give 0 and a luminance ratio of 1."""
    rng = np.random.default_rng(3)
    a = _image(rng)
    noise = rng.normal(0, 0.05, a[..., :3].shape).astype(np.float32)
    b = a.copy()
    b[..., :3] += noise
    lum = (a[..., :3] @ np.array([0.2126, 0.7152, 0.0722])).mean()
    m = C.metrics(a, b)
    assert m["pixels"] == 256
    assert m["rel_rmse"] == pytest.approx(np.sqrt((noise.astype(np.float64) ** 2).mean()) / lum,
                                          rel=1e-5)
    pooled = noise.reshape(4, 4, 4, 4, 3).mean(axis=(1, 3))
    assert m["rel_rmse_4x4"] == pytest.approx(np.sqrt((pooled.astype(np.float64) ** 2).mean())
                                              / lum, rel=1e-5)
    same = C.metrics(a, a)
    assert same["rel_rmse"] == 0 and same["mean_luminance_ratio"] == pytest.approx(1.0)


def test_the_sheet_shows_a_b_and_their_difference_with_a_legend():
    rng = np.random.default_rng(4)
    a = _image(rng)
    b = a.copy()
    b[:8, :, :3] *= 2.0                      # the top half differs, the bottom does not
    out = C.sheet(a, b, 0.0, "pbr-neutral")
    assert out.shape == (16 + C.LEGEND_HEIGHT, 48, 3) and out.dtype == np.uint8
    diff = out[:16, 32:]
    assert (diff[8:] == 0).all()                        # no difference: black
    assert diff[:8].mean() > 100                        # a large one: bright
    assert out[16, 32:].tolist() != out[16, 32:][::-1].tolist()  # the ramp runs along the legend
    assert (C.ramp(0.0) == 0).all() and np.allclose(C.ramp(1.0), 1.0)


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    d = tmp_path_factory.mktemp("compare")
    save_cloud(S.box_room(0.1), d / "room.ply")
    (d / "obj.json").write_text(json.dumps({"mesh": "sphere", "translate": [0, 0.8, 0],
                                            "scale": 0.6}))
    (d / "cam.json").write_text(json.dumps({"position": [0.3, 1.0, 0.9], "look_at": [0, 0.8, 0],
                                            "fov_y_deg": 40, "width": 16, "height": 16}))
    pano = np.full((16, 32, 3), 0.5, np.float32)
    write_exr(d / "sky.exr", pano)
    return d


def _args(d, *extra):
    return ["render", "--cloud", str(d / "room.ply"), "--object", str(d / "obj.json"),
            "--camera", str(d / "cam.json"), "--microbuffer", "8", *extra]


def test_compare_writes_side_by_side_difference_and_metrics(room, tmp_path):
    """mode:envmap against mode:classic: the EXR is both renders side by side, each equal to a
    plain render with that mode; the stats hold the metrics of B against A."""
    from PIL import Image
    out, png, stats = tmp_path / "cmp.exr", tmp_path / "cmp.png", tmp_path / "cmp.json"
    assert main(_args(room, "--compare", "mode:classic", "mode:envmap", "--out", str(out),
                      "--png", str(png), "--stats", str(stats))) == 0
    both = read_exr(out).rgb
    assert both.shape == (16, 32, 3)
    for i, mode in enumerate(("classic", "envmap")):
        assert main(_args(room, "--mode", mode, "--out", str(tmp_path / f"{mode}.exr"))) == 0
        alone = read_exr(tmp_path / f"{mode}.exr").rgb
        np.testing.assert_allclose(both[:, 16 * i:16 * (i + 1)], alone, atol=1e-5)
    s = json.loads(stats.read_text())
    assert s["compare"]["a"] == "mode:classic" and s["compare"]["b"] == "mode:envmap"
    a, b = both[:, :16], both[:, 16:]
    alpha = read_exr_layers(out)[""][..., 3]            # both halves' coverage
    both_cover = (alpha[:, :16] > 0.5) & (alpha[:, 16:] > 0.5)
    assert s["compare"]["metrics"]["pixels"] == int(both_cover.sum()) > 0
    assert 0 < s["compare"]["metrics"]["rel_rmse"] < 1
    with Image.open(png) as im:
        assert im.size == (48, 16 + C.LEGEND_HEIGHT)


def test_compare_with_an_hdri_side(room, tmp_path):
    """hdri:FILE lights B with a constant grey sky: B is smooth and differs from the scan's A."""
    out = tmp_path / "h.exr"
    assert main(_args(room, "--compare", "mode:envmap", f"hdri:{room / 'sky.exr'}",
                      "--out", str(out), "--stats", str(tmp_path / "h.json"))) == 0
    s = json.loads((tmp_path / "h.json").read_text())
    assert s["compare"]["b"] == "hdri:sky.exr"
    assert s["compare"]["b_stats"]["hdri"].endswith("sky.exr")
    assert s["compare"]["metrics"]["rel_rmse"] > 0.01


def test_compare_gives_a_glossy_metal_its_passes(room, tmp_path):
    """Each side of a gold sphere's compare averages pbgi.glossy_passes (4) passes, as `render`
    does (app/pbgi/upsample.py: render_passes_of), unless --glossy-passes says otherwise."""
    (tmp_path / "gold.json").write_text(json.dumps({"base_color": [1.0, 0.71, 0.29],
                                                    "metallic": 1.0, "roughness": 0.2}))
    gold = ["--material", str(tmp_path / "gold.json"), "--edge-samples", "1"]
    for extra, want in (([], 4), (["--glossy-passes", "1"], 1)):
        stats = tmp_path / f"g{want}.json"
        assert main(_args(room, *gold, *extra, "--compare", "mode:classic", "mode:hybrid",
                          "--out", str(tmp_path / f"g{want}.exr"), "--stats", str(stats))) == 0
        s = json.loads(stats.read_text())["compare"]
        assert (s["a_stats"]["passes"], s["b_stats"]["passes"]) == (want, want)


def test_compare_refuses_a_missing_side_file(room, tmp_path, capsys):
    assert main(_args(room, "--compare", "mode:envmap", f"cloud:{tmp_path / 'none.ply'}",
                      "--out", str(tmp_path / "x.exr"))) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "none.ply" in err[0]
    assert not (tmp_path / "x.exr").exists()


def test_render_lit_by_an_hdri(room, tmp_path):
    """--hdri: the asset is lit by the constant sky (stats name it; the environment map gathers
    it), and --background shows the sky where the asset is not."""
    out, stats = tmp_path / "sky.exr", tmp_path / "sky.json"
    assert main(_args(room, "--hdri", str(room / "sky.exr"), "--background", "--out", str(out),
                      "--stats", str(stats))) == 0
    img = read_exr(out).rgb
    s = json.loads(stats.read_text())
    assert s["hdri"].endswith("sky.exr") and s["mode"] == "envmap" and s["differential"] is None
    assert main(_args(room, "--hdri", str(room / "sky.exr"), "--out", str(tmp_path / "a.exr"))) == 0
    asset = read_exr(tmp_path / "a.exr").rgb.sum(axis=-1) > 0
    assert asset.any() and (~asset).any()
    np.testing.assert_allclose(img[~asset], 0.5, atol=1e-6)
    # a sky of 0.5 lights a surface to at most about 0.5 (Disney's diffuse + specular may exceed
    # its albedo by a few percent at grazing angles: it is not strictly energy-conserving)
    assert 0.05 < img[asset].max() < 0.5 * 1.1


def test_a_panorama_of_the_wrong_shape_is_refused(room, tmp_path, capsys):
    write_exr(tmp_path / "square.exr", np.ones((8, 8, 3), np.float32))
    assert main(_args(room, "--hdri", str(tmp_path / "square.exr"),
                      "--out", str(tmp_path / "x.exr"))) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "square.exr" in err[0] and "twice as wide" in err[0]
    assert not (tmp_path / "x.exr").exists()
