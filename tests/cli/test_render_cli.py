"""``scanlight render``: outputs, stats, and one-line errors with exit codes 2 (usage) / 3 (input)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from tests.support import scenes as S
from app.cli import main
from app.io.exr import read_exr, read_exr_layers
from app.io.pointcloud import save_cloud


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("render")
    save_cloud(S.box_room(0.1), d / "room.ply")
    (d / "obj.json").write_text(json.dumps({"mesh": "sphere", "translate": [0, 0.8, 0],
                                            "scale": 0.6}))
    (d / "mat.json").write_text(json.dumps({"base_color": [0.8, 0.2, 0.1], "roughness": 0.3}))
    (d / "cam.json").write_text(json.dumps({"position": [0.3, 1.0, 0.9], "look_at": [0, 0.8, 0],
                                            "fov_y_deg": 40, "width": 16, "height": 12}))
    return d


def _args(d, *extra):
    return ["render", "--cloud", str(d / "room.ply"), "--object", str(d / "obj.json"),
            "--material", str(d / "mat.json"), "--camera", str(d / "cam.json"),
            "--out", str(d / "out.exr"), *extra]


@pytest.mark.parametrize("mode", ["classic", "envmap"])
def test_render_writes_exr_png_and_stats(inputs, mode, capsys):
    d = inputs
    code = main(_args(d, "--mode", mode, "--microbuffer", "12", "--png", str(d / "out.png"),
                      "--stats", str(d / "stats.json"), "--size", "20x14", "--background"))
    assert code == 0
    img = read_exr(d / "out.exr").rgb
    assert img.shape == (14, 20, 3) and np.isfinite(img).all() and img.max() > 0
    from PIL import Image
    with Image.open(d / "out.png") as png:
        assert png.size == (20, 14)
    stats = json.loads((d / "stats.json").read_text())
    assert stats["mode"] == mode and stats["microbuffer"] == 12 and stats["completed"] is True
    assert stats["width"] == 20 and stats["height"] == 14
    assert stats["ms"] > 0 and stats["mb"] > 0
    assert stats["tonemapper"] == "Khronos PBR Neutral"
    if mode == "classic":
        assert stats["nodes_visited"] > 1
    # the background fills the pixels around the object: nothing is black
    assert (img.sum(axis=-1) > 0).all()
    assert "rendered 20x14" in capsys.readouterr().out


def test_render_matches_the_api(inputs):
    """The CLI renders what Relighter renders (no background, same material and camera)."""
    from app.camera import load_camera
    from app.cloud import PointCloud
    from app.io.formats import load_object, placed_mesh
    from app.io.pointcloud import load_cloud
    from app.material import load_material
    from app.pbgi.renderer import Relighter, RenderParams
    d = inputs
    assert main(_args(d, "--microbuffer", "8")) == 0
    cli = read_exr_layers(d / "out.exr")[""]          # RGBA: the EXR carries the coverage
    r = Relighter()
    c = load_cloud(d / "room.ply")
    r.set_cloud(PointCloud(c.positions, c.normals, c.colors, hdr=True))
    r.set_asset(placed_mesh(load_object(d / "obj.json")))
    # the table's default: 8 samples on the silhouettes (app/pbgi/antialias.py)
    api = r.render_passes(load_camera(d / "cam.json"), [load_material(d / "mat.json")],
                          RenderParams(microbuffer=8), 1, edge_samples=8).image
    assert cli.shape == api.shape == (12, 16, 4)
    assert np.allclose(cli, api, rtol=1e-5, atol=1e-6)
    assert 0 < cli[..., 3].sum() < cli[..., 3].size and np.array_equal(cli[..., 3], api[..., 3])


def test_render_scale_renders_the_gi_smaller_and_upsamples_it(inputs, capsys):
    """--render-scale 0.5 writes what app/pbgi/upsample.py computes (the GI at half resolution,
    joint bilateral upsampled), at the full size with the full-resolution coverage, and says so
    in the stats and on stdout; --quality preview brings its scale with it."""
    from app.camera import load_camera
    from app.cloud import PointCloud
    from app.io.formats import load_object, placed_mesh
    from app.io.pointcloud import load_cloud
    from app.material import load_material
    from app.pbgi.renderer import Relighter, RenderParams
    from app.pbgi.upsample import render_upsampled
    d = inputs
    assert main(_args(d, "--microbuffer", "8", "--render-scale", "0.5", "--size", "32x24",
                      "--stats", str(d / "half.json"))) == 0
    assert "GI at 0.5 of the resolution" in capsys.readouterr().out
    cli = read_exr_layers(d / "out.exr")[""]
    stats = json.loads((d / "half.json").read_text())
    assert (stats["render_scale"], stats["width"], stats["out_width"]) == (0.5, 16, 32)
    r = Relighter()
    c = load_cloud(d / "room.ply")
    r.set_cloud(PointCloud(c.positions, c.normals, c.colors, hdr=True))
    r.set_asset(placed_mesh(load_object(d / "obj.json")))
    cam = load_camera(d / "cam.json")
    from dataclasses import replace
    cam = replace(cam, width=32, height=24)
    api = render_upsampled(r, cam, [load_material(d / "mat.json")], RenderParams(microbuffer=8),
                           1, 0.5, edge_samples=8).image
    # the coverage: box-filtered at full resolution with the 8 edge samples' jitter
    full = r.render_passes(cam, [load_material(d / "mat.json")], RenderParams(microbuffer=8),
                           8).image
    assert cli.shape == api.shape == (24, 32, 4)
    assert np.allclose(cli, api, rtol=1e-5, atol=1e-6)
    assert np.array_equal(cli[..., 3], full[..., 3])
    assert main(_args(d, "--quality", "preview", "--size", "32x24",
                      "--stats", str(d / "preview.json"))) == 0
    from app.params import QUALITY_PRESETS
    assert json.loads((d / "preview.json").read_text())["render_scale"] == \
        QUALITY_PRESETS["preview"]["pbgi.render_scale"]


def test_render_passes_average_jittered_renders(inputs, capsys):
    """--passes N writes the mean of Relighter.render_passes (N jittered passes): its stats say
    so, the silhouette's pixels are partly covered (anti-aliased), and the background composite
    treats the mean as premultiplied by its coverage (straight alpha would darken the fringe).
    (The asset's shadow on the scan is off here: test_render_layers_for_compositing.)"""
    from app.pbgi.renderer import Relighter, RenderParams
    d = inputs
    # --edge-samples as many as the passes (nothing more on the silhouettes), then 1 (one
    # sample per pixel): the passes alone (tests/pbgi/test_antialias.py has the edge samples)
    assert main(_args(d, "--microbuffer", "8", "--passes", "4", "--stats", str(d / "st.json"),
                      "--background", "--size", "32x24", "--differential", "false",
                      "--edge-samples", "4")) == 0
    assert "4 passes" in capsys.readouterr().out
    stats = json.loads((d / "st.json").read_text())
    assert stats["passes"] == 4 and stats["completed"] is True
    four = read_exr(d / "out.exr").rgb
    four_alpha = read_exr_layers(d / "out.exr")[""][..., 3]
    assert main(_args(d, "--microbuffer", "8", "--background", "--size", "32x24",
                      "--differential", "false", "--edge-samples", "1")) == 0
    one = read_exr(d / "out.exr").rgb
    one_alpha = read_exr_layers(d / "out.exr")[""][..., 3]
    assert np.isfinite(four).all() and four.shape == one.shape
    r = Relighter()
    from app.io.pointcloud import load_cloud
    from app.cloud import PointCloud
    from app.io.formats import load_object, placed_mesh
    from app.camera import load_camera
    from app.material import load_material
    from dataclasses import replace
    c = load_cloud(d / "room.ply")
    r.set_cloud(PointCloud(c.positions, c.normals, c.colors, hdr=True))
    r.set_asset(placed_mesh(load_object(d / "obj.json")))
    cam = replace(load_camera(d / "cam.json"), width=32, height=24)
    res = r.render_passes(cam, [load_material(d / "mat.json")], RenderParams(microbuffer=8), 4)
    a = res.image[..., 3]
    assert ((a > 0) & (a < 1)).any() and set(np.unique(a)) <= {0.0, 0.25, 0.5, 0.75, 1.0}
    expect = res.image[..., :3] + r.background(cam)[..., :3] * (1.0 - a[..., None])
    np.testing.assert_allclose(four, expect, rtol=1e-4, atol=1e-6)
    # the EXR's alpha: with --background, max(object coverage, splats' coverage)
    np.testing.assert_array_equal(four_alpha, np.maximum(a, r.background(cam)[..., 3]))
    assert set(np.unique(one_alpha)) <= {0.0, 1.0}


def test_glossy_passes_follow_the_materials():
    """render_passes_of: pbgi.passes, raised to pbgi.glossy_passes where a metal is smoother than
    pbgi.rough_scale_from (or has a roughness texture, which can make it smoother anywhere); a
    dielectric's weak lobe and a rough metal keep pbgi.passes, and more passes asked win."""
    from dataclasses import replace
    from app.material import Material
    from app.params import BY_KEY
    from app.pbgi.upsample import render_passes_of
    values = {k: BY_KEY[k].default for k in ("pbgi.passes", "pbgi.glossy_passes",
                                             "pbgi.rough_scale_from")}
    assert (values["pbgi.passes"], values["pbgi.glossy_passes"]) == (1, 4)
    gold = Material(base_color=(1.0, 0.71, 0.29), metallic=1.0, roughness=0.2)
    rough_gold = replace(gold, roughness=0.5)
    plastic = Material(roughness=0.2)
    half_metal = replace(gold, metallic=0.3)
    textured = replace(rough_gold, metallic_roughness_texture=np.ones((2, 2, 3), np.float32))
    assert render_passes_of(values, [gold]) == 4
    assert render_passes_of(values, [plastic, gold]) == 4        # one glossy metal is enough
    assert render_passes_of(values, [half_metal]) == 4
    assert render_passes_of(values, [textured]) == 4
    assert render_passes_of(values, [rough_gold]) == 1
    assert render_passes_of(values, [plastic]) == 1
    assert render_passes_of({**values, "pbgi.rough_scale_from": 0.15}, [gold]) == 1
    assert render_passes_of({**values, "pbgi.passes": 6}, [gold]) == 6
    assert render_passes_of({**values, "pbgi.glossy_passes": 1}, [gold]) == 1


def test_render_gives_a_glossy_metal_its_passes(inputs, capsys):
    """`render` of a gold sphere averages pbgi.glossy_passes (4) passes by default - the stats
    and stdout say so and the image is Relighter.render_passes' mean of 4 - and
    --glossy-passes 1 renders one pass, as for a rough material."""
    from app.camera import load_camera
    from app.cloud import PointCloud
    from app.io.formats import load_object, placed_mesh
    from app.io.pointcloud import load_cloud
    from app.material import load_material
    from app.pbgi.renderer import Relighter, RenderParams
    d = inputs
    (d / "gold.json").write_text(json.dumps({"base_color": [1.0, 0.71, 0.29], "metallic": 1.0,
                                             "roughness": 0.2}))
    gold = ["--material", str(d / "gold.json")]
    common = ["--microbuffer", "8", "--edge-samples", "1", "--differential", "false"]
    assert main(_args(d, *common, *gold, "--stats", str(d / "gold.json.stats"))) == 0
    assert "4 passes" in capsys.readouterr().out
    assert json.loads((d / "gold.json.stats").read_text())["passes"] == 4
    cli = read_exr_layers(d / "out.exr")[""]
    r = Relighter()
    c = load_cloud(d / "room.ply")
    r.set_cloud(PointCloud(c.positions, c.normals, c.colors, hdr=True))
    r.set_asset(placed_mesh(load_object(d / "obj.json")))
    api = r.render_passes(load_camera(d / "cam.json"), [load_material(d / "gold.json")],
                          RenderParams(microbuffer=8), 4).image
    np.testing.assert_allclose(cli, api, rtol=1e-5, atol=1e-6)
    assert main(_args(d, *common, *gold, "--glossy-passes", "1",
                      "--stats", str(d / "gold.json.stats"))) == 0
    assert "passes" not in capsys.readouterr().out
    assert json.loads((d / "gold.json.stats").read_text())["passes"] == 1


def _scanlight(*args):
    return subprocess.run([sys.executable, "-m", "app", *args], capture_output=True, text=True,
                          timeout=600)


@pytest.mark.parametrize("extra, code, needle", [
    (["--microbuffer", "40"], 2, "--microbuffer"),
    (["--mode", "nope"], 2, "invalid choice"),
    (["--size", "12by4"], 2, "--size"),
    (["--layers", "layers.png"], 2, "--layers"),
    (["--asset-surfels", "10"], 2, "--asset-surfels"),
    (["--out-of-range"], 2, "unrecognized"),
])
def test_bad_arguments_exit_2_with_one_line(inputs, extra, code, needle):
    res = _scanlight(*_args(inputs, *extra))
    assert res.returncode == code, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in res.stderr


def test_bad_input_files_exit_3_naming_the_file(inputs, tmp_path):
    bad_cam = tmp_path / "cam.json"
    bad_cam.write_text('{"position": [0, 1, 0], "look_at": [0, 1, 0]}')
    args = _args(inputs)
    args[args.index("--camera") + 1] = str(bad_cam)
    res = _scanlight(*args)
    assert res.returncode == 3
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad_cam) in lines[0]
    args = _args(inputs)
    args[args.index("--cloud") + 1] = str(tmp_path / "missing.ply")
    res = _scanlight(*args)
    assert res.returncode == 3 and "missing.ply" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_render_layers_for_compositing(inputs):
    """--layers writes one EXR with the compositing layers in order, channels <layer>.R/G/B/A:
    the asset layer is the --out image; beauty is the asset over the background with the
    asset's shadow (background + shadow); the shadow darkens the room somewhere (under the
    sphere) and brightens little; the indirect layer is the asset's own bounce (zero without
    bounces), on the asset's pixels only."""
    d = inputs
    lay = d / "layers.exr"
    (d / "top.json").write_text(json.dumps({"position": [0.6, 1.6, 0.8], "look_at": [0, 0.2, 0],
                                            "fov_y_deg": 60, "width": 32, "height": 24}))
    (d / "low.json").write_text(json.dumps({"mesh": "sphere", "translate": [0, 0.4, 0],
                                            "scale": 0.6}))
    top = ["--camera", str(d / "top.json"), "--object", str(d / "low.json")]   # sees its floor
    assert main(_args(d, "--microbuffer", "8", "--layers", str(lay), *top)) == 0
    layers = read_exr_layers(lay)
    assert list(layers) == ["beauty", "asset", "background", "shadow", "indirect"]
    assert all(v.shape == (24, 32, 4) and np.isfinite(v).all() for v in layers.values())
    np.testing.assert_array_equal(layers["asset"], read_exr_layers(d / "out.exr")[""])
    a = layers["asset"][..., 3:4]
    lit = layers["background"][..., :3] + layers["shadow"][..., :3]
    np.testing.assert_allclose(layers["beauty"][..., :3],
                               layers["asset"][..., :3] + lit * (1 - a), rtol=1e-5, atol=1e-6)
    room = layers["background"][..., 3] > 0
    dark = (layers["shadow"][..., :3].sum(-1) < -0.02 * layers["background"][..., :3].sum(-1))
    assert (dark & room).sum() > 3
    assert (layers["indirect"][..., 3] == layers["asset"][..., 3]).all()
    assert np.abs(layers["indirect"][..., :3][layers["asset"][..., 3] == 0]).max() == 0
    assert main(_args(d, "--microbuffer", "8", "--layers", str(lay), "--asset-bounces", "0",
                      *top)) == 0
    assert np.abs(read_exr_layers(lay)["indirect"][..., :3]).max() == 0
